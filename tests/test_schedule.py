"""Scheduling: byte-identical for the same inputs, balanced positions and scene orders, constraints, extras."""

import itertools
from collections import Counter
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from studyapp.runner.protocol import load_protocol, protocol_from_data
from studyapp.runner.schedule import (
    BREAK_TEXT,
    _Stream,
    balanced_latin_square_row,
    break_text,
    build_schedule,
    constrained_shuffle,
    counterbalance_index,
    schedule_bytes,
    schedule_hash,
    scene_starts,
)

PROTOCOLS = Path(__file__).resolve().parents[1] / "protocols"


@pytest.fixture(scope="module")
def afc():
    return load_protocol(PROTOCOLS / "seed001_2afc.yaml", check_renderers=False)


@pytest.fixture(scope="module")
def task1():
    return load_protocol(PROTOCOLS / "seed003_task1.yaml", check_renderers=False)


@pytest.fixture(scope="module")
def task2():
    return load_protocol(PROTOCOLS / "seed003_task2.yaml", check_renderers=False)


def test_same_inputs_give_byte_identical_schedules(afc):
    a = schedule_bytes(build_schedule(afc, "P03", 7))
    b = schedule_bytes(build_schedule(afc, "P03", 7))
    assert a == b
    assert a != schedule_bytes(build_schedule(afc, "P03", 8))
    assert a != schedule_bytes(build_schedule(afc, "P04", 7))


def test_stream_is_a_function_of_its_key_only():
    a, b, c = _Stream(1, "x"), _Stream(1, "x"), _Stream(2, "x")
    xs = [a.below(1000) for _ in range(50)]
    assert xs == [b.below(1000) for _ in range(50)]
    assert xs != [c.below(1000) for _ in range(50)]
    assert all(0 <= v < 1000 for v in xs)
    assert sorted(_Stream(3).shuffle(list(range(20)))) == list(range(20))
    with pytest.raises(ValueError):
        a.below(0)


def test_counterbalance_index():
    assert counterbalance_index("P07") == 7
    assert counterbalance_index("subj-12") == 12
    assert counterbalance_index("anna") == counterbalance_index("anna") < 10**6


@pytest.mark.parametrize("n", range(1, 9))
def test_balanced_latin_square(n):
    rows = [balanced_latin_square_row(n, r) for r in range(n if n % 2 == 0 else 2 * n)]
    reps = 1 if n % 2 == 0 else 2
    for row in rows:
        assert sorted(row) == list(range(n))
    for pos in range(n):
        assert Counter(r[pos] for r in rows) == {v: reps for v in range(n)}
    pairs = Counter((r[i], r[i + 1]) for r in rows for i in range(n - 1))
    assert all(pairs[(a, b)] == reps for a in range(n) for b in range(n) if a != b)


def test_scene_order_is_a_latin_square_across_consecutive_participants(afc):
    orders = []
    for i in range(1, 7):
        sched = build_schedule(afc, f"P{i}", 0)
        seen = []
        for t in sched:
            if t.kind == "trial" and t.scene not in seen:
                seen.append(t.scene)
        orders.append(tuple(seen))
    assert len(set(orders)) == 6  # 3 scenes: the 6 rows of the balanced square are the 6 permutations
    for pos in range(3):
        assert Counter(o[pos] for o in orders) == {s: 2 for s in afc.scenes}


def test_2afc_pairs_and_position_balance(afc):
    pairs = list(itertools.combinations(afc.design_conditions, 2))
    both = Counter()
    for pid in ("P1", "P2"):
        main = [t for t in build_schedule(afc, pid, 3) if t.kind == "trial"]
        per = Counter((t.scene, frozenset(t.conditions)) for t in main)
        assert set(per.values()) == {3} and len(per) == 30
        own = Counter((t.scene, t.conditions) for t in main)
        for scene in afc.scenes:
            for a, b in pairs:
                assert {own[(scene, (a, b))], own[(scene, (b, a))]} == {1, 2}
        both.update(own)
    # Two consecutive participants together show every pair 3 times in each order.
    assert set(both.values()) == {3}


