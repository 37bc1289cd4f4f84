"""Live trials in the PsychoPy window: every refresh renders the stimulus where the participant looks.

Per refresh (:meth:`LiveTrial.run`): the newest gaze sample (psychopy.iohub: an eye tracker, or MouseGaze) is
delayed by the condition's ``latency_ms``, mapped from window pixels onto the render of the eye it falls on
(:meth:`studyapp.runner.live.LiveStimulus.views`, :func:`data_schema.geometry.eye_views`), and the condition's renderer renders a new frame foveated there when
the frame-rate cap allows (:class:`studyapp.runner.live.FramePacer`), on the GPU backend inside this window's
OpenGL context (or the CPU backend); the frame is tone-mapped once (:func:`renderers.stimuli.to_srgb8`),
uploaded into a texture that covers the window and flipped. A binocular condition (``stereo: dup|rep``) renders
and times both eyes; a monoscopic display shows the eye its ``eye`` parameter names over the whole window, as
every other condition (A and B are not told apart by their layout), a stereo display (``display.stereo``) both
side by side.
Every flip is logged (:class:`studyapp.runner.live.FrameRecord`): flip time, render time, the gaze sample
used and its age, the camera pose, the dropped flag.

The camera follows the protocol's path, or the participant's keys (W/S/A/D move, arrow keys turn) and a mouse
drag when exploring. Answer and switch keys work as in pre-rendered trials; a switch shows the other condition
at the same place (explore) or restarts its path (path).

Keys are never lost (psychtoolbox queues them in its own thread while a render blocks this one). Escape is
polled before, during and after every render: the render's ``cancel`` hook (:func:`renderers.registry.render`)
asks the keyboard every :data:`ESCAPE_POLL_S` between chunks of work, so a render of many seconds stops
within about one chunk (tens of milliseconds) and the trial ends without showing that frame (the texture is
only updated from a finished render), before the first frame at once. Keys pressed before the trial's first
frame are dropped, Escape excepted: before it every key is taken from the queue, after it a key that went
down before the onset flip (negative time from onset) is ignored. How long Escape took to act (from the
key going down to the trial ending) is recorded in the presenter's ``trial_info`` (``escape_latency_s``).
"""

from __future__ import annotations

import math
import time

import numpy as np

from data_schema.geometry import EYES, EyeView, eye_at
from renderers.plugin_types import RenderCancelled
from studyapp.runner.live import FramePacer, FrameRecord, GazeDelay
from studyapp.runner.protocol import EXPLORE_KEYS

from .base import ESCAPE, PresentationError, TrialDisplay
from .loading import release_stim, update_texture

#: How often a render asks the keyboard whether Escape went down (seconds): far inside the 100-ms bound of
#: issue 26 item 3, rare enough to cost nothing (a poll takes microseconds).
ESCAPE_POLL_S = 0.01

# psychtoolbox key names of exploration -> pyglet key codes (held-key state comes from pyglet)
_PYGLET_KEYS = {"w": "W", "s": "S", "a": "A", "d": "D", "left": "LEFT", "right": "RIGHT", "up": "UP",
                "down": "DOWN"}


class _Surface:
    """One eye's texture covering its viewport; a new frame replaces the texels (no new texture per frame)."""

    def __init__(self, presenter, view):
        self.view = view
        ww, wh = (int(v) for v in presenter.win.size)
        centre = (view.x0 + view.width / 2 - ww / 2, wh / 2 - (view.y0 + view.height / 2))
        self.stim = presenter.texture_stim((view.width, view.height), centre, view.render_width,
                                           view.render_height)

    def update(self, rgb8: np.ndarray) -> None:
        update_texture(self.stim, rgb8)

    def release(self) -> None:
        release_stim(self.stim)


