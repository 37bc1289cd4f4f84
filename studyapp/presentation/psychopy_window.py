"""A real PsychoPy window implementing :class:`studyapp.presentation.base.Presenter`.

This is the only module of studyapp that imports PsychoPy, and it does so lazily (inside :meth:`open`), so
that importing it on a machine without a display or without PsychoPy costs nothing and fails only when a
window is really asked for.

What a trial looks like (:meth:`PsychoPyPresenter.present`)
----------------------------------------------------------
1. **Black interval** of ``trial.black_before_s`` seconds (with the trial label, e.g. "this is the ground
   truth", and the progress indicator in dim text). The trial's stimuli are decoded and uploaded to the GPU
   *inside* this interval (:class:`psychopy.core.StaticPeriod`); if loading overran the interval the overrun
   is recorded in :attr:`PsychoPyPresenter.trial_info`. Calling :meth:`preload` earlier starts the black
   interval and the loading at once; :meth:`present` then only waits for what is left of the interval.
2. **Stimulus**: still images are drawn until answered; sequences (``Stimulus.frames`` pre-decoded into one
   texture each) are drawn one frame per flip, frame ``k = floor((t_flip - t_onset) * fps)`` of the sequence,
   so a dropped flip skips a frame instead of stretching the sequence. ``yes_no`` sequences play once for
   ``duration_s`` (answers are accepted from onset; the sequence always plays to its end, then the question
   stays up until answered); in ``2afc``/``preference`` trials sequences loop and the participant switches
   among the stimuli with ``trial.switch_keys`` (a switch restarts the sequence) before committing.
3. **Fixation mark** at ``trial.fixation_px`` (stimulus pixel coordinates: x right, y down, origin at the
   image's top-left corner, as the foveation mappings use), drawn over every stimulus frame, with the
   overlays: the reference's label (top centre, for the whole reference), "practice" (top right) on a
   practice trial and the key reminder (``trial.key_reminder``: a line at the bottom or top on a dark band,
   or none). A practice trial says "practice" where the others show their number ("3 / 96", practice and
   references not counted).
4. **Answers**: ``trial.answer_keys`` maps key names (psychtoolbox names: ``left``, ``a``, ``1``,
   ``space``...) to the recorded answer. ``preference`` trials collect ``trial.n_picks`` distinct picks; a key
   whose answer is ``""`` ends the picking early ("only one"). ``rt_s`` runs from the onset flip of the first
   stimulus frame (the keyboard clock is reset with ``win.callOnFlip``) to the key press that completed the
   answer.
5. **Escape** ends the trial at once with ``escaped=True`` and no answer (pressed during the black interval,
   before the stimulus is shown; ``onset_s`` is then NaN); the runner then calls :meth:`pause` ("R" resume /
   "E" end) and re-presents the trial on resume.

Per trial the presenter records the onset time (``win.flip()`` time stamp on PsychoPy's monotonic clock), the
number of dropped frames (``win.recordFrameIntervals`` / ``win.nDroppedFrames``) and, with an eye tracker
(``eyetracker="mousegaze"`` simulates one with the mouse through ``psychopy.iohub``), every gaze sample and
whether the gaze left the foveal disc of radius ``fovea_deg`` around the fixation point.
"""

from __future__ import annotations

import collections
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Literal

import numpy as np

from data_schema import families
from data_schema.errors import UserError
from data_schema.geometry import Display

from ._texture import TextureRef
from .base import (
    CONTINUE_KEY,
    END_KEY,
    ESCAPE,
    RESUME_KEY,
    PresentationError,
    TrialDisplay,
    TrialResult,
    key_reminder_text,
    key_text,
)
EventHook = Callable[[str, dict], None]


@dataclass(frozen=True)
class Placement:
    """Where a ``img_w`` x ``img_h`` stimulus lands in a ``win_w`` x ``win_h`` window.

    The window is the participant's display and a stimulus subtends the display's visual angle, so the image
    is scaled to cover the window (up from a smaller render, e.g. seed 003's 256x144 stimuli on a 1920x1080
    display), keeping its aspect ratio, and centred. ``left``/``top`` are whole window pixels from the window's
    top-left corner, so that at ``scale = 1`` every image pixel maps onto exactly one window pixel.
    """

    win_w: int
    win_h: int
    img_w: int
    img_h: int
    scale: float
    left: int
    top: int

    @classmethod
    def fit(cls, win_w: int, win_h: int, img_w: int, img_h: int) -> "Placement":
        scale = min(win_w / img_w, win_h / img_h)
        if abs(scale - 1.0) < 1e-12:
            scale = 1.0
        w, h = img_w * scale, img_h * scale
        # 1e-9 absorbs the round-off of w = img_w * (win_w / img_w)
        return cls(
            win_w,
            win_h,
            img_w,
            img_h,
            scale,
            int(math.floor((win_w - w) / 2 + 1e-9)),
            int(math.floor((win_h - h) / 2 + 1e-9)),
        )

    @property
    def size(self) -> tuple[float, float]:
        """Drawn size in window pixels."""
        return (self.img_w * self.scale, self.img_h * self.scale)

    @property
    def centre_pix(self) -> tuple[float, float]:
        """Image centre in PsychoPy ``pix`` units (origin at the window centre, y up)."""
        w, h = self.size
        return (self.left + w / 2.0 - self.win_w / 2.0, self.win_h / 2.0 - (self.top + h / 2.0))

    def image_to_window(self, x: float, y: float) -> tuple[float, float]:
        """Image pixel coordinates (x right, y down, top-left origin) -> window pixels (same convention)."""
        return (self.left + x * self.scale, self.top + y * self.scale)

    def image_to_pix(self, x: float, y: float) -> tuple[float, float]:
        """Image pixel coordinates -> PsychoPy ``pix`` units (origin at the window centre, y up)."""
        wx, wy = self.image_to_window(x, y)
        return (wx - self.win_w / 2.0, self.win_h / 2.0 - wy)


