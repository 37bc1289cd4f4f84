"""The presentation interface: what the session runner asks of a window (or of the simulated observer).

The runner (scheduling, logging, resuming) talks only to a :class:`Presenter`; it never imports PsychoPy.
``studyapp.presentation.psychopy_window`` implements it with a real PsychoPy window; the simulated observer
implements it without any window. Everything here is plain data so that both sides can be tested apart.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Protocol, Sequence

from data_schema.errors import UserError
from data_schema.geometry import Display


class PresentationError(UserError):
    """A window could not be opened or used as required (no display, keyboard backend not psychtoolbox, an
    unreadable stimulus frame): one line, and the way out where there is one."""

Family = str  # a trial family name (data_schema.families)


@dataclass(frozen=True)
class Stimulus:
    """One stimulus: a still image (one frame) or a sequence of frames played at ``fps``."""

    condition: str
    frames: tuple[Path, ...]
    fps: float = 0.0  # 0 for a still image
    live: Any = None  # a studyapp.runner.live.LiveStimulus: rendered every refresh (no frames)

    @property
    def is_sequence(self) -> bool:
        return len(self.frames) > 1


@dataclass(frozen=True)
class TrialDisplay:
    """Everything a presenter needs to show one trial and collect its answer.

    ``stimuli`` holds 1 stimulus (``yes_no``), 2 (``2afc``, first = A/left) or N (``preference``). For
    ``2afc`` and ``preference`` the participant may switch among the stimuli (keys in ``switch_keys``) before
    committing; ``answer_keys`` maps a key name to the answer it records (``"A"``/``"B"``, ``"yes"``/``"no"``,
    or a stimulus index as a string for preference picks; ``""`` ends a preference trial after fewer than
    ``n_picks`` picks). A labelled reference (``kind == "reference"``) that is a sequence has no answer keys
    and simply plays; a still reference is acknowledged with a key (answer ``"seen"``).
    """

    index: int
    family: Family
    stimuli: tuple[Stimulus, ...]
    question: str
    answer_keys: dict[str, str]
    switch_keys: dict[str, int] = field(default_factory=dict)
    fixation_px: tuple[float, float] | None = None
    duration_s: float | None = None  # None: until answered (still images), else the sequence length
    black_before_s: float = 0.5
    label: str = ""  # e.g. "this is the ground truth" for the GT reference sequence
    n_picks: int = 1  # preference: 2 for "top two of N"
    progress: tuple[int, int] | None = None  # (trial number, of how many), shown to the participant
    scene: str = ""  # scene the stimuli show (the simulated observer compares against this scene's GT)
    kind: str = "trial"  # "trial", "practice", "catch" or "reference" (shown, answered with any key)
    key_reminder: str = "bottom"  # where the answer keys are recalled on the stimulus: "bottom", "top", "off"
    # adaptive designs: the varied parameter, the level shown (the stimuli of the varied condition are its
    # ``NAME(level)`` rendering) and the procedure (``VaFR@temple``); None/"" for a fixed design
    level: float | None = None
    varied: str | None = None
    procedure: str = ""


@dataclass
class TrialResult:
    """What happened in one trial. ``answers`` holds one entry per pick (two for top-two preference)."""

    answers: list[str]
    rt_s: float  # from the onset of the first stimulus frame (callOnFlip), seconds
    onset_s: float  # stimulus onset on the presenter's clock, seconds
    dropped_frames: int = 0
    switches: int = 0  # how often the participant switched between stimuli before committing
    gaze_left_fovea: bool | None = None  # None without an eye tracker
    escaped: bool = False  # Escape was pressed during this trial (no answer recorded)
    frames: list = field(default_factory=list)  # live trials: one studyapp.runner.live.FrameRecord per flip
    # (also of an attempt that Escape ended: ``escaped`` tells it is no answer's)


class Presenter(Protocol):
    """A window (or a simulation) that shows trials and returns answers."""

    def open(self, display: Display) -> dict:
        """Open a window covering ``display`` (the participant's physical display); return measured facts
        (``refresh_hz``, ``keyboard_backend``, ...)."""

    def instructions(self, text: str) -> None:
        """Show ``text`` until the participant presses a key."""

    def preload(self, trial: TrialDisplay) -> None:
        """Load the next trial's stimuli (called during the black interval)."""

    def present(self, trial: TrialDisplay) -> TrialResult:
        """Show one trial and return its result."""

    def pause(self) -> Literal["resume", "end"]:
        """After Escape: ask whether to resume or end the session."""

    def message(self, text: str, seconds: float) -> None:
        """Show a message (break, end of session) for ``seconds``."""

    def rest(self, text: str, seconds: float) -> None:
        """A break: ``text`` with the seconds left counting down, then wait for the continue key."""

    def close(self) -> None:
        """Close the window."""


#: The session keys of every presenter: Escape pauses a trial, then R resumes or E ends the session; SPACE
#: ends a break once its countdown is over. After a failed eye-tracker validation the experimenter repeats the
#: calibration (R), skips the check (S) or ends the session (E).
ESCAPE = "escape"
CONTINUE_KEY = "space"
RESUME_KEY, END_KEY = "r", "e"
REPEAT_KEY, SKIP_KEY = "r", "s"

KEY_REMINDER_PLACES = ("bottom", "top", "off")


def key_text(key: str) -> str:
    """A key name as the participant reads it: ``y`` -> ``Y``, ``left`` -> ``Left``, ``space`` -> ``SPACE``.
    """
    return key.upper() if len(key) == 1 or key == "space" else key.capitalize()


def key_reminder_text(trial: TrialDisplay) -> str:
    """The one-line reminder of a trial's keys, e.g. ``"1: A   2: B   Left / Right: switch"`` (answers by
    their meaning: a preference pick by the stimulus label, ``""`` as "done"); empty for a trial without
    keys."""
    from data_schema import families

    labels = families.get(trial.family).labels(len(trial.stimuli))

    def meaning(answer: str) -> str:
        if answer == "":
            return "done"
        if answer.isdigit() and families.get(trial.family).has_picks and int(answer) < len(labels):
            return labels[int(answer)]
        return answer

    parts = [f"{key_text(k)}: {meaning(a)}" for k, a in trial.answer_keys.items()]
    if trial.switch_keys:
        parts.append(" / ".join(key_text(k) for k in trial.switch_keys) + ": switch")
    return "   ".join(parts)


def stimulus_paths(stimuli: Sequence[Stimulus]) -> list[Path]:
    """Every frame file of ``stimuli``, in order (for pre-flight checks that files exist)."""
    return [f for s in stimuli for f in s.frames]