class _Input:
    """Held keys (pyglet's key state) and the mouse drag since the last call (pixels, y up)."""

    def __init__(self, win):
        from pyglet.window import key

        self._key = key
        self.state = key.KeyStateHandler()
        self.drag = [0.0, 0.0]
        handle = win.winHandle

        def on_mouse_drag(x, y, dx, dy, buttons, modifiers):
            self.drag[0] += dx
            self.drag[1] += dy

        self._handlers = (self.state, on_mouse_drag)
        handle.push_handlers(self.state, on_mouse_drag=on_mouse_drag)
        self._handle = handle

    def held(self) -> set[str]:
        return {k for k in EXPLORE_KEYS if self.state[getattr(self._key, _PYGLET_KEYS[k])]}

    def take_drag(self) -> tuple[float, float]:
        d, self.drag = tuple(self.drag), [0.0, 0.0]
        return (d[0], -d[1])

    def close(self) -> None:
        import contextlib

        with contextlib.suppress(Exception):  # the window may already be gone
            self._handle.remove_handlers(self.state)
            self._handle.remove_handler("on_mouse_drag", self._handlers[1])


class _Escape:
    """Escape in a live trial: asked before and after every render, during it (:meth:`cancel`, the renderer's
    hook, at most every :data:`ESCAPE_POLL_S`) and after every flip; :attr:`latency_s` is how long it took from
    the key going down to being acted on.

    Before the first frame (``started`` False) every wanted key is taken from the queue and all but Escape
    dropped (none is an answer or a switch); after it only Escape is taken, the other keys stay queued for the
    poll after the flip."""

    def __init__(self, clock, poll_keys, keys_wanted):
        self.clock, self.poll_keys, self.keys_wanted = clock, poll_keys, keys_wanted
        self.started = False
        self.latency_s: float | None = None
        self._next = 0.0

    def acted(self, key) -> None:
        """Record the latency of ``key`` (an Escape press: its ``rt`` and the clock share their reset)."""
        self.latency_s = float(self.clock.getTime() - key.rt) if key.rt is not None else None

    def pressed(self) -> bool:
        """Whether Escape went down since the last poll."""
        keys = self.poll_keys(self.keys_wanted if not self.started else [ESCAPE])
        esc = [k for k in keys if k.name == ESCAPE]
        if esc:
            self.acted(esc[0])
        return bool(esc)

    def cancel(self) -> bool:
        """The render's ``cancel`` hook: :meth:`pressed`, at most every :data:`ESCAPE_POLL_S`."""
        now = time.perf_counter()
        if now < self._next:
            return False
        self._next = now + ESCAPE_POLL_S
        return self.pressed()