def sequence_frame(elapsed_s: float, fps: float, n_frames: int, loop: bool) -> int:
    """Index of the frame of an ``n_frames``-frame sequence at ``fps`` to show ``elapsed_s`` after onset.

    ``k = floor(elapsed_s * fps)`` (with a 1e-6 s guard against a flip time stamp landing a hair before a
    frame boundary), wrapped modulo ``n_frames`` when looping, else held on the last frame.
    """
    if n_frames <= 1 or fps <= 0:
        return 0
    k = int(math.floor(max(0.0, elapsed_s) * fps + 1e-6))
    return k % n_frames if loop else min(k, n_frames - 1)


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


def _stim_labels(trial: TrialDisplay) -> list[str]:
    return families.get(trial.family).labels(len(trial.stimuli))


def decode_image(path: Path):
    """Open and fully decode an image file into a PIL image in ``RGB`` (or ``RGBA``) mode (its size checked from
    the header first: :func:`data_schema.images.open_image`)."""
    from data_schema.images import open_image

    try:
        with open_image(path, load=True) as im:
            return im if im.mode in ("RGB", "RGBA") else im.convert("RGB")
    except ValueError as exc:  # one line naming the file (a UserError)
        raise PresentationError(str(exc).replace("cannot read image", "cannot read stimulus frame", 1)) from None


def _has_display() -> bool:
    import os
    import sys

    return not sys.platform.startswith("linux") or bool(
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )


def _set_text(stim, text: str) -> None:
    """Set a TextStim's text only when it changes (a change re-lays out the text, too slow for every
    frame)."""
    if stim.text != text:
        stim.text = text


class _Loaded:
    """A trial's stimuli decoded into textures: ``frames[i]`` is the list of ImageStims of stimulus ``i``."""

    def __init__(self, trial: TrialDisplay, frames: list[list], placements: list[Placement], load_s: float):
        self.trial = trial
        self.frames = frames
        self.placements = placements
        self.load_s = load_s

    def release(self) -> None:
        """Free the GPU textures now. ImageStims sit in reference cycles, so waiting for the garbage collector
        would hold tens of MB per large stimulus; the ids are then removed so that ``__del__`` cannot delete a
        texture name that OpenGL has meanwhile handed to a new stimulus."""
        import ctypes

        from pyglet import gl

        for seq in self.frames:
            for stim in seq:
                for attr in ("_texID", "_maskID"):
                    if hasattr(stim, attr):
                        gl.glDeleteTextures(1, ctypes.byref(getattr(stim, attr)))
                        delattr(stim, attr)
                if hasattr(stim, "_pixbuffID"):
                    gl.glDeleteBuffers(1, ctypes.byref(stim._pixbuffID))
                    del stim._pixbuffID
        self.frames = []


