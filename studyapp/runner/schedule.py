"""Scheduling: a pure function of (protocol, participant, seed) -> the participant's list of trials.

The same inputs give a byte-identical schedule (:func:`schedule_bytes`) on any machine and Python version: the
random stream is BLAKE2b in counter mode keyed by ``(seed, participant, protocol content hash)``, not NumPy's or
Python's generators, whose streams may change between releases.

What a schedule holds, in order:

1. practice trials (``practice``), stimuli spanning the quality range as listed in the protocol, after the
   labelled reference of the practice scene where the design has references (the practice question, "is this
   the ground truth?", is then asked only once the ground truth was shown);
2. per scene block (``trial_order: blocked``; scene order fixed, random or a balanced Latin square across
   participants), an optional labelled reference (``reference``, not answered) and the block's trials in a
   constrained shuffle; or all trials in one constrained shuffle (``interleaved``);
3. catch trials (``catch``) with a known answer, spread over the main trials;
4. ``break_before`` flags (:func:`place_breaks`): in a blocked design at each scene change (before the new
   scene's reference or first trial) and after every ``breaks.every`` design trials within a block; in an
   interleaved design every ``breaks.every`` answered trials.

Counterbalancing index
----------------------
The Latin-square row and the 2AFC position balance use the participant's counterbalancing index: the number at
the end of the participant id (``P07`` -> 7), else ``int(sha256(id)) mod 10**6``. Consecutively numbered
participants therefore get consecutive Latin-square rows.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import asdict, dataclass

from data_schema import families
from data_schema.errors import UserError
from data_schema.ranges import SEED

from .protocol import Protocol

SCHEDULE_FORMAT = 1
MAX_SHUFFLE_ATTEMPTS = 2000
_NOTHING = object()


@dataclass(slots=True)
class PlannedTrial:
    """One planned trial. ``conditions`` are in display order (A/left first; offered order for preference)."""

    index: int
    kind: str  # "trial", "practice", "catch" or "reference" (shown, not answered)
    family: str
    scene: str
    block: str
    conditions: tuple[str, ...]
    expected: str = ""  # catch: the known answer ("A", "B", "yes", "no" or "same:<trial index>")
    break_before: bool = False
    item: str = ""  # identity of the item for the repeat-distance constraint

    @property
    def idx(self) -> int:
        """Same as ``index`` (the name the session store uses)."""
        return self.index


class _Stream:
    """Deterministic uniform numbers: BLAKE2b(key, counter) -> 64-byte blocks -> eight 64-bit integers."""

    def __init__(self, *key) -> None:
        self._key = hashlib.blake2b(json.dumps(key, default=str).encode(), digest_size=32).digest()
        self._counter = 0
        self._buffer: list[int] = []

    def _next64(self) -> int:
        if not self._buffer:
            self._counter += 1
            block = hashlib.blake2b(self._counter.to_bytes(8, "little"), key=self._key, digest_size=64).digest()
            self._buffer = [int.from_bytes(block[i:i + 8], "little") for i in range(56, -8, -8)]
        return self._buffer.pop()

    def below(self, n: int) -> int:
        """Uniform integer in ``[0, n)`` (rejection sampling, no modulo bias)."""
        if n <= 0:
            raise UserError(f"n={n} is out of range: must be >= 1")
        limit = (1 << 64) - ((1 << 64) % n)
        while True:
            x = self._next64()
            if x < limit:
                return x % n

    def shuffle(self, items: list) -> list:
        """Fisher-Yates shuffle of a copy."""
        out = list(items)
        for i in range(len(out) - 1, 0, -1):
            j = self.below(i + 1)
            out[i], out[j] = out[j], out[i]
        return out


def counterbalance_index(participant: str) -> int:
    """Trailing number of the id (``P07`` -> 7), else ``int(sha256(id)) mod 10**6``."""
    m = re.search(r"(\d+)$", participant)
    if m:
        return int(m.group(1))
    return int(hashlib.sha256(participant.encode()).hexdigest(), 16) % 10**6


def balanced_latin_square_row(n: int, row: int) -> list[int]:
    """Row ``row`` of a balanced (Williams) Latin square of order ``n``.

    First row ``0, 1, n-1, 2, n-2, ...``; row ``r`` adds ``r`` modulo ``n``. For even ``n`` the ``n`` rows put
    every element once in every position and every ordered pair of neighbours once; for odd ``n`` the rows of
    odd ``r`` are reversed, and the ``2n`` rows do the same twice over.
    """
    if n < 1:
        raise UserError(f"n={n} is out of range: must be >= 1")
    seq, j, h = [], 0, 0
    for i in range(n):
        if i < 2 or i % 2 == 1:
            val, j = j, j + 1
        else:
            val, h = n - h - 1, h + 1
        seq.append((val + row) % n)
    if n % 2 == 1 and row % 2 == 1:
        seq.reverse()
    return seq


def constrained_shuffle(items: list[dict], stream: _Stream, max_run: int = 0, min_distance: int = 0,
                        run_key: str = "run", item_key: str = "item") -> list[dict]:
    """Random order of ``items`` with no ``run_key`` value more than ``max_run`` times in a row and at least
    ``min_distance`` positions between equal ``item_key`` values (0 disables a constraint).

    Randomised greedy construction: each position takes a uniformly chosen remaining item among those that
    keep the constraints (items are bucketed by their ``(run, item)`` values, so a step costs one check per
    distinct value, not per item); a dead end restarts, at most ``MAX_SHUFFLE_ATTEMPTS`` times.

    Raises
    ------
    ValueError
        When no order satisfying the constraints was found.
    """
    if not max_run and not min_distance:
        return stream.shuffle(items)
    order: list[tuple] = []
    for it in items:
        k = (it[run_key], it[item_key])
        if k not in order:
            order.append(k)
    for _ in range(MAX_SHUFFLE_ATTEMPTS):
        buckets = {k: [] for k in order}
        for it in items:
            buckets[(it[run_key], it[item_key])].append(it)
        out: list[dict] = []
        runs: list = []
        recent: list = []
        n = len(items)
        while len(out) < n:
            # The run value that may not continue, and the items shown too recently.
            blocked = runs[-1] if max_run and len(runs) >= max_run and runs[-max_run:].count(runs[-1]) == max_run \
                else _NOTHING
            near = recent[-(min_distance - 1):] if min_distance > 1 else ()
            ok = [(k, b) for k, b in buckets.items() if b and k[0] != blocked and k[1] not in near]
            if not ok:
                break
            r = stream.below(sum(len(b) for _, b in ok))
            for k, b in ok:
                if r < len(b):
                    out.append(b.pop(r))
                    runs.append(k[0])
                    recent.append(k[1])
                    break
                r -= len(b)
        if len(out) == len(items):
            return out
    raise UserError(f"design: no trial order satisfies max_run={max_run} and min_repeat_distance="
                     f"{min_distance} for {len(items)} trials; relax the constraints")


def scene_order(protocol: Protocol, cb: int, stream: _Stream) -> list[str]:
    scenes = list(protocol.scenes)
    if protocol.scene_order == "latin_square":
        return [scenes[i] for i in balanced_latin_square_row(len(scenes), cb)]
    if protocol.scene_order == "random":
        return stream.shuffle(scenes)
    return scenes


def _main_items(protocol: Protocol, scene: str, scene_idx: int, cb: int, stream: _Stream) -> list[dict]:
    """The answered trials of one scene (before ordering): the family's items; for an adaptive design each
    procedure's ``stop.trials`` slots (the reference and the varied condition; its level is chosen when the
    trial comes, from the answers before it: :mod:`studyapp.runner.adaptive`)."""
    fam = families.get(protocol.family)
    if protocol.adaptive is not None:
        a = protocol.adaptive
        return [it for c in a.varied for it in fam.adaptive_items(a.reference, c, scene, a.cap, stream)]
    return fam.main_items(
        protocol.design_conditions, scene, protocol.repetitions, position_balance=protocol.position_balance,
        flip_seed=cb + scene_idx, stream=stream)


def _practice(protocol: Protocol, legacy: bool = False) -> list[dict]:
    """The practice trials, after the practice scene's labelled reference if the design has references
    (not in ``legacy`` schedules, stored before that reference was added)."""
    p = protocol.practice
    if not p:
        return []
    groups = families.get(protocol.family).practice_groups(list(p["conditions"]))
    ref = [{"kind": "reference", "scene": p["scene"], "conditions": (protocol.reference,)}] \
        if protocol.reference and not legacy else []
    return ref + [{"kind": "practice", "scene": p["scene"], "conditions": g} for g in groups]


def _insert_catch(protocol: Protocol, main: list[dict], stream: _Stream) -> list[dict]:
    catch = protocol.catch
    if not catch or not catch["count"] or not main:
        return main
    out = list(main)
    n = catch["count"]
    if catch["kind"] == "degraded":
        good, bad = catch["good"], catch["bad"]
        # Slots spread evenly over the main trials, jittered within each stretch.
        for i in reversed(range(n)):
            lo, hi = (i * len(main)) // n + 1, ((i + 1) * len(main)) // n
            pos = min(len(out), lo + stream.below(max(1, hi - lo + 1)))
            scene = out[min(pos, len(out) - 1)]["scene"]
            conds, expected = families.get(protocol.family).catch_item(i, good, bad)
            out.insert(pos, {"kind": "catch", "scene": scene, "conditions": conds, "expected": expected})
    else:  # repeat: a 2afc trial shown again later, same order; the known answer is the earlier choice
        n = min(n, len(main) // 2)
        picks = sorted(stream.shuffle(list(range(len(main) // 2)))[:n])
        for k, i in enumerate(reversed(picks)):
            orig = out[i]
            lo = i + 3
            pos = min(len(out), lo + stream.below(max(1, len(out) - lo + 1)))
            out.insert(pos, {**orig, "kind": "catch", "expected": orig, "item": orig.get("item", "") + "#repeat"})
    return out


def scene_starts(trials: list) -> set[int]:
    """Positions in ``trials`` (objects with ``kind`` and ``scene``) where a new scene block starts: the first
    trial after the practice (and its reference) of each scene after the first scene. A catch trial that
    repeats an earlier scene's pair further on starts nothing (its scene has been seen)."""
    practice_end = max((i + 1 for i, t in enumerate(trials) if t.kind == "practice"), default=0)
    seen: set[str] = set()
    out: set[int] = set()
    for i, t in enumerate(trials):
        if i < practice_end or t.scene in seen:
            continue
        if seen:
            out.add(i)
        seen.add(t.scene)
    return out


