"""Whole simulated studies in memory, for power analysis: no database, no files.

:func:`simulate_log` runs the schedules of ``n`` participants through the simulated observer and returns the
tidy trial log (:data:`data_schema.trial_log.ALL_COLUMNS`) that the same study would export, so that
``analysis`` can be run on many simulated replications (how many participants find a given effect).
"""

from __future__ import annotations

from pathlib import Path

from data_schema.errors import UserError
from data_schema.store import adaptive_columns, tidy_frame, tidy_row

from .adaptive_run import AdaptiveRun
from .observer import SimulatedObserver
from .protocol import Protocol
from .schedule import build_schedule
from .session import StimulusSet, ground_truth_stimuli, interpret, trial_display


def simulate_log(protocol: Protocol, participants: int | list[str], seed: int = 0, scale: float = 1.0,
                 stimuli_root: Path | None = None):
    """Tidy log (pandas DataFrame) of simulated participants answering ``protocol``.

    Parameters
    ----------
    protocol : Protocol
    participants : int or list of str
        ``n`` (ids ``P01``..) or explicit ids.
    seed : int
        Schedule and observer seed; the same inputs give the same log as ``studyapp run --simulate`` would
        record (without the session column's ids, which are ``<id>-sim`` here).
    scale, stimuli_root
        Where the stimulus images are (declared qualities stand in for the missing ones).
    """
    ids = [f"P{i + 1:02d}" for i in range(participants)] if isinstance(participants, int) else list(participants)
    if not ids:
        raise UserError("participants must name at least one participant")
    stimuli = StimulusSet(protocol, scale, stimuli_root, allow_declared=True)
    gt = ground_truth_stimuli(protocol, stimuli)
    gaze = protocol.render_geometry(scale).gaze if protocol.fixation_mark else None
    rows = []
    for pid in ids:
        obs = SimulatedObserver(protocol, pid, seed, gt)
        sched = build_schedule(protocol, pid, seed)
        total = sum(t.kind != "reference" for t in sched)
        # an adaptive design: each slot's level from the answers before it, as in a session (adaptive_run)
        adaptive = AdaptiveRun(protocol, pid, seed, [], "simulation") if protocol.adaptive is not None else None
        for t in sched:
            slot = adaptive is not None and adaptive.procedure_of(t) is not None
            if slot and adaptive.finished(t):
                continue  # the procedure stopped early: the slot is skipped (not in the log)
            res = obs.present(trial_display(protocol, t, stimuli, 0, total, gaze, adaptive))
            if t.kind == "reference":
                continue
            d = interpret(protocol, t, res)
            row = tidy_row(pid, f"{pid}-sim", t.block, t.scene, t.index, t.family, t.conditions,
                           d["chosen"], d["chosen_2"], d["response"], res.rt_s, t.kind)
            if slot:
                row.update(adaptive_columns(adaptive.record(t, d)))
            rows.append(row)
    return tidy_frame(rows)
