"""A real PsychoPy window implementing :class:`studyapp.presentation.base.Presenter`.

The presenter is the trial loop; its parts are the window and keyboard (:mod:`.window`), text layout
(:mod:`.text`), stimulus loading (:mod:`.loading`), the trial logic (:mod:`.trial_logic`), the eye tracker
(:mod:`.eyetracker`) and live trials (:mod:`.live_window`). PsychoPy is imported lazily (inside
:meth:`open`), so importing this module on a machine without a display or without PsychoPy costs nothing and fails only when a
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

import math
from pathlib import Path
from typing import Callable, Literal

import numpy as np

from data_schema import families
from data_schema.errors import UserError
from data_schema.geometry import Display, Placement

from .base import (
    CONTINUE_KEY,
    END_KEY,
    ESCAPE,
    RESUME_KEY,
    PresentationError,
    TrialDisplay,
    TrialResult,
    key_text,
)
from .loading import LoadedTrial, StimulusLoader, decode_image, texture_stim
from .text import TextLayout, progress_text
from .trial_logic import AnswerState, sequence_frame, stimulus_time, validate_trial
from .window import Window, open_window

# re-exported: the presenter's parts that callers and tests name from here
__all__ = ["PsychoPyPresenter", "PresentationError", "AnswerState", "sequence_frame", "validate_trial",
           "decode_image"]

EventHook = Callable[[str, dict], None]


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
        self.window: Window | None = None  # the window and keyboard (.window), once open
        self.text: TextLayout | None = None  # text and overlays (.text), once open
        self.loader = StimulusLoader()  # decoding and upload of the stimuli (.loading)
        self._black_since: float | None = None
        self.tracker = None  # the EyeTracker (.eyetracker) once started: gaze, calibration, validation
        self._n_shots = 0

    # ------------------------------------------------------------------ window
    def open(self, display: Display) -> dict:
        """Open the window and the psychtoolbox keyboard (:func:`.window.open_window`); return measured facts.

        Raises :class:`PresentationError` if PsychoPy cannot open a window or if the keyboard backend is not
        psychtoolbox (PsychoPy silently falls back to a polling backend whose key names and times differ).
        """
        self.window = open_window(display)
        self.win, self.kb, self.display = self.window.win, self.window.kb, display
        self.facts = dict(self.window.facts)
        self.text = TextLayout(self.win, self.window.visual, text_height_px=self.text_height_px,
                               fixation_rgb=self.fixation_rgb, fixation_size_px=self.fixation_size_px,
                               fixation_line_px=self.fixation_line_px, show_labels=self.show_labels)
        self.loader.attach(self.win, self.window.visual)
        if self.gpu:
            self.facts["gpu"] = self._open_gpu()
        if self.eyetracker:
            self._start_eyetracker()
        return dict(self.facts)

    def close(self) -> None:
        """Close the window and the eye tracker (safe to call twice)."""
        self.loader.close()
        if self.tracker is not None:
            self.tracker.stop()
            self.tracker = None
        if self.win is not None:
            self.window.close()
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

    # ------------------------------------------------------------------ the drawing interface (live trials)
    # What a trial loop drawing into this window uses (:class:`.live_window.LiveTrial`): the clock and refresh
    # period, text, overlays, textures, screenshots, events, the gaze and a scene's exposure.
    def now(self) -> float:
        """The clock of ``win.flip()``'s time stamps (seconds)."""
        return self.window.now()

    @property
    def frame_period(self) -> float:
        """The measured refresh period (seconds)."""
        return self.window.frame_period

    def emit(self, name: str, **info) -> None:
        """Call ``on_event(name, info)`` (if set)."""
        if self.on_event is not None:
            self.on_event(name, info)

    def draw_text(self, text: str, dim: str = "") -> None:
        """Draw ``text`` centred and ``dim`` in small dim text at the bottom
        (:meth:`.text.TextLayout.draw_text`)."""
        self.text.draw_text(text, dim)

    def draw_question(self, trial: TrialDisplay) -> None:
        """The screen after a sequence: the question, the trial's progress in dim text."""
        self.text.draw_text(trial.question, progress_text(trial))

    def draw_overlay(self, trial: TrialDisplay, current: int, picks: list,
                     placement: Placement | None = None) -> None:
        """The fixation mark, labels, key reminder and practice tag over stimulus ``current``
        (:meth:`.text.TextLayout.draw_overlay`). ``placement`` None: a live stimulus covering the window (its
        render size maps onto it)."""
        if placement is None:
            ww, wh = (int(v) for v in self.win.size)
            placement = Placement.fit(ww, wh, *trial.stimuli[current].live.render_size)
        self.text.draw_overlay(trial, current, picks, placement)

    def texture_stim(self, size: tuple[float, float], pos: tuple[float, float], width: int, height: int):
        """A new RGB texture of ``width`` x ``height`` texels drawn at ``pos`` with ``size`` (window ``pix``
        units), filled later (:func:`.loading.texture_stim`, :func:`.loading.update_texture`)."""
        return texture_stim(self.win, self.window.visual, size, pos, width, height)

    @staticmethod
    def exposure(scene: str) -> float:
        """The exposure a scene's frames are tone-mapped with."""
        from renderers.catalog import resolve

        return resolve(scene).exposure

    def gaze_window_px(self) -> tuple[float, float] | None:
        """The newest gaze sample in window pixels (x right, y down, top-left origin), or None without a gaze
        source."""
        return None if self.tracker is None else self.tracker.gaze_window_px()

    def screenshot(self) -> np.ndarray:
        """The back buffer as an ``(H, W, 3)`` uint8 RGB array, row 0 at the top (call before ``flip``)."""
        self._require_open()
        return self.window.screenshot()

    def save_shot(self, trial: TrialDisplay | None, stim: int | str) -> None:
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

    # ------------------------------------------------------------------ eye tracking (.eyetracker)
    def _start_eyetracker(self) -> None:
        """Start the gaze source (:class:`.eyetracker.EyeTracker`) into ``facts["eyetracker"]`` and, where the
        protocol's block asks, calibrate and validate it into ``facts["validation"]``."""
        from .eyetracker import EyeTracker, Screen

        self.tracker = EyeTracker(self.eyetracker, self.tracker_spec)
        self.facts["eyetracker"] = self.tracker.start(self.win, self.window.logging, self.window.location)
        if not self.facts["eyetracker"]["ok"]:
            self.tracker = None
            if self.required_tracker:
                reason = self.facts["eyetracker"]["reason"]
                self.close()
                raise PresentationError(f"the eye tracker did not start ({reason}): check its connection and "
                                        "the protocol's eyetracker block, or use gaze: fixation")
            return
        if self.tracker.wants_validation:
            screen = Screen(win=self.win, visual=self.window.visual, show_text=self.draw_text,
                            wait_key=self.window.wait_keys,
                            poll_keys=lambda keys: [k.name for k in self.window.poll_keys(keys)],
                            now=self.now, emit=self.emit)
            try:
                self.facts["validation"] = self.tracker.calibrate_and_validate(screen, self.display)
            except BaseException:
                self.close()
                raise
            self._black_since = None

    # ------------------------------------------------------------------ loading (.loading)
    def load_image_stim(self, path: Path, placement: Placement | None = None):
        """Decode ``path`` and upload it into an ImageStim (:meth:`.loading.StimulusLoader.image_stim`)."""
        return self.loader.load_image_stim(path, placement)

    def image_stim(self, im, placement: Placement | None = None, name: str = "image"):
        """Upload a decoded PIL image into a new ImageStim; return ``(stim, placement)``
        (:meth:`.loading.StimulusLoader.image_stim`)."""
        return self.loader.image_stim(im, placement, name)

    def prefetch(self, trial: TrialDisplay) -> None:
        """Start decoding ``trial``'s frame files in the background (optional; not part of ``Presenter``).

        Call it while the previous trial is on screen (e.g. just before ``present(previous)``): decoding then
        overlaps the participant's answer, and :meth:`preload` / :meth:`present` only upload the textures in
        the black interval. At most two trials are kept prefetched (the oldest is dropped).
        """
        self.loader.prefetch(trial)

    def _start_black(self, trial: TrialDisplay) -> None:
        lead = "\n\n".join(t for t in (trial.label, trial.question) if t)
        self.text.draw_text(lead, progress_text(trial))
        self.text_layout[trial.index] = self.text.text_record()
        if self.screenshot_dir is not None:
            self.save_shot(trial, "black")
        self.win.flip()
        self._black_since = self.now()
        self.emit("black", trial=trial.index)

    def preload(self, trial: TrialDisplay) -> None:
        """Start the black interval before ``trial`` and load its stimuli in it (see the module docstring)."""
        self._require_open()
        validate_trial(trial)
        if self.loader.is_loaded(trial.index):
            return
        self._start_black(trial)
        self.loader.preload(trial)

    # ------------------------------------------------------------------ trials
    def _black_interval(self, trial: TrialDisplay) -> tuple[LoadedTrial, bool]:
        """Show (or finish) the black interval before ``trial`` with its stimuli loaded in it; return them
        and whether loading overran the interval."""
        core = self.window.core
        if self.loader.is_loaded(trial.index) and self._black_since is not None:  # preload() started it
            loaded = self.loader.take(trial.index)
            remaining = trial.black_before_s - (self.now() - self._black_since)
            if remaining > 0:
                core.wait(remaining, hogCPUperiod=min(remaining, 0.02))
            overran = remaining < 0
        else:
            self._start_black(trial)
            period = core.StaticPeriod(win=self.win, screenHz=1.0 / self.frame_period)
            period.start(trial.black_before_s)
            loaded = self.loader.take(trial.index) or self.loader.load(trial)
            overran = period.complete() != 1
        self.loader.release_all()
        self._black_since = None
        return loaded, overran

    def _draw_stimulus(
        self, trial: TrialDisplay, loaded: LoadedTrial, state: AnswerState, elapsed_s: float
    ) -> None:
        """Draw into the back buffer the current stimulus' frame at ``elapsed_s``, the fixation cross, the
        stimulus label with the picks so far, and the question if there is a margin for it."""
        current = state.current
        seq, placement = loaded.frames[current], loaded.placements[current]
        seq[sequence_frame(elapsed_s, trial.stimuli[current].fps, len(seq), families.get(trial.family).loops)].draw()
        self.text.draw_overlay(trial, current, state.picks, placement)
        self.text.draw_question_in_margin(trial, placement)

    def _sample_gaze(self, trial: TrialDisplay, placement: Placement, t_s: float, info: dict) -> bool:
        """Record the last gaze sample at ``t_s`` after onset; True if it lies outside the foveal disc: its
        eccentricity seen from the fixation point (:meth:`data_schema.geometry.Display.outside_disc`) exceeds
        ``fovea_deg``."""
        g = self.gaze_window_px()
        if g is None:
            return False
        info["gaze"].append([t_s, g[0], g[1]])
        if trial.fixation_px is None:
            return False
        return self.display.outside_disc(g, placement.image_to_window(*trial.fixation_px), self.fovea_deg)

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
        if self.window.poll_keys([ESCAPE]):  # Escape in the black interval: pause before the stimulus shows
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
        next_flip = self.now() + self.frame_period
        try:
            while True:
                if timed_once and onset is not None:
                    playback_over = next_flip - onset >= trial.duration_s
                if playback_over:
                    self.draw_question(trial)
                else:
                    self._draw_stimulus(trial, loaded, state, stimulus_time(next_flip, stim_onset, onset_pending))
                    if shot_pending:
                        self.save_shot(trial, state.current)
                        shot_pending = False
                if onset is None:  # RT clock and key queue restart with the first stimulus frame
                    win.callOnFlip(kb.clock.reset)
                    win.callOnFlip(kb.clearEvents)
                t_flip = win.flip()
                next_flip = t_flip + self.frame_period
                if onset_pending:
                    stim_onset = t_flip
                    onset = t_flip if onset is None else onset
                    info["onsets"].append([state.current, t_flip])
                    onset_pending = False
                    self.emit("onset", trial=trial.index, stimulus=state.current, t=t_flip)
                if playback_over and not state.answered and "question_shown" not in info:
                    info["question_shown"] = t_flip
                    self.emit("question", trial=trial.index)
                if self.tracker is not None and not playback_over:
                    outside = self._sample_gaze(trial, loaded.placements[state.current], t_flip - onset, info)
                    if gaze_left is not None:
                        gaze_left = gaze_left or outside
                for key in self.window.poll_keys(keys_wanted):
                    event = state.press(key.name, key.rt, can_switch=not playback_over)
                    if event == "escape":
                        state.picks, state.rt_s = [], None
                        return self._result(state, onset, win.nDroppedFrames - dropped0, gaze_left, True)
                    if event == "switch":
                        onset_pending, shot_pending = True, self.screenshot_dir is not None
                        self.emit("switch", trial=trial.index, stimulus=state.current)
                    elif event == "pick":
                        self.emit("pick", trial=trial.index, answer=state.picks[-1])
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
        info = {"trial": trial.index, "load_s": 0.0, "black_overran": bool(overran), "onsets": [],
                "gaze": [], "live": True}
        self.trial_info.append(info)
        if self.window.poll_keys([ESCAPE]):
            info["escaped_in_black"] = True
            return TrialResult(answers=[], rt_s=float("nan"), onset_s=float("nan"), escaped=True)
        keys_wanted = sorted({*trial.answer_keys, *trial.switch_keys, ESCAPE})
        timed_once = not families.get(trial.family).loops or not trial.answer_keys
        state = AnswerState(trial)

        def on_switch(i):
            self.emit("switch", trial=trial.index, stimulus=i)

        onset, frames, dropped, escaped = LiveTrial(self, trial).run(state, keys_wanted, timed_once,
                                                                     self.window.poll_keys, on_switch, info)
        info["frames"] = len(frames)
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
    def instructions(self, text: str) -> None:
        """Show ``text`` until any key but Escape is pressed."""
        self._require_open()
        self.draw_text(text, "press any key to continue")
        self.win.flip()
        self.emit("instructions")
        while self.window.wait_keys(None) == ESCAPE:
            pass
        self._black_since = None

    def pause(self) -> Literal["resume", "end"]:
        """Ask whether to resume (R) or end (E) the session."""
        self._require_open()
        self.draw_text("Paused.\n\nPress R to resume or E to end the session.")
        self.win.flip()
        self.emit("pause")
        key = self.window.wait_keys([RESUME_KEY, END_KEY])
        self._black_since = None
        return "resume" if key == RESUME_KEY else "end"

    def rest(self, text: str, seconds: float) -> None:
        """A break: ``text`` with the seconds left (updated once a second) for ``seconds``, then "press SPACE
        to continue" until it is pressed (keys pressed during the countdown do not end it)."""
        self._require_open()
        if not (math.isfinite(seconds) and seconds >= 0):
            raise UserError(f"seconds={seconds!r} is out of range: must be >= 0")
        end = self.now() + seconds
        shown = None
        while (left := math.ceil(end - self.now())) > 0:
            if left != shown:
                self.draw_text(f"{text}\n\n{left} s")
                if self.screenshot_dir is not None:
                    self.save_shot(None, f"{left}s")
                self.win.flip()
                self.emit("rest", text=text, left_s=left)
                shown = left
            self.window.core.wait(min(0.05, max(0.0, end - self.now())), hogCPUperiod=0)
        self.draw_text(f"{text}\n\npress {key_text(CONTINUE_KEY)} to continue")
        if self.screenshot_dir is not None:
            self.save_shot(None, "continue")
        self.win.flip()
        self.emit("rest", text=text, left_s=0)
        self.window.wait_keys([CONTINUE_KEY])  # (clears the keys pressed during the countdown first)
        self._black_since = None

    def message(self, text: str, seconds: float) -> None:
        """Show ``text`` for ``seconds`` (breaks, end of session)."""
        self._require_open()
        if not (math.isfinite(seconds) and seconds >= 0):
            raise UserError(f"seconds={seconds!r} is out of range: must be >= 0")
        self.draw_text(text)
        self.win.flip()
        self.emit("message", text=text)
        self.window.core.wait(seconds)
        self._black_since = None