class LiveTrial:
    """One live trial in the presenter's window; :meth:`run` returns ``(answer state, onset, frames, dropped,
    escaped)``."""

    def __init__(self, presenter, trial: TrialDisplay):
        self.p, self.trial = presenter, trial
        self.live = [s.live for s in trial.stimuli]
        win = presenter.win
        self.window = tuple(int(v) for v in win.size)
        self.views = [lv.views(self.window) for lv in self.live]
        self.motions = [lv.motion_model() for lv in self.live]
        if self.live[0].motion == "explore":  # one camera for the whole trial: a switch keeps the place
            self.motions = [self.motions[0]] * len(self.live)
        self.delays = [GazeDelay(lv.latency_ms / 1000.0) for lv in self.live]
        self.pacers = [FramePacer(lv.max_fps) for lv in self.live]
        self.surfaces: dict[int, list[_Surface]] = {}

    def _surfaces(self, i: int) -> list[_Surface]:
        if i not in self.surfaces:
            self.surfaces[i] = [_Surface(self.p, v) for v in self.views[i]]
        return self.surfaces[i]

    def _gaze_sample(self, now: float):
        """The newest gaze sample in window pixels with its time, or the fixation point."""
        g = self.p.gaze_window_px()
        if g is not None:
            return now, g[0], g[1]
        fix = self.trial.fixation_px
        if fix is None:
            return now, self.window[0] / 2, self.window[1] / 2
        # the fixation point of the render (render pixels) on the window the render covers
        cover = EyeView("mono", 0, 0, *self.window, *self.live[0].render_size)
        return (now, *cover.to_window(*fix))

    def _render(self, i: int, t_stim: float, gaze_window, held, drag, cancel=None):
        """Render stimulus ``i`` for all its eyes at the gaze; upload; return (render seconds, pose). ``cancel``:
        the render's hook (:class:`_Escape`); a cancelled render raises
        :class:`~renderers.plugin_types.RenderCancelled` before anything is uploaded."""
        from renderers.registry import render
        from renderers.stimuli import to_srgb8

        lv = self.live[i]
        pose = self.motions[i].pose(t_stim, held, drag)
        views = self.views[i]
        w, h = views[0].render_width, views[0].render_height
        # Both eyes are foveated at the gaze as seen in the eye it falls on (side by side, the right half: the
        # right eye; on a monoscopic display the one eye shown).
        gaze = None if gaze_window is None else eye_at(views, *gaze_window).to_render(*gaze_window)
        params = dict(lv.params)
        t0 = time.perf_counter()
        try:
            img, stats = render(lv.scene, lv.renderer, params, w, h, gaze=gaze, camera=pose.camera(lv.fov_y_deg),
                                backend=lv.backend, cancel=cancel)
        except ValueError as exc:  # a user-facing problem (no OpenGL 4.3, ...): one line, as everywhere
            raise PresentationError(f"cannot render {lv.condition} live: {str(exc).splitlines()[0]}") from None
        both = stats.get("eye_images")
        images = [img if both is None else both[EYES.index(v.eye)] for v in views]
        exposure = self.p.exposure(lv.scene)
        for surf, im in zip(self._surfaces(i), images):
            surf.update(to_srgb8(im, exposure))
        seconds = stats["seconds"].get("total", time.perf_counter() - t0)
        return float(seconds), pose

    def run(self, state, keys_wanted, timed_once: bool, poll_keys, on_switch, info: dict):
        """Show the trial until answered (or its duration, or Escape); ``info`` (the presenter's
        ``trial_info`` row) receives ``question_shown``, ``escaped_before_onset`` and ``escape_latency_s``."""
        p, trial = self.p, self.trial
        win = p.win
        frames: list[FrameRecord] = []
        onset = stim_onset = None
        dropped0 = win.nDroppedFrames
        win.recordFrameIntervals = True
        inp = _Input(win)
        pose = None
        last_dropped = dropped0
        next_flip = p.now() + p.frame_period
        escaped, playback_over = False, False
        esc = _Escape(p.kb.clock, poll_keys, keys_wanted)
        try:
            while True:
                i = state.current
                t_est = next_flip
                if timed_once and onset is not None:
                    playback_over = t_est - onset >= trial.duration_s
                t_sample = self._gaze_sample(p.now())
                self.delays[i].push(*t_sample)
                used = self.delays[i].at(t_est)
                render_s = None
                if playback_over:
                    p.draw_question(trial)
                else:
                    t_stim = 0.0 if stim_onset is None else t_est - stim_onset
                    if not timed_once and self.live[i].motion == "path":
                        t_stim = t_stim % self.live[i].duration_s
                    if self.pacers[i].due(t_est) or i not in self.surfaces:
                        esc.started = onset is not None
                        try:
                            if esc.pressed():
                                raise RenderCancelled
                            render_s, pose = self._render(i, t_stim, None if used is None else used[1:],
                                                          inp.held(), inp.take_drag(), cancel=esc.cancel)
                            if esc.pressed():
                                raise RenderCancelled  # the frame is rendered but never shown
                        except RenderCancelled:
                            escaped = True
                            break
                    for surf in self.surfaces[i]:
                        surf.stim.draw()
                    p.draw_overlay(trial, state.current, state.picks)
                    if render_s is not None and p.screenshot_dir is not None:
                        p.save_shot(trial, f"live{len(frames):05d}")
                if onset is None:  # the RT clock starts with the first frame (keys before it: rt < 0)
                    win.callOnFlip(p.kb.clock.reset)
                t_flip = win.flip()
                next_flip = t_flip + p.frame_period
                if stim_onset is None or (onset is not None and frames and frames[-1].stimulus != i):
                    stim_onset = t_flip
                if onset is None:
                    onset = t_flip
                    p.emit("onset", trial=trial.index, stimulus=i, t=t_flip)
                dropped_now = win.nDroppedFrames
                if not playback_over and pose is not None:
                    frames.append(FrameRecord(len(frames), i, t_flip, render_s,
                                              None if used is None else used[0],
                                              None if used is None else used[1], None if used is None else used[2],
                                              tuple(pose.position), tuple(pose.look_at),
                                              dropped_now > last_dropped))
                last_dropped = dropped_now
                if playback_over and "question_shown" not in info:
                    info["question_shown"] = t_flip
                    p.emit("question", trial=trial.index)
                for key in poll_keys(keys_wanted):
                    if key.name != ESCAPE and key.rt is not None and key.rt < 0:
                        continue  # went down before the first frame: not an answer, not a switch
                    event = state.press(key.name, key.rt, can_switch=not playback_over)
                    if event == "escape":
                        esc.acted(key)
                        escaped = True
                        break
                    if event == "switch":
                        stim_onset = None
                        on_switch(state.current)
                    elif event == "pick":
                        p.emit("pick", trial=trial.index, answer=state.picks[-1])
                if escaped:
                    break
                if (state.answered or not trial.answer_keys) and (playback_over or not timed_once):
                    break
            if escaped and onset is None:
                info["escaped_before_onset"] = True
            if escaped and esc.latency_s is not None:
                info["escape_latency_s"] = round(esc.latency_s, 4)
        finally:
            win.recordFrameIntervals = False
            inp.close()
            for surfs in self.surfaces.values():
                for s in surfs:
                    s.release()
        return onset, frames, win.nDroppedFrames - dropped0, escaped


