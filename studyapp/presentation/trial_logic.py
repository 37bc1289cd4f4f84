"""What a trial is apart from the window: its checks, the frame of a sequence to show, the answer keys'
bookkeeping.

Pure Python (no PsychoPy): the window's trial loop (:mod:`.psychopy_window`, :mod:`.live_window`) asks these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from data_schema import families
from data_schema.errors import UserError

from .base import ESCAPE, TrialDisplay


def sequence_frame(elapsed_s: float, fps: float, n_frames: int, loop: bool) -> int:
    """Index of the frame of an ``n_frames``-frame sequence at ``fps`` to show ``elapsed_s`` after onset.

    ``k = floor(elapsed_s * fps)`` (with a 1e-6 s guard against a flip time stamp landing a hair before a
    frame boundary), wrapped modulo ``n_frames`` when looping, else held on the last frame.
    """
    if n_frames <= 1 or fps <= 0:
        return 0
    k = int(math.floor(max(0.0, elapsed_s) * fps + 1e-6))
    return k % n_frames if loop else min(k, n_frames - 1)


def stimulus_time(next_flip: float, stim_onset: float | None, onset_pending: bool) -> float:
    """Seconds into the current stimulus at the coming flip: 0 for the first flip of a stimulus (none shown yet,
    or one just switched to, whose onset is that flip), else the time since its onset flip. A switched-to
    sequence therefore starts at its frame 0, not at the previous stimulus' elapsed time."""
    return 0.0 if stim_onset is None or onset_pending else next_flip - stim_onset


def validate_trial(trial: TrialDisplay) -> None:
    """One-line errors for a trial the window cannot show."""
    n = len(trial.stimuli)
    fam = families.get(trial.family)
    need = fam.stimuli_range(n)
    if not need[0] <= n <= need[1]:
        raise UserError(
            f"trial {trial.index}: family {trial.family!r} needs {need[0]}..{need[1]} stimuli, got {n}"
        )
    for s in trial.stimuli:
        if not s.frames and s.live is None:
            raise UserError(f"trial {trial.index}: stimulus {s.condition!r} has no frames")
        if s.is_sequence and not s.fps > 0:
            raise UserError(f"trial {trial.index}: sequence {s.condition!r} needs fps > 0, got {s.fps!r}")
    both = sorted(
        set(trial.switch_keys) & set(trial.answer_keys)
        | {ESCAPE} & (set(trial.switch_keys) | set(trial.answer_keys))
    )
    if both:
        raise UserError(
            f"trial {trial.index}: key {both[0]!r} cannot both switch and answer (escape pauses)"
        )
    for key, idx in trial.switch_keys.items():
        if not 0 <= idx < n:
            raise UserError(f"trial {trial.index}: switch key {key!r} -> {idx} is out of range 0..{n - 1}")
    if fam.has_picks and not 1 <= trial.n_picks <= n:
        raise UserError(f"trial {trial.index}: n_picks={trial.n_picks} is out of range 1..{n}")
    if fam.has_picks:
        for key, ans in trial.answer_keys.items():
            if ans != "" and not (ans.isdigit() and int(ans) < n):
                raise UserError(
                    f"trial {trial.index}: answer key {key!r} -> {ans!r} must be a stimulus index "
                    f"0..{n - 1} or '' (stop picking)"
                )
    if trial.black_before_s < 0 or (trial.duration_s is not None and not trial.duration_s > 0):
        raise UserError(f"trial {trial.index}: black_before_s must be >= 0 and duration_s > 0 or None")
    if not trial.answer_keys and trial.duration_s is None:
        raise UserError(f"trial {trial.index}: a trial without answer keys needs a duration_s")


@dataclass
class AnswerState:
    """The key bookkeeping of one trial, apart from the window: switching, answering, picking.

    ``press(name, rt_s)`` applies one key press (psychtoolbox key name, time from onset) and returns what it
    did: ``"escape"``, ``"switch"`` (``current`` changed), ``"pick"`` (a preference pick, more to come),
    ``"answer"`` (the answer is complete; ``rt_s`` is this key's time) or ``None`` (ignored: an unknown key, a
    switch to the stimulus already shown, a pick already made, any key after the answer but Escape).
    """

    trial: TrialDisplay
    current: int = 0
    switches: int = 0
    picks: list = field(default_factory=list)
    rt_s: float | None = None

    @property
    def answered(self) -> bool:
        return self.rt_s is not None

    def press(self, name: str, rt_s: float, can_switch: bool = True) -> str | None:
        t = self.trial
        if name == ESCAPE:
            return "escape"
        if self.answered:
            return None
        if name in t.switch_keys:
            if not can_switch or t.switch_keys[name] == self.current:
                return None
            self.current = t.switch_keys[name]
            self.switches += 1
            return "switch"
        if name not in t.answer_keys:
            return None
        ans = t.answer_keys[name]
        if not families.get(t.family).has_picks:
            if ans == "":
                return None
            self.picks, self.rt_s = [ans], float(rt_s)
            return "answer"
        if ans == "":  # "no further pick": ends the picking once at least one pick was made
            if not self.picks:
                return None
            self.rt_s = float(rt_s)
            return "answer"
        if ans in self.picks:
            return None
        self.picks.append(ans)
        if len(self.picks) >= t.n_picks:
            self.rt_s = float(rt_s)
            return "answer"
        return "pick"


def stim_labels(trial: TrialDisplay) -> list[str]:
    """The stimuli's names as the participant sees them ("A"/"B", "1".."N")."""
    return families.get(trial.family).labels(len(trial.stimuli))