class PsychoPyPresenter:
    """A PsychoPy window that shows trials and collects keyboard answers (see the module docstring).

    Parameters
    ----------
    fixation_rgb : colour of the fixation cross (0-255 RGB); ``None`` draws no fixation mark.
    fixation_size_px, fixation_line_px : arm length and line width of the cross, window pixels.
    show_labels : draw "A"/"B" (2AFC) or "1".."N" (preference) in the top-left corner while switching.
    eyetracker : ``None``, ``"mousegaze"`` (psychopy.iohub's mouse-driven simulated eye tracker), ``"device"``
        (the iohub device of ``tracker``) or ``"pointer"`` (the window's mouse pointer); see :mod:`.eyetracker`.
    tracker : the protocol's ``eyetracker`` block: with ``calibrate`` or ``max_validation_error_deg`` the tracker
        is calibrated and validated at :meth:`open` (``facts["validation"]``).
    fovea_deg : radius of the foveal disc around the fixation point; a gaze sample farther away sets
        ``TrialResult.gaze_left_fovea``.
    gaze_log : with an eye tracker, append every gaze sample to this CSV file (``trial,t_s,x_px,y_px``: time
        from onset, window pixels, top-left origin), flushed and fsynced at the end of each trial.
    screenshot_dir : if set, the back buffer of the first frame of every stimulus shown is saved there as
        ``trial{index:04d}_stim{i}_{n}.png`` (for tests and for checking a protocol; costs a read-back).
    gpu : open the GPU backend in the window's OpenGL context at :meth:`open` (live trials rendered on the GPU):
        no OpenGL 4.3 then fails there, in one line, before anything is recorded.
    on_event : called as ``on_event(name, info)`` at ``instructions``, ``black``, ``onset``, ``switch``,
        ``pick``, ``question``, ``pause`` and ``message`` (after the flip that shows it), e.g. to drive tests.
    """

    def __init__(
        self,
        *,
        fixation_rgb: tuple[int, int, int] | None = (255, 0, 0),
        fixation_size_px: int = 16,
        fixation_line_px: int = 2,
        show_labels: bool = True,
        eyetracker: str | None = None,
        fovea_deg: float = 2.5,
        screenshot_dir: str | Path | None = None,
        gaze_log: str | Path | None = None,
        on_event: EventHook | None = None,
        text_height_px: int | None = None,
        tracker: dict | None = None,
        required_tracker: bool = False,
        gpu: bool = False,
    ):
        if eyetracker not in (None, "mousegaze", "device", "pointer"):
            raise UserError(f"eyetracker={eyetracker!r} is not supported: use None, 'mousegaze', 'device' or "
                            "'pointer'")
        if eyetracker == "device" and not (tracker or {}).get("device"):
            raise UserError("eyetracker='device' needs a tracker block with the iohub device")
        if not (math.isfinite(fovea_deg) and fovea_deg > 0):
            raise UserError(f"fovea_deg={fovea_deg!r} is out of range: must be > 0")
        self.fixation_rgb = fixation_rgb
        self.fixation_size_px = int(fixation_size_px)
        self.fixation_line_px = int(fixation_line_px)
        self.show_labels = show_labels
        self.eyetracker = eyetracker
        self.tracker_spec = dict(tracker or {})  # the protocol's eyetracker block (device, settings, calibrate...)
        self.required_tracker = required_tracker  # live gaze-contingent trials cannot run without it
        self.gpu = gpu  # live trials render on the GPU backend in this window's context: checked at open()
        self.fovea_deg = float(fovea_deg)
        self.screenshot_dir = Path(screenshot_dir) if screenshot_dir is not None else None
        self.gaze_log = Path(gaze_log) if gaze_log is not None else None
        self.on_event = on_event
        self.text_height_px = None if text_height_px is None else int(text_height_px)
        self.win = None
        self.display: Display | None = None
        self.facts: dict = {}
        self.trial_info: list[dict] = []  # one dict per presented trial: load time, overrun, onsets, gaze...
        self.text_layout: dict[int, dict] = {}  # trial -> the black interval's text: height, box, window
        self._loaded: dict[int, _Loaded] = {}
        self._handled = collections.deque(maxlen=256)  # key presses already acted on (see _poll_keys)
        self._prefetched: dict[int, list] = {}  # trial index -> futures of decoded frames, in order
        self._pool = None
        self._black_since: float | None = None
        self.tracker = None  # the EyeTracker (.eyetracker) once started: gaze, calibration, validation
        self._n_shots = 0

    # ------------------------------------------------------------------ window
    def open(self, display: Display) -> dict:
        """Open the window and the psychtoolbox keyboard; return measured facts.

        Raises :class:`PresentationError` if PsychoPy cannot open a window or if the keyboard backend is not
        psychtoolbox (PsychoPy silently falls back to a polling backend whose key names and times differ).
        """
        try:
            import psychopy
            from psychopy import core, logging, monitors, visual
            from psychopy.hardware import keyboard
        except Exception as exc:  # no display, missing package...
            hint = (
                " (no DISPLAY: run under a display or Xvfb, e.g. xvfb-run -a)" if not _has_display() else ""
            )
            raise PresentationError(
                f"cannot import PsychoPy's window modules: {type(exc).__name__}: {exc}{hint}"
            ) from None
        self._core, self._visual, self._logging = core, visual, logging
        self._now = logging.defaultClock.getTime  # the clock of win.flip()'s time stamps
        import pyglet

        n_screens = len(pyglet.canvas.get_display().get_screens())
        if display.screen >= n_screens:  # PsychoPy would silently open the window on screen 0
            raise PresentationError(
                f"display.screen={display.screen} does not exist: this machine has {n_screens} screen(s), "
                f"0..{n_screens - 1}"
            )
        mon = monitors.Monitor("studyapp", width=display.width_cm, distance=display.distance_cm)
        mon.setSizePix([display.width_px, display.height_px])
        try:
            self.win = visual.Window(
                size=(display.width_px, display.height_px),
                fullscr=display.fullscreen,
                screen=display.screen,
                monitor=mon,
                units="pix",
                color=(-1, -1, -1),
                colorSpace="rgb",
                allowGUI=not display.fullscreen,
                checkTiming=False,
                waitBlanking=True,
            )
        except Exception as exc:
            raise PresentationError(f"cannot open a PsychoPy window: {type(exc).__name__}: {exc}") from None
        self.kb = keyboard.Keyboard()
        backend = self.kb.getBackend()
        if backend != "ptb":
            self.close()
            raise PresentationError(
                f"keyboard backend is {backend!r}, not 'ptb': psychtoolbox did not load (on Debian install "
                "libjack-jackd2-0); refusing to run with imprecise reaction times"
            )
        self.display = display
        self.win.mouseVisible = False  # no pointer over the stimuli (MouseGaze still follows the mouse)
        measured = self.win.getActualFrameRate(nIdentical=10, nMaxFrames=120, nWarmUpFrames=10, threshold=1)
        period = 1.0 / (measured or display.refresh_hz)
        self.win.refreshThreshold = 1.2 * period
        self._frame_period = period
        try:
            from importlib.metadata import version

            ptb_version = version("psychtoolbox")
        except Exception:
            ptb_version = None
        self.facts = {
            "presenter": "PsychoPyPresenter",
            "software": {
                "psychopy": psychopy.__version__,
                "pyglet": pyglet.version,
                "psychtoolbox": ptb_version,
            },
            "refresh_hz": float(measured) if measured else None,
            "refresh_hz_nominal": float(display.refresh_hz),
            "keyboard_backend": backend,
            "psychopy_version": psychopy.__version__,
            "pyglet_version": pyglet.version,
            "window_size_px": [int(v) for v in self.win.size],
            "window_pos_px": [int(v) for v in self._window_location()],
            "window_matches_display": [int(v) for v in self.win.size]
            == [display.width_px, display.height_px],
            "fullscreen": bool(display.fullscreen),
            "screen": int(display.screen),
            "pixels_per_degree": display.ppd,
            "fov_y_deg": display.fov_y_deg,
            "gl_renderer": pyglet.gl.gl_info.get_renderer(),
            "eyetracker": None,
        }
        self._make_stims()
        if self.gpu:
            self.facts["gpu"] = self._open_gpu()
        if self.eyetracker:
            self._start_eyetracker()
        return dict(self.facts)

    def _make_stims(self) -> None:
        visual, win = self._visual, self.win
        ww, wh = (int(v) for v in win.size)
        # Text is laid out for the window: a height that reads at the viewing distance of the display (about
        # 1/36 of its height), wrapped inside it, and shrunk until the whole text fits (see _fit_text).
        h = self.text_height_px or max(14, min(40, round(wh / 36)))
        self._text_h = h
        self._text = visual.TextStim(
            win, text="", height=h, color=(0.8, 0.8, 0.8), wrapWidth=ww * 0.9, units="pix"
        )
        self._dim = visual.TextStim(
            win,
            text="",
            height=h * 0.75,
            color=(-0.3, -0.3, -0.3),
            units="pix",
            wrapWidth=ww * 0.9,
            pos=(0, -wh / 2 + h),
        )
        self._question = visual.TextStim(
            win, text="", height=h, color=(0.8, 0.8, 0.8), units="pix", wrapWidth=ww * 0.9
        )
        self._corner = visual.TextStim(
            win,
            text="",
            height=h,
            color=(1, 1, 1),
            units="pix",
            anchorHoriz="left",
            alignText="left",
            anchorVert="top",
            pos=(-ww / 2 + 8, wh / 2 - 8),
        )
        # Overlays over the stimulus: the reference's label (top centre), "practice" (top right) and the key
        # reminder on a dark band (bottom or top), readable over any stimulus.
        self._label = visual.TextStim(win, text="", height=h, color=(1, 1, 1), units="pix", anchorVert="top",
                                      pos=(0, wh / 2 - 8), wrapWidth=ww * 0.6)
        self._tag = visual.TextStim(win, text="practice", height=h, color=(1, 0.8, 0.2), units="pix",
                                    anchorHoriz="right", alignText="right", anchorVert="top",
                                    pos=(ww / 2 - 8, wh / 2 - 8))
        self._reminder = visual.TextStim(win, text="", height=h, color=(0.8, 0.8, 0.8), units="pix",
                                         wrapWidth=ww * 0.95)
        self._reminder_band = visual.Rect(win, width=ww, height=round(h * 1.6), units="pix",
                                          fillColor=(-1, -1, -1), lineColor=None, lineWidth=0, opacity=0.7)
        self._fix = []
        if self.fixation_rgb is not None:
            arm, line = self.fixation_size_px, self.fixation_line_px
            for w, hh in ((arm, line), (line, arm)):
                self._fix.append(
                    visual.Rect(
                        win,
                        width=w,
                        height=hh,
                        units="pix",
                        fillColor=self.fixation_rgb,
                        lineColor=None,
                        colorSpace="rgb255",
                        lineWidth=0,
                    )
                )

    def close(self) -> None:
        """Close the window and the eye tracker (safe to call twice)."""
        self._release_loaded()
        for futures in self._prefetched.values():
            for fut in futures:
                fut.cancel()
        self._prefetched.clear()
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self.tracker is not None:
            self.tracker.stop()
            self.tracker = None
        if self.win is not None:
            self.win.close()
            self.win = None

    def _open_gpu(self) -> dict:
        """The GPU backend's device in this window's context (its one-line error closes the window first)."""
        from renderers.gpu.context import get_device

        try:
            device = get_device()
        except UserError as exc:
            self.close()
            raise UserError(f"{exc} (live trials: backend: cpu on the protocol's conditions)") from None
        return {"context": device.source, "gl_version": device.version, "gl_renderer": device.renderer}

    def _require_open(self):
        if self.win is None:
            raise PresentationError("the window is not open: call open(display) first")

    def _emit(self, name: str, **info) -> None:
        if self.on_event is not None:
            self.on_event(name, info)

    # ------------------------------------------------------------------ eye tracking (.eyetracker)
    def _start_eyetracker(self) -> None:
        """Start the gaze source (:class:`.eyetracker.EyeTracker`) into ``facts["eyetracker"]`` and, where the
        protocol's block asks, calibrate and validate it into ``facts["validation"]``."""
        from .eyetracker import EyeTracker, Screen

        self.tracker = EyeTracker(self.eyetracker, self.tracker_spec)
        self.facts["eyetracker"] = self.tracker.start(self.win, self._logging, self._window_location)
        if not self.facts["eyetracker"]["ok"]:
            self.tracker = None
            if self.required_tracker:
                reason = self.facts["eyetracker"]["reason"]
                self.close()
                raise PresentationError(f"the eye tracker did not start ({reason}): check its connection and "
                                        "the protocol's eyetracker block, or use gaze: fixation")
            return
        if self.tracker.wants_validation:
            screen = Screen(win=self.win, visual=self._visual, show_text=self._draw_text,
                            wait_key=self._wait_keys, poll_keys=lambda keys: [k.name for k in self._poll_keys(keys)],
                            now=self._now, emit=self._emit)
            try:
                self.facts["validation"] = self.tracker.calibrate_and_validate(screen, self.display)
            except BaseException:
                self.close()
                raise
            self._black_since = None

    def _window_location(self) -> tuple[int, int]:
        """Top-left corner of the window on its screen, pixels (0, 0 in fullscreen)."""
        if self.display.fullscreen:
            return (0, 0)
        return tuple(self.win.winHandle.get_location())

    def gaze_window_px(self) -> tuple[float, float] | None:
        """The newest gaze sample in window pixels (x right, y down, top-left origin), or None without a gaze
        source."""
        return None if self.tracker is None else self.tracker.gaze_window_px()

    # ------------------------------------------------------------------ drawing helpers
    def _fit_text(self, stim, text: str, max_h: float) -> None:
        """Set ``text`` on ``stim`` at the window's text height, shrunk until the wrapped text is at most
        ``max_h`` pixels high (never clipped by the window). Re-laid out only when the text changes."""
        if stim.text == text:
            return
        stim.height = self._text_h * (0.75 if stim is self._dim else 1.0)
        stim.text = text
        while text and stim.boundingBox[1] > max_h and stim.height > 6:
            stim.height = stim.height * 0.85
            stim.text = text + " "  # force a new layout at the new height
            stim.text = text

    def _draw_text(self, text: str, dim: str = "") -> None:
        wh = int(self.win.size[1])
        self._fit_text(self._text, text, 0.8 * wh)
        self._text.draw()
        if dim:
            self._fit_text(self._dim, dim, 2.5 * self._text_h)
            self._dim.pos = (0, -wh / 2 + 0.5 * self._dim.boundingBox[1] + 4)
            self._dim.draw()

    def _draw_question_in_margin(self, question: str, placement: Placement, below: float = 0.0) -> None:
        """Draw ``question`` centred in the margin below the stimulus, above ``below`` pixels at the bottom
        of the window (the key reminder's band), if that margin is at least 2 lines high (never over the
        stimulus; the question also shows in the black interval before each trial and after a sequence)."""
        margin = placement.win_h - (placement.top + placement.size[1]) - below
        if question and margin >= 2 * self._text_h:
            self._fit_text(self._question, question, margin)
            self._question.pos = (0, -placement.win_h / 2.0 + below + margin / 2.0)
            self._question.draw()

    def _progress_text(self, trial: TrialDisplay) -> str:
        if trial.kind == "practice":
            return "practice"
        if trial.progress is None:
            return ""
        k, n = trial.progress
        return f"{k} / {n}"

    def screenshot(self) -> np.ndarray:
        """The back buffer as an ``(H, W, 3)`` uint8 RGB array, row 0 at the top (call before ``flip``)."""
        self._require_open()
        im = self.win.getMovieFrame(buffer="back")
        self.win.movieFrames.clear()
        return np.asarray(im.convert("RGB"))

    def _save_shot(self, trial: TrialDisplay | None, stim: int | str) -> None:
        """Save the back buffer as ``trialNNNN_WHAT_K.png`` (``breakNNNN_WHAT_K.png`` without a trial)."""
        from PIL import Image

        from data_schema.atomic import atomic_path

        self.screenshot_dir.mkdir(parents=True, exist_ok=True)
        what = stim if isinstance(stim, str) else f"stim{stim}"
        who = "break" if trial is None else f"trial{trial.index:04d}"
        path = self.screenshot_dir / f"{who}_{what}_{self._n_shots}.png"
        self._n_shots += 1
        with atomic_path(path) as tmp:
            Image.fromarray(self.screenshot()).save(tmp, format="PNG")

    # ------------------------------------------------------------------ loading
    def load_image_stim(self, path: Path, placement: Placement | None = None):
        """Decode ``path`` and upload it into an ImageStim placed by ``placement`` (fit to the window if
        None).

        Returns ``(stim, placement)``. See :meth:`image_stim` for the upload.
        """
        return self.image_stim(decode_image(path), placement, name=str(path))

    def image_stim(self, im, placement: Placement | None = None, name: str = "image"):
        """Upload a decoded PIL image (``RGB`` or ``RGBA``) into a new ImageStim; return ``(stim,
        placement)``.

        The rows are uploaded as they are (top row first, 8 bits per channel, ``flipVert`` drawing) with no
        mipmaps and nearest-texel sampling at ``scale = 1``, so the window shows the file's pixel values
        unchanged. This skips the flip, RGBA conversion and mipmap generation that ``ImageStim(image=...)``
        does, which is most of its cost for a large stimulus (see docs/benchmarks.md, section presentation).
        """
        import ctypes

        from pyglet import gl

        w, h = im.size
        if placement is None:
            ww, wh = (int(v) for v in self.win.size)
            placement = Placement.fit(ww, wh, w, h)
        elif (w, h) != (placement.img_w, placement.img_h):
            raise PresentationError(
                f"{name}: frame size {w}x{h} differs from the sequence's first frame "
                f"{placement.img_w}x{placement.img_h}"
            )
        data = np.asarray(im)
        fmt = gl.GL_RGBA if im.mode == "RGBA" else gl.GL_RGB
        stim = self._visual.ImageStim(
            self.win, image=None, units="pix", size=placement.size, pos=placement.centre_pix
        )
        filt = gl.GL_NEAREST if placement.scale == 1.0 else gl.GL_LINEAR
        gl.glBindTexture(gl.GL_TEXTURE_2D, stim._texID)
        for param, value in (
            (gl.GL_TEXTURE_MIN_FILTER, filt),
            (gl.GL_TEXTURE_MAG_FILTER, filt),
            (gl.GL_TEXTURE_WRAP_S, gl.GL_CLAMP_TO_EDGE),
            (gl.GL_TEXTURE_WRAP_T, gl.GL_CLAMP_TO_EDGE),
            (gl.GL_TEXTURE_MAX_LEVEL, 0),
        ):
            gl.glTexParameteri(gl.GL_TEXTURE_2D, param, value)
        gl.glPixelStorei(gl.GL_UNPACK_ALIGNMENT, 1)
        gl.glTexImage2D(
            gl.GL_TEXTURE_2D,
            0,
            fmt,
            w,
            h,
            0,
            fmt,
            gl.GL_UNSIGNED_BYTE,
            data.ctypes.data_as(ctypes.POINTER(ctypes.c_ubyte)),
        )
        gl.glBindTexture(gl.GL_TEXTURE_2D, 0)
        stim.image = TextureRef(
            stim._texID
        )  # draw this texture as a top-row-first RGB image (no recolouring)
        return stim, placement

    def _decoder(self):
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="studyapp-decode")
        return self._pool

    def prefetch(self, trial: TrialDisplay) -> None:
        """Start decoding ``trial``'s frame files in the background (optional; not part of ``Presenter``).

        Call it while the previous trial is on screen (e.g. just before ``present(previous)``): decoding then
        overlaps the participant's answer, and :meth:`preload` / :meth:`present` only upload the textures in
        the black interval. At most two trials are kept prefetched (the oldest is dropped).
        """
        validate_trial(trial)
        if trial.index in self._prefetched or trial.index in self._loaded:
            return
        pool = self._decoder()
        self._prefetched[trial.index] = [
            pool.submit(decode_image, Path(f)) for s in trial.stimuli for f in s.frames
        ]
        while len(self._prefetched) > 2:
            for fut in self._prefetched.pop(next(iter(self._prefetched))):
                fut.cancel()

    def _load(self, trial: TrialDisplay) -> _Loaded:
        """Decode every frame (two threads: PIL releases the GIL while decoding, or already done by
        :meth:`prefetch`) and upload them in order on this thread (OpenGL's)."""
        t0 = time.perf_counter()
        frames, placements = [], []
        if trial.stimuli and trial.stimuli[0].live is not None:  # rendered during the trial
            return _Loaded(trial, [], [], 0.0)
        decoded = iter(
            self._prefetched.pop(trial.index, None)
            or [self._decoder().submit(decode_image, Path(f)) for s in trial.stimuli for f in s.frames]
        )
        for s in trial.stimuli:
            seq, placement = [], None
            for f in s.frames:
                stim, placement = self.image_stim(next(decoded).result(), placement, name=str(f))
                seq.append(stim)
            frames.append(seq)
            placements.append(placement)
        return _Loaded(trial, frames, placements, time.perf_counter() - t0)

    def _release_loaded(self) -> None:
        for item in self._loaded.values():
            item.release()
        self._loaded.clear()

    def _start_black(self, trial: TrialDisplay) -> None:
        lead = "\n\n".join(t for t in (trial.label, trial.question) if t)
        self._draw_text(lead, self._progress_text(trial))
        self.text_layout[trial.index] = {"text_height_px": float(self._text.height),
                                         "text_box_px": [float(v) for v in self._text.boundingBox],
                                         "window_px": [int(v) for v in self.win.size]}
        if self.screenshot_dir is not None:
            self._save_shot(trial, "black")
        self.win.flip()
        self._black_since = self._now()
        self._emit("black", trial=trial.index)

    def preload(self, trial: TrialDisplay) -> None:
        """Start the black interval before ``trial`` and load its stimuli in it (see the module docstring)."""
        self._require_open()
        validate_trial(trial)
        if trial.index in self._loaded:
            return
        self._start_black(trial)
        self._release_loaded()
        self._loaded = {trial.index: self._load(trial)}

    # ------------------------------------------------------------------ trials
    def _black_interval(self, trial: TrialDisplay) -> tuple[_Loaded, bool]:
        """Show (or finish) the black interval before ``trial`` with its stimuli loaded in it; return them
        and whether loading overran the interval."""
        core = self._core
        if trial.index in self._loaded and self._black_since is not None:  # preload() started it
            loaded = self._loaded.pop(trial.index)
            remaining = trial.black_before_s - (self._now() - self._black_since)
            if remaining > 0:
                core.wait(remaining, hogCPUperiod=min(remaining, 0.02))
            overran = remaining < 0
        else:
            self._start_black(trial)
            period = core.StaticPeriod(win=self.win, screenHz=1.0 / self._frame_period)
            period.start(trial.black_before_s)
            loaded = self._loaded.pop(trial.index, None) or self._load(trial)
            overran = period.complete() != 1
        self._release_loaded()
        self._black_since = None
        return loaded, overran

    def _draw_stimulus(
        self, trial: TrialDisplay, loaded: _Loaded, state: AnswerState, elapsed_s: float
    ) -> None:
        """Draw into the back buffer the current stimulus' frame at ``elapsed_s``, the fixation cross, the
        stimulus label with the picks so far, and the question if there is a margin for it."""
        current = state.current
        seq, placement = loaded.frames[current], loaded.placements[current]
        seq[sequence_frame(elapsed_s, trial.stimuli[current].fps, len(seq), families.get(trial.family).loops)].draw()
        self._draw_overlay(trial, state, placement)
        bottom_band = trial.key_reminder == "bottom" and key_reminder_text(trial)
        band = float(self._reminder_band.height) if bottom_band else 0.0
        self._draw_question_in_margin(trial.question, placement, band)

    def _draw_overlay(self, trial: TrialDisplay, state: AnswerState, placement: Placement | None) -> None:
        """The fixation mark (at ``trial.fixation_px`` of the stimulus image) and the stimulus label with the
        picks so far. ``placement`` None: a live stimulus covering the window (its render size maps onto it)."""
        if trial.fixation_px is not None and self.fixation_rgb is not None:
            if placement is None:
                live = trial.stimuli[state.current].live
                ww, wh = (int(v) for v in self.win.size)
                placement = Placement.fit(ww, wh, *live.render_size)
            fx, fy = placement.image_to_pix(*trial.fixation_px)
            for r in self._fix:
                r.pos = (fx, fy)
                r.draw()
        self._draw_reminder(trial)  # first: a top band must not cover the corner label or the practice tag
        labels = _stim_labels(trial)
        if self.show_labels and len(labels) > 1:
            picked = ("  picked: " + ", ".join(labels[int(p)] for p in state.picks)) if state.picks else ""
            _set_text(self._corner, labels[state.current] + picked)
            self._corner.draw()
        if trial.kind == "practice":
            self._tag.draw()

    def _draw_reminder(self, trial: TrialDisplay) -> None:
        """The key reminder band (``trial.key_reminder``) and, below a top band, the reference's label."""
        wh = int(self.win.size[1])
        text = key_reminder_text(trial) if trial.key_reminder != "off" else ""
        band_h = float(self._reminder_band.height)
        if text:
            _set_text(self._reminder, text)
            y = -wh / 2 + band_h / 2 if trial.key_reminder == "bottom" else wh / 2 - band_h / 2
            self._reminder_band.pos = self._reminder.pos = (0, y)
            self._reminder_band.draw()
            self._reminder.draw()
        if trial.label:
            _set_text(self._label, trial.label)
            self._label.pos = (0, wh / 2 - 8 - (band_h if text and trial.key_reminder == "top" else 0))
            self._label.draw()

    def _exposure(self, scene: str) -> float:
        from renderers.catalog import resolve

        return resolve(scene).exposure

    def _sample_gaze(self, trial: TrialDisplay, placement: Placement, t_s: float, info: dict) -> bool:
        """Record the last gaze sample at ``t_s`` after onset; True if it lies outside the foveal disc."""
        g = self.gaze_window_px()
        if g is None:
            return False
        info["gaze"].append([t_s, g[0], g[1]])
        if trial.fixation_px is None:
            return False
        fx, fy = placement.image_to_window(*trial.fixation_px)
        return math.hypot(g[0] - fx, g[1] - fy) > self.fovea_deg * self.display.ppd

    def present(self, trial: TrialDisplay) -> TrialResult:
        """Black interval (stimuli loaded in it), then the stimulus until answered; see the module
        docstring."""
        self._require_open()
        validate_trial(trial)
        if trial.stimuli[0].live is not None:
            return self._present_live(trial)
        win, kb = self.win, self.kb
        loaded, overran = self._black_interval(trial)
        info = {
            "trial": trial.index,
            "load_s": loaded.load_s,
            "black_overran": bool(overran),
            "onsets": [],
            "gaze": [],
        }
        self.trial_info.append(info)
        if self._poll_keys([ESCAPE]):  # Escape during the black interval: pause before the stimulus shows
            loaded.release()
            info["escaped_in_black"] = True
            return TrialResult(answers=[], rt_s=float("nan"), onset_s=float("nan"), escaped=True)

        keys_wanted = sorted({*trial.answer_keys, *trial.switch_keys, ESCAPE})
        # a yes/no (or unanswered) stimulus with a duration plays once, then the question stays up
        timed_once = trial.duration_s is not None and (not families.get(trial.family).loops or not trial.answer_keys)
        state = AnswerState(trial)
        onset = stim_onset = None  # first stimulus onset (the RT origin); current stimulus onset (its t = 0)
        onset_pending, shot_pending, playback_over = True, self.screenshot_dir is not None, False
        gaze_left = False if self.tracker is not None and trial.fixation_px is not None else None
        dropped0 = win.nDroppedFrames
        win.recordFrameIntervals = True
        next_flip = self._now() + self._frame_period
        try:
            while True:
                if timed_once and onset is not None:
                    playback_over = next_flip - onset >= trial.duration_s
                if playback_over:
                    self._draw_text(trial.question, self._progress_text(trial))
                else:
                    self._draw_stimulus(
                        trial, loaded, state, 0.0 if stim_onset is None else next_flip - stim_onset
                    )
                    if shot_pending:
                        self._save_shot(trial, state.current)
                        shot_pending = False
                if onset is None:  # RT clock and key queue restart with the first stimulus frame
                    win.callOnFlip(kb.clock.reset)
                    win.callOnFlip(kb.clearEvents)
                t_flip = win.flip()
                next_flip = t_flip + self._frame_period
                if onset_pending:
                    stim_onset = t_flip
                    onset = t_flip if onset is None else onset
                    info["onsets"].append([state.current, t_flip])
                    onset_pending = False
                    self._emit("onset", trial=trial.index, stimulus=state.current, t=t_flip)
                if playback_over and not state.answered and "question_shown" not in info:
                    info["question_shown"] = t_flip
                    self._emit("question", trial=trial.index)
                if self.tracker is not None and not playback_over:
                    outside = self._sample_gaze(trial, loaded.placements[state.current], t_flip - onset, info)
                    if gaze_left is not None:
                        gaze_left = gaze_left or outside
                for key in self._poll_keys(keys_wanted):
                    event = state.press(key.name, key.rt, can_switch=not playback_over)
                    if event == "escape":
                        state.picks, state.rt_s = [], None
                        return self._result(state, onset, win.nDroppedFrames - dropped0, gaze_left, True)
                    if event == "switch":
                        onset_pending, shot_pending = True, self.screenshot_dir is not None
                        self._emit("switch", trial=trial.index, stimulus=state.current)
                    elif event == "pick":
                        self._emit("pick", trial=trial.index, answer=state.picks[-1])
                if (state.answered or not trial.answer_keys) and (playback_over or not timed_once):
                    break
        finally:
            win.recordFrameIntervals = False
            loaded.release()
            self._write_gaze(trial.index, info["gaze"])
        return self._result(state, onset, win.nDroppedFrames - dropped0, gaze_left, False)

    def _present_live(self, trial: TrialDisplay) -> TrialResult:
        """A live trial (:mod:`.live_window`): the black interval, then a rendered frame every refresh."""
        from .live_window import LiveTrial, check_live_trial

        check_live_trial(trial)
        _, overran = self._black_interval(trial)
        self._info = {"trial": trial.index, "load_s": 0.0, "black_overran": bool(overran), "onsets": [],
                      "gaze": [], "live": True}
        self.trial_info.append(self._info)
        if self._poll_keys([ESCAPE]):
            self._info["escaped_in_black"] = True
            return TrialResult(answers=[], rt_s=float("nan"), onset_s=float("nan"), escaped=True)
        keys_wanted = sorted({*trial.answer_keys, *trial.switch_keys, ESCAPE})
        timed_once = not families.get(trial.family).loops or not trial.answer_keys
        state = AnswerState(trial)

        def on_switch(i):
            self._emit("switch", trial=trial.index, stimulus=i)

        onset, frames, dropped, escaped = LiveTrial(self, trial).run(state, keys_wanted, timed_once,
                                                                     self._poll_keys, on_switch)
        self._info["frames"] = len(frames)
        if escaped:
            state.picks, state.rt_s = [], None
        res = self._result(state, onset if onset is not None else float("nan"), dropped, None, escaped)
        res.frames = frames  # escaped: the interrupted attempt's flips (the runner keeps them apart, for replay)
        return res

    def fps_check_frames(self, live, seconds: float):
        """The frame-rate check's rows of one condition x scene (:func:`.live_window.fps_check_frames`)."""
        from .live_window import fps_check_frames

        self._require_open()
        return fps_check_frames(self, live, seconds)

    def _write_gaze(self, index: int, samples: list) -> None:
        """Append ``samples`` of trial ``index`` to :attr:`gaze_log` (header first), then flush and fsync."""
        if self.gaze_log is None or not samples:
            return
        import os

        new = not self.gaze_log.exists() or self.gaze_log.stat().st_size == 0
        with open(self.gaze_log, "a", encoding="utf-8", newline="\n") as fh:
            if new:
                fh.write("trial,t_s,x_px,y_px\n")
            fh.writelines(f"{index},{t:.6f},{x:.2f},{y:.2f}\n" for t, x, y in samples)
            fh.flush()
            os.fsync(fh.fileno())

    @staticmethod
    def _result(state: AnswerState, onset: float, dropped: int, gaze_left, escaped: bool) -> TrialResult:
        return TrialResult(
            answers=list(state.picks),
            rt_s=state.rt_s if state.answered else float("nan"),
            onset_s=float(onset),
            dropped_frames=int(dropped),
            switches=state.switches,
            gaze_left_fovea=gaze_left,
            escaped=escaped,
        )

    # ------------------------------------------------------------------ screens
    def _poll_keys(self, key_list: list[str] | None) -> list:
        """Key presses since the last poll, each once, in the order they went down.

        ``Keyboard.getKeys(waitRelease=False)`` skips a press that was already released when polled (a tap
        shorter than the time between two polls is lost), and ``waitRelease=True`` reports a press only once
        it is released; so both are polled, and a press seen before (still down last time, released now) is
        dropped by identity.
        """
        kb = self.kb
        got = kb.getKeys(keyList=key_list, waitRelease=False, clear=True) + kb.getKeys(
            keyList=key_list, waitRelease=True, clear=True
        )
        fresh = []
        for k in got:
            if not any(k is h for h in self._handled) and not any(k is f for f in fresh):
                fresh.append(k)
        self._handled.extend(fresh)
        return sorted(fresh, key=lambda k: k.tDown)

    def _wait_keys(self, key_list: list[str] | None) -> str:
        self.kb.clearEvents()
        while True:
            keys = self._poll_keys(key_list)
            if keys:
                return keys[0].name
            self._core.wait(0.005, hogCPUperiod=0)

    def instructions(self, text: str) -> None:
        """Show ``text`` until any key but Escape is pressed."""
        self._require_open()
        self._draw_text(text, "press any key to continue")
        self.win.flip()
        self._emit("instructions")
        while self._wait_keys(None) == ESCAPE:
            pass
        self._black_since = None

    def pause(self) -> Literal["resume", "end"]:
        """Ask whether to resume (R) or end (E) the session."""
        self._require_open()
        self._draw_text("Paused.\n\nPress R to resume or E to end the session.")
        self.win.flip()
        self._emit("pause")
        key = self._wait_keys([RESUME_KEY, END_KEY])
        self._black_since = None
        return "resume" if key == RESUME_KEY else "end"

    def rest(self, text: str, seconds: float) -> None:
        """A break: ``text`` with the seconds left (updated once a second) for ``seconds``, then "press SPACE
        to continue" until it is pressed (keys pressed during the countdown do not end it)."""
        self._require_open()
        if not (math.isfinite(seconds) and seconds >= 0):
            raise UserError(f"seconds={seconds!r} is out of range: must be >= 0")
        end = self._now() + seconds
        shown = None
        while (left := math.ceil(end - self._now())) > 0:
            if left != shown:
                self._draw_text(f"{text}\n\n{left} s")
                if self.screenshot_dir is not None:
                    self._save_shot(None, f"{left}s")
                self.win.flip()
                self._emit("rest", text=text, left_s=left)
                shown = left
            self._core.wait(min(0.05, max(0.0, end - self._now())), hogCPUperiod=0)
        self._draw_text(f"{text}\n\npress {key_text(CONTINUE_KEY)} to continue")
        if self.screenshot_dir is not None:
            self._save_shot(None, "continue")
        self.win.flip()
        self._emit("rest", text=text, left_s=0)
        self._wait_keys([CONTINUE_KEY])  # (clears the keys pressed during the countdown first)
        self._black_since = None

    def message(self, text: str, seconds: float) -> None:
        """Show ``text`` for ``seconds`` (breaks, end of session)."""
        self._require_open()
        if not (math.isfinite(seconds) and seconds >= 0):
            raise UserError(f"seconds={seconds!r} is out of range: must be >= 0")
        self._draw_text(text)
        self.win.flip()
        self._emit("message", text=text)
        self._core.wait(seconds)
        self._black_since = None