def test_2afc_no_pair_twice_in_a_row_and_catch_trials(afc):
    sched = build_schedule(afc, "P5", 11)
    main = [t for t in sched if t.kind in ("trial", "catch")]
    trials = [t for t in sched if t.kind == "trial"]
    for x, y in itertools.pairwise(trials):
        if x.scene == y.scene:
            assert frozenset(x.conditions) != frozenset(y.conditions)
    catch = [t for t in sched if t.kind == "catch"]
    assert len(catch) == 6
    for t in catch:
        assert set(t.conditions) == {"GT", "DEGRADED"}
        assert t.expected == ("A" if t.conditions[0] == "GT" else "B")
    assert Counter(t.expected for t in catch) == {"A": 3, "B": 3}
    assert main.index(catch[0]) > 0


def test_task1_reference_first_per_scene_in_seed_order(task1):
    sched = build_schedule(task1, "P2", 0)
    assert [t.kind for t in sched[:4]] == ["reference"] + ["practice"] * 3  # the practice scene's GT first
    assert [t.conditions[0] for t in sched[1:4]] == ["CC1", "CC4", "CC2"]  # best to worst
    sched = sched[4:]
    refs = [t for t in sched if t.kind == "reference"]
    assert [t.scene for t in refs] == list(task1.scenes)  # Study ... Sponza, in the seed's order
    for ref in refs:
        block = [t for t in sched if t.scene == ref.scene and t.kind != "practice"]
        assert block[0] is ref and ref.conditions == ("CC1",)
        trials = [t for t in block if t.kind == "trial"]
        assert Counter(t.conditions[0] for t in trials) == {c: 2 for c in task1.design_conditions}
        for x, y in itertools.pairwise(trials):
            assert x.conditions != y.conditions  # max_run 1
    catch = [t for t in sched if t.kind == "catch"]
    assert sorted((t.conditions[0], t.expected) for t in catch) == [("CC1", "yes")] * 2 + [("DEGRADED", "no")] * 2


def test_task2_interleaved_with_constraints_and_breaks(task2):
    sched = build_schedule(task2, "P9", 2)
    trials = [t for t in sched if t.kind == "trial"]
    assert len(trials) == 40 and len({t.scene for t in trials[:10]}) > 1  # interleaved across scenes
    for i in range(len(trials) - 2):
        assert len({t.conditions[0] for t in trials[i:i + 3]}) > 1  # max_run 2
    pos = {}
    for i, t in enumerate(trials):
        key = (t.scene, t.conditions[0])
        if key in pos:
            assert i - pos[key] >= 3
        pos[key] = i
    answered = [t for t in sched if t.kind != "reference"]
    assert [i for i, t in enumerate(answered) if t.break_before] == [20, 40]


SHIPPED = sorted(PROTOCOLS.glob("seed*.yaml"))


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_breaks_fall_at_scene_changes_or_say_break_only(path):
    p = load_protocol(path, check_renderers=False)
    for pid in ("P1", "P2", "P3", "P4", "P5", "P6"):
        sched = build_schedule(p, pid, 0)
        starts = scene_starts(sched)
        for t in sched:
            if not t.break_before:
                continue
            text = break_text(p, sched, t.index)
            assert "break" in text.lower()
            if "scene" in text.lower():  # says a scene starts only where one does
                assert t.index in starts and sched[t.index - 1].scene != t.scene
            else:
                assert text == BREAK_TEXT or p.trial_order == "interleaved"
        if p.trial_order == "blocked" and p.breaks:
            # seed001_2afc: blocks of 30 pairs (+ catch) and every: 31 -> a break at each scene change only
            assert {t.index for t in sched if t.break_before} == starts and len(starts) == len(p.scenes) - 1
            assert all("next scene starts" in break_text(p, sched, i) for i in starts)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_schedules_whose_breaks_fell_right_are_unchanged(path):
    """Interleaved designs and blocked designs without breaks keep the stored-schedule rule byte for byte,
    unless the design has a labelled reference (then shown before the practice too)."""
    p = load_protocol(path, check_renderers=False)
    now, before = build_schedule(p, "P3", 1), build_schedule(p, "P3", 1, legacy=True)
    same = schedule_bytes(now) == schedule_bytes(before)
    assert same == ((p.trial_order == "interleaved" or not p.breaks) and not (p.reference and p.practice))