def place_breaks(protocol: Protocol, trials: list, legacy: bool = False) -> list[bool]:
    """``break_before`` of each of ``trials`` (in presentation order).

    Blocked design: a break before each scene change (:func:`scene_starts`), and within a scene block after
    every ``breaks.every`` of the block's design trials (catch trials and the reference not counted, so a
    block of 30 pairs with ``every: 31`` has no break inside it). Interleaved design, or ``legacy`` (the rule
    of schedules stored before scene-change breaks, kept so that their participants can resume): a break
    before every ``breaks.every``-th answered trial, practice included. No ``breaks``: none.
    """
    if not protocol.breaks:
        return [False] * len(trials)
    every = protocol.breaks.get("every", 0)
    out: list[bool] = []
    if legacy or protocol.trial_order != "blocked":
        answered = 0
        for t in trials:
            brk = False
            if t.kind != "reference":
                brk = bool(every) and answered > 0 and answered % every == 0
                answered += 1
            out.append(brk)
        return out
    starts = scene_starts(trials)
    in_block, pending = 0, False
    for i, t in enumerate(trials):
        if i in starts:
            out.append(True)
            in_block, pending = 0, False
        elif pending and t.kind != "reference":
            out.append(True)
            pending = False
        else:
            out.append(False)
        if t.kind == "trial":
            in_block += 1
            pending = bool(every) and in_block % every == 0
    return out