def check_live_trial(trial: TrialDisplay) -> None:
    """One-line errors for a live trial the window cannot show."""
    if not all(s.live is not None for s in trial.stimuli):
        raise PresentationError(f"trial {trial.index}: live and pre-rendered stimuli cannot be mixed in a trial")
    if trial.duration_s is None or not math.isfinite(trial.duration_s):
        raise PresentationError(f"trial {trial.index}: a live trial needs a duration")


def fps_check_frames(presenter, live, seconds: float) -> tuple[list, list, list, list]:
    """Render ``live`` (a :class:`~studyapp.runner.live.LiveStimulus`) in the presenter's window for ``seconds``
    as a trial would (gaze, delay, camera at the path's start or the exploration's start, upload, draw, flip):
    the frame-rate check's rows (:func:`studyapp.runner.fpscheck.sample_frames`). Keys are not read."""
    from studyapp.runner.fpscheck import sample_frames

    from .base import Stimulus

    from data_schema import families

    # one stimulus shown alone: the family that shows a lone stimulus (its keys are not read here)
    trial = TrialDisplay(index=-1, family=families.single_stimulus().name, stimuli=(Stimulus(live.condition, (), 0.0, live=live),),
                         question="", answer_keys={}, duration_s=live.duration_s)
    lt = LiveTrial(presenter, trial)
    t0 = presenter.now()

    def frame():
        now = presenter.now()
        lt.delays[0].push(*lt._gaze_sample(now))
        used = lt.delays[0].at(now)
        render_s, _ = lt._render(0, now - t0, None if used is None else used[1:], (), (0.0, 0.0))
        for surf in lt.surfaces[0]:
            surf.stim.draw()
        return presenter.win.flip(), render_s, None if used is None else used[0]

    try:
        return sample_frames(frame, presenter.now, seconds)
    finally:
        for surf in lt.surfaces.get(0, []):
            surf.release()
        presenter.win.flip()  # black again