@pytest.mark.parametrize("name", ["seed003_task1", "seed003_task1_live"])
def test_yes_no_practice_of_is_this_the_ground_truth_shows_the_ground_truth_first(name):
    p = load_protocol(PROTOCOLS / f"{name}.yaml", check_renderers=False)
    assert "ground truth" in p.question and p.reference_label == "This is the ground truth"
    sched = build_schedule(p, "P1", 0)
    first = next(t.index for t in sched if t.kind == "practice")
    assert first == 1 and sched[0].kind == "reference" and sched[0].conditions == (p.reference,)
    assert sched[0].scene == p.practice["scene"] and not sched[0].break_before
    old = build_schedule(p, "P1", 0, legacy=True)  # as stored before: the practice came first
    assert old[0].kind == "practice" and schedule_bytes(sched[1:]) != schedule_bytes(old)
    assert [(t.kind, t.scene, t.conditions) for t in sched[1:]] == [
        (t.kind, t.scene, t.conditions) for t in old]


def test_legacy_are_the_stored_rule(afc):
    """The rule of schedules stored before scene-change breaks: every 31 answered trials, practice counted."""
    sched = build_schedule(afc, "P1", 0, legacy=True)
    assert [t.index for t in sched if t.break_before] == [31, 62, 93]
    assert all(break_text(afc, sched, i) == BREAK_TEXT for i in (31, 62, 93))  # no scene starts there
    assert sorted(scene_starts(sched)) == [34, 66]


def test_breaks_every_n_within_a_long_block_say_break_only(afc):
    data = {**afc.data, "breaks": {"every": 12, "seconds": 5, "text": "Rest. The next scene starts soon."}}
    p = protocol_from_data(data, "every12", check_renderers=False)
    sched = build_schedule(p, "P2", 3)
    assert schedule_bytes(sched) == schedule_bytes(build_schedule(p, "P2", 3))  # reproducible
    starts = scene_starts(sched)
    inside = [t.index for t in sched if t.break_before and t.index not in starts]
    assert {t.index for t in sched if t.break_before} >= starts
    assert len(inside) == 2 * len(p.scenes)  # 30 design trials per block: after the 12th and the 24th
    first_main = next(t.index for t in sched if t.kind != "practice")
    for i in inside:
        block = sched[max(s for s in starts | {first_main} if s <= i):i]
        design = [t for t in block if t.kind == "trial"]
        assert len(design) in (12, 24) and block[-1].kind == "trial"  # right after the 12th / 24th
        assert break_text(p, sched, i) == BREAK_TEXT
    assert all(break_text(p, sched, i) == "Rest. The next scene starts soon." for i in starts)


def test_constrained_shuffle_reports_impossible_constraints():
    items = [{"run": "a", "item": "a"}] * 3 + [{"run": "b", "item": "b"}]
    with pytest.raises(ValueError, match="no trial order satisfies max_run=1"):
        constrained_shuffle(items, _Stream(0), max_run=1)


@given(st.lists(st.sampled_from("abcd"), min_size=1, max_size=24), st.integers(0, 2**31), st.integers(1, 3))
def test_constrained_shuffle_keeps_items_and_constraints(labels, seed, max_run):
    items = [{"run": c, "item": c, "i": i} for i, c in enumerate(labels)]
    try:
        out = constrained_shuffle(items, _Stream(seed), max_run=max_run)
    except ValueError:  # only when no order exists: the commonest label cannot be spread out
        most = Counter(labels).most_common(1)[0][1]
        assert most > max_run * (len(labels) - most + 1)
        return
    assert sorted(o["i"] for o in out) == list(range(len(labels)))
    runs = [len(list(g)) for _, g in itertools.groupby(o["run"] for o in out)]
    assert max(runs) <= max_run


def test_thousand_participants_are_distinct_and_stable(task1):
    hashes = {schedule_hash(build_schedule(task1, f"P{i}", 0)) for i in range(40)}
    assert len(hashes) == 40


def test_seed_and_participant_are_checked(task1):
    with pytest.raises(ValueError, match="seed=-1 is out of range"):
        build_schedule(task1, "P1", -1)
    with pytest.raises(ValueError, match="participant"):
        build_schedule(task1, "", 0)