BREAK_TEXT = "Take a short break."
SCENE_BREAK_TEXT = "Take a short break. The next scene starts after it."


def break_text(protocol: Protocol, trials: list, i: int) -> str:
    """What the break before ``trials[i]`` says: the protocol's ``breaks.text`` (default: that it is a break,
    and that the next scene starts after it where one does) where a scene starts or in an interleaved design;
    inside a scene block (or at a break of a schedule stored before scene-change breaks) only that it is a
    break, whatever the protocol's text says of scenes."""
    text = (protocol.breaks or {}).get("text")
    if protocol.trial_order != "blocked":
        return text or BREAK_TEXT
    if i in scene_starts(trials):
        return text or SCENE_BREAK_TEXT
    return BREAK_TEXT


def build_schedule(protocol: Protocol, participant: str, seed: int, legacy: bool = False
                   ) -> list[PlannedTrial]:
    """The participant's whole schedule (practice, references, trials, catch trials, breaks).

    Parameters
    ----------
    protocol : Protocol
    participant : str
        Pseudonymous participant id; gives the counterbalancing index (see module docstring).
    seed : int
        Study seed (>= 0).
    legacy : bool
        The rules of schedules stored before scene-change breaks (:func:`place_breaks`) and the practice
        scene's reference (:func:`_practice`): how a participant enrolled then is recognised on ``--resume``.

    Returns
    -------
    list of PlannedTrial
        Indexed 0..n-1 in presentation order. Same inputs -> identical list (and :func:`schedule_bytes`).
    """
    seed = SEED.check("seed", seed)
    if not participant or not isinstance(participant, str):
        raise UserError(f"participant={participant!r} is invalid: must be a non-empty string")
    cb = counterbalance_index(participant)
    stream = _Stream(SCHEDULE_FORMAT, protocol.content_hash, participant, seed)
    scenes = scene_order(protocol, cb, stream)
    refs: list[dict] = []
    main: list[dict] = []
    if protocol.trial_order == "blocked":
        for s_idx, scene in enumerate(scenes):
            block = _main_items(protocol, scene, protocol.scenes.index(scene), cb, stream)
            block = constrained_shuffle(block, stream, protocol.max_run, protocol.min_repeat_distance)
            if protocol.reference:
                block.insert(0, {"kind": "reference", "scene": scene, "conditions": (protocol.reference,)})
            main += block
    else:
        items = []
        for scene in scenes:
            items += _main_items(protocol, scene, protocol.scenes.index(scene), cb, stream)
        main = constrained_shuffle(items, stream, protocol.max_run, protocol.min_repeat_distance)
        if protocol.reference:
            refs = [{"kind": "reference", "scene": s, "conditions": (protocol.reference,)} for s in scenes]
    answered = [t for t in main if t.get("kind") != "reference"]
    with_catch = _insert_catch(protocol, answered, stream)
    if protocol.trial_order == "blocked" and protocol.reference:
        # Put the references back in front of each scene's first trial.
        merged, seen = [], set()
        for t in with_catch:
            if t["scene"] not in seen and t["scene"] in scenes:
                seen.add(t["scene"])
                merged.append({"kind": "reference", "scene": t["scene"], "conditions": (protocol.reference,)})
            merged.append(t)
        with_catch = merged
    sequence = _practice(protocol, legacy) + refs + with_catch
    # Indices, the repeat-catch answers, then the breaks.
    out, index_of = [], {}
    for i, t in enumerate(sequence):
        index_of[id(t)] = i
    for i, t in enumerate(sequence):
        expected = t.get("expected", "")
        if isinstance(expected, dict):
            expected = f"same:{index_of[id(expected)]}"
        out.append(PlannedTrial(index=i, kind=t.get("kind", "trial"), family=protocol.family,
                                scene=t["scene"], block=protocol.block, conditions=tuple(t["conditions"]),
                                expected=expected, item=t.get("item", "")))
    for t, brk in zip(out, place_breaks(protocol, out, legacy)):
        t.break_before = brk
    return out


def schedule_bytes(trials: list[PlannedTrial]) -> bytes:
    """Canonical JSON of a schedule (sorted keys, no whitespace): what 'byte-identical' compares."""
    rows = [asdict(t) for t in trials]
    return json.dumps(rows, sort_keys=True, separators=(",", ":"), ensure_ascii=True).encode("ascii")


def schedule_hash(trials: list[PlannedTrial]) -> str:
    return hashlib.sha256(schedule_bytes(trials)).hexdigest()


def n_answered(trials: list[PlannedTrial]) -> int:
    return sum(t.kind != "reference" for t in trials)
