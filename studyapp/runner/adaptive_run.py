"""An adaptive session's procedures, rebuilt from the committed trials (exact resume).

The schedule plans ``stop.trials`` slots per procedure (varied condition x scene), randomly interleaved within
a block (:func:`studyapp.runner.schedule.build_schedule`); the level of a slot is chosen when it comes, by the
procedure replayed from every answer committed before it (:func:`studyapp.runner.adaptive.replay`). Each
committed trial stores its level, its answer (correct or not) and the procedure's state after it, in the same
transaction as the response (:class:`data_schema.store.AdaptiveRow`), so after a SIGKILL at any point a
``--resume`` proposes exactly the level an uninterrupted run with the same seed and answers would have. A slot
of a procedure that stopped early (``stop.reversals``, ``stop.sd_below``) is committed as skipped, not shown.
"""

from __future__ import annotations

import hashlib
import json

from data_schema import families
from data_schema.store import AdaptiveRow, StoreError

from .adaptive import Procedure, level_condition, make_procedure, procedure_id
from .protocol import Protocol


def procedure_seed(seed: int, participant: str, pid: str) -> int:
    """The seed of one participant's procedure: BLAKE2b of (study seed, participant, procedure id)."""
    key = json.dumps([int(seed), participant, pid]).encode()
    return int.from_bytes(hashlib.blake2b(key, digest_size=4).digest(), "little")


def varied_of(protocol: Protocol, conditions) -> str | None:
    """The varied condition a planned trial shows (None: not an adaptive slot)."""
    if protocol.adaptive is None:
        return None
    return next((c for c in conditions if c in protocol.adaptive.varied), None)


def state_json(proc: Procedure) -> str:
    """The procedure's state as stored (canonical JSON)."""
    return json.dumps(proc.state(), sort_keys=True, separators=(",", ":"))


class AdaptiveRun:
    """The procedures of one participant, replayed from the stored adaptive rows and kept up to date."""

    def __init__(self, protocol: Protocol, participant: str, seed: int, rows: list[dict], where: str) -> None:
        self.protocol = protocol
        self.design = protocol.adaptive
        self.family = families.get(protocol.family)
        self.participant, self.seed = participant, int(seed)
        self.procedures: dict[str, Procedure] = {}
        last: dict[str, dict] = {}
        for row in rows:
            proc = self._procedure(row["procedure"], where)
            if not row["skipped"]:
                proc.update(float(row["level"]), bool(row["correct"]))
            last[row["procedure"]] = row
        for pid, row in last.items():  # the replay must reach the state the last committed trial stored
            stored = json.loads(row["state"])
            now = self.procedures[pid].state()
            if stored.get("history") != now["history"] or stored.get("next_level") != now["next_level"]:
                raise StoreError(f"{where}: participant {participant!r}, trial {row['idx']}: procedure {pid} "
                                 "does not replay to its stored state (the database or the procedure changed): "
                                 "cannot resume")

    def _procedure(self, pid: str, where: str = "") -> Procedure:
        if pid not in self.procedures:
            condition = pid.rsplit("@", 1)[0]
            if condition not in self.design.varied:
                raise StoreError(f"{where}: procedure {pid!r} is not one of the protocol's: cannot resume")
            self.procedures[pid] = make_procedure(self.design.spec(condition),
                                                  procedure_seed(self.seed, self.participant, pid))
        return self.procedures[pid]

    def procedure_of(self, t) -> str | None:
        """The procedure id of planned trial ``t`` (None: not an adaptive slot)."""
        c = varied_of(self.protocol, t.conditions) if t.kind == "trial" else None
        return None if c is None else procedure_id(c, t.scene)

    def finished(self, t) -> bool:
        """Whether ``t``'s procedure has stopped (its slot is skipped)."""
        return self._procedure(self.procedure_of(t)).finished()

    def trials(self, t) -> int:
        """Answers ``t``'s procedure has had (a display made before this count changed is stale)."""
        pid = self.procedure_of(t)
        return -1 if pid is None else len(self._procedure(pid).history)

    def shown(self, t) -> tuple[tuple[str, ...], float, str, str]:
        """``t``'s conditions as shown (the varied one at its procedure's next level), the level, the varied
        parameter and the procedure id."""
        pid = self.procedure_of(t)
        test = pid.rsplit("@", 1)[0]
        level = self._procedure(pid).next_level()
        shown = tuple(level_condition(c, level) if c == test else c for c in t.conditions)
        return shown, level, self.design.varied[test].param, pid

    def record(self, t, derived: dict) -> AdaptiveRow:
        """Update ``t``'s procedure with the answer (``derived``: the family's interpretation) and return the
        row to commit with the response."""
        shown, level, varied, pid = self.shown(t)
        test = pid.rsplit("@", 1)[0]
        proc = self._procedure(pid)
        correct = bool(self.family.adaptive_correct(t.conditions, test, derived))
        proc.update(level, correct)
        est = proc.estimate()
        return AdaptiveRow(pid, varied, level, proc.axis.to_intensity(level), correct, est["mean"], est["sd"],
                           state_json(proc))

    def skip(self, t) -> AdaptiveRow:
        """The row of a slot whose procedure has stopped (nothing shown; the level it would have shown)."""
        shown, level, varied, pid = self.shown(t)
        proc = self._procedure(pid)
        est = proc.estimate()
        return AdaptiveRow(pid, varied, level, proc.axis.to_intensity(level), None, est["mean"], est["sd"],
                           state_json(proc), skipped=True)
