"""Live, gaze-contingent stimuli: what is rendered at every refresh, apart from any window or GPU.

A live trial renders each stimulus every refresh where the participant looks (seed 001 §5.3, seed 003 §5). This
module holds the parts that decide *what* is rendered and *what is logged*, so that the PsychoPy presenter,
the simulated observer and ``studyapp replay`` share them and they are tested without a window:

- :class:`LiveStimulus` — one condition of a live trial: scene, renderer, parameters, backend, the controlled
  gaze delay (``latency_ms``) and frame-rate cap (``max_fps``), the motion and the geometry;
- :class:`PathMotion` / :class:`ExploreMotion` — the camera: a key-framed path over the trial, or free
  exploration from the keyboard (and the mouse, unless it is the gaze) inside the scene's bounds, at speeds
  declared in metres per second and scaled by the scene's unit (:data:`WALK_M_S`, :func:`live_stimulus`);
- :func:`controls_text` / :func:`instructions_text` — the participant's instructions, with the exploration
  controls generated from the keys the motion model responds to and the gaze source;
- :class:`GazeDelay` — the newest gaze sample at least ``latency_ms`` old (the manipulation of Albert et al.
  2017);
- :class:`FramePacer` — renders only as often as ``max_fps`` allows (an emulated slower renderer); the other
  refreshes show the last frame again;
- :class:`FrameRecord` and :func:`timing_summary` — one log row per flip and the per-trial timing summary
  (frame rate median and 5th percentile, dropped-frame share, gaze-to-flip latency p50 and p95).
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from .protocol import CONTROLS, MOVE_KEYS, TURN_KEYS, eye_of, eyes_of

#: A human walking pace, metres per second, and the arrow keys' turning speed, degrees per second: the defaults of
#: ``stimulus.explore.move_speed_m_s`` and ``turn_speed_deg``.
WALK_M_S = 1.4
TURN_DEG_S = 60.0
#: How far a mouse drag turns the camera (degrees per pixel) when the mouse is not the gaze.
MOUSE_DEG_PER_PX = 0.1


@dataclass(frozen=True)
class Pose:
    """Camera position and look-at point (scene units)."""

    position: tuple[float, float, float]
    look_at: tuple[float, float, float]

    def camera(self, fov_y_deg: float) -> dict:
        """The renderer's camera overrides (``renderers.registry.render(camera=...)``)."""
        return {"position": [float(v) for v in self.position], "look_at": [float(v) for v in self.look_at],
                "fov_y": float(fov_y_deg)}


class PathMotion:
    """The camera of a key-framed path: ``pose(t_s)`` for the time since the stimulus' onset."""

    def __init__(self, poses_at, duration_s: float):
        self._at = poses_at  # t in [0, 1] -> Pose
        self.duration_s = float(duration_s)

    def pose(self, t_s: float, keys=(), mouse=(0.0, 0.0)) -> Pose:
        return self._at(min(1.0, max(0.0, t_s / self.duration_s)) if self.duration_s > 0 else 0.0)


class ExploreMotion:
    """Free exploration: W/S forward and back, A/D sideways, Left/Right turn, Up/Down look up and down, and the
    mouse (a drag in pixels) turns unless ``mouse_deg_per_px`` is 0; the position stays inside ``bounds``.
    ``move_speed`` is in scene units per second, ``turn_speed_deg`` in degrees per second.

    ``pose(t_s, keys, mouse)`` integrates from the last call: ``keys`` are the keys held down now, ``mouse`` the
    pointer's motion (pixels) since the last call. Yaw turns about the world's up axis (+y), pitch is kept within
    ±85°, so the view never flips.
    """

    def __init__(self, start: Pose, move_speed: float = WALK_M_S, turn_speed_deg: float = TURN_DEG_S,
                 bounds: tuple | None = None, mouse_deg_per_px: float = MOUSE_DEG_PER_PX):
        p, q = np.asarray(start.position, float), np.asarray(start.look_at, float)
        d = q - p
        self.distance = float(np.linalg.norm(d)) or 1.0
        d = d / self.distance
        self.yaw = math.atan2(d[0], d[2])
        self.pitch = math.asin(max(-1.0, min(1.0, d[1])))
        self.position = p
        self.move_speed, self.turn_speed = float(move_speed), math.radians(turn_speed_deg)
        self.bounds = None if bounds is None else (np.asarray(bounds[0], float), np.asarray(bounds[1], float))
        self.mouse_rad_per_px = math.radians(mouse_deg_per_px)
        self._t: float | None = None

    def direction(self) -> np.ndarray:
        cp = math.cos(self.pitch)
        return np.array([cp * math.sin(self.yaw), math.sin(self.pitch), cp * math.cos(self.yaw)])

    def pose(self, t_s: float, keys=(), mouse=(0.0, 0.0)) -> Pose:
        dt = 0.0 if self._t is None else max(0.0, t_s - self._t)
        self._t = t_s
        turn = [0.0, 0.0]
        for k in keys:
            if k in TURN_KEYS:
                turn[0] += TURN_KEYS[k][0]
                turn[1] += TURN_KEYS[k][1]
        self.yaw += self.turn_speed * dt * turn[0] + self.mouse_rad_per_px * float(mouse[0])
        lim = math.radians(85.0)
        self.pitch = max(-lim, min(lim, self.pitch + self.turn_speed * dt * turn[1]
                                   - self.mouse_rad_per_px * float(mouse[1])))
        fwd = np.array([math.sin(self.yaw), 0.0, math.cos(self.yaw)])
        right = np.array([math.cos(self.yaw), 0.0, -math.sin(self.yaw)])
        move = np.zeros(3)
        for k in keys:
            if k in MOVE_KEYS:
                move += MOVE_KEYS[k][0] * fwd + MOVE_KEYS[k][1] * right
        n = float(np.linalg.norm(move))
        if n > 0:
            self.position = self.position + move / n * self.move_speed * dt
        if self.bounds is not None:
            self.position = np.clip(self.position, self.bounds[0], self.bounds[1])
        return Pose(tuple(self.position), tuple(self.position + self.distance * self.direction()))


class GazeDelay:
    """The gaze that drives the foveation: the newest sample at least ``latency_s`` old.

    ``push(t, x, y)`` adds a sample (times on the presenter's clock, seconds); ``at(now)`` returns the sample
    used at ``now``: ``(t, x, y)``, or None while no sample is old enough.
    """

    def __init__(self, latency_s: float = 0.0, keep_s: float = 2.0):
        self.latency_s, self.keep_s = float(latency_s), float(keep_s)
        self._t: deque[float] = deque()
        self._xy: deque[tuple[float, float]] = deque()

    def push(self, t: float, x: float, y: float) -> None:
        if self._t and t <= self._t[-1]:
            return  # the same sample polled again
        self._t.append(float(t))
        self._xy.append((float(x), float(y)))
        while len(self._t) > 2 and self._t[1] < t - self.keep_s - self.latency_s:
            self._t.popleft()
            self._xy.popleft()

    def at(self, now: float) -> tuple[float, float, float] | None:
        i = bisect.bisect_right(self._t, now - self.latency_s) - 1
        if i < 0:
            return None
        return (self._t[i], *self._xy[i])


class FramePacer:
    """Renders at most ``max_fps`` frames per second (None: every refresh)."""

    def __init__(self, max_fps: float | None):
        self.period = 0.0 if not max_fps else 1.0 / float(max_fps)
        self._next = -math.inf

    def due(self, t: float) -> bool:
        """True if a new frame is to be rendered for the flip at ``t`` (and books the next one)."""
        if t + 1e-4 < self._next:
            return False
        # Keep the cadence from the planned time (a cap of 30 fps at 60 Hz renders every other flip), but never
        # plan less than half a period ahead after a stall.
        planned = t + self.period if self._next == -math.inf else self._next + self.period
        self._next = max(planned, t + 0.5 * self.period)
        return True


@dataclass
class FrameRecord:
    """One flip of a live trial (a row of the session store's ``frames`` table)."""

    frame: int  # flip index within the trial
    stimulus: int  # which of the trial's stimuli was shown (2AFC: 0 = A, 1 = B)
    flip_s: float  # flip time (presenter's clock), seconds
    render_s: float | None  # render time of a new frame (GPU timer where available); None: the last one again
    gaze_t: float | None  # time of the gaze sample used
    gaze_x: float | None  # display pixels (x right, y down)
    gaze_y: float | None
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    look_at: tuple[float, float, float] = (0.0, 0.0, 1.0)
    dropped: bool = False

    @property
    def gaze_age_s(self) -> float | None:
        """Latency: how old the gaze sample was at the flip."""
        return None if self.gaze_t is None else self.flip_s - self.gaze_t


@dataclass
class LiveStimulus:
    """One condition of a live trial, as the presenter renders it."""

    condition: str
    scene: str  # what renderers.catalog.resolve takes (a built-in name or a scene file)
    renderer: str
    params: dict
    backend: str
    latency_ms: float
    max_fps: float | None
    motion: str  # "path" or "explore"
    duration_s: float
    fov_y_deg: float
    render_size: tuple[int, int]
    path: tuple = ()  # PathMotion's poses: ((t, Pose), ...) sampled along the path
    start: Pose | None = None
    move_speed: float = WALK_M_S  # scene units per second: explore.move_speed_m_s / the scene's metres_per_unit
    turn_speed_deg: float = TURN_DEG_S  # degrees per second
    bounds: tuple | None = None
    mouse_turns: bool = True  # a mouse drag turns the camera (not when the mouse is the gaze)
    extra: dict = field(default_factory=dict)

    stereo_display: bool = False  # the protocol's display.stereo: both eyes side by side

    @property
    def eyes(self) -> int:
        """Binocular conditions (``stereo: dup|rep``) render both eyes (and are timed for both)."""
        return eyes_of(self.params)

    def views(self, window: tuple[int, int]):
        """Where this stimulus goes in a ``window`` (:func:`data_schema.geometry.eye_views`): one view over the
        window, also for a binocular renderer on a monoscopic display (the eye its ``eye`` parameter names);
        both eyes side by side on a stereo display."""
        from data_schema.geometry import eye_views

        return eye_views(window, self.render_size, self.eyes, self.stereo_display, eye_of(self.params))

    def motion_model(self):
        if self.motion == "explore":
            return ExploreMotion(self.start, self.move_speed, self.turn_speed_deg, self.bounds,
                                 MOUSE_DEG_PER_PX if self.mouse_turns else 0.0)
        ts = [t for t, _ in self.path]
        poses = [p for _, p in self.path]

        def at(t: float) -> Pose:
            i = min(len(poses) - 1, max(0, bisect.bisect_right(ts, t) - 1))
            if i + 1 >= len(poses) or ts[i + 1] == ts[i]:
                return poses[i]
            w = (t - ts[i]) / (ts[i + 1] - ts[i])
            a, b = poses[i], poses[i + 1]
            lerp = lambda u, v: tuple(x + w * (y - x) for x, y in zip(u, v))
            return Pose(lerp(a.position, b.position), lerp(a.look_at, b.look_at))

        return PathMotion(at, self.duration_s)


def timing_summary(frames: list[FrameRecord]) -> dict:
    """Per-trial timing of :mod:`data_schema.timing` (frame rate median and 5th percentile, dropped share,
    gaze-to-flip latency p50 and p95 in ms; NaN where not defined)."""
    from data_schema.timing import summary

    return summary([f.flip_s for f in frames], [f.render_s for f in frames], [f.gaze_t for f in frames],
                   [f.dropped for f in frames], [f.stimulus for f in frames])


def scene_record(protocol) -> dict:
    """What a live session records of its scenes (``Store.start_session(scenes=...)``): the protocol's folder
    (scene files are found there) and the content hash of every scene (:meth:`renderers.scene.Scene.content_hash`:
    geometry, materials, lights, camera; a built-in scene's generated description), which ``studyapp replay``
    compares before it renders anything."""
    scenes = list(protocol.scenes) + ([protocol.practice["scene"]] if protocol.practice else [])
    return {"folder": str(protocol.path.resolve().parent),
            "scenes": {s: scene_hash(protocol.scene_ref(s)) for s in dict.fromkeys(scenes)}}


def scene_hash(ref: str) -> str:
    """The content hash of the scene ``ref`` (a built-in name or a scene file path)."""
    from renderers.catalog import resolve

    return resolve(ref).content_hash()


def layout_record(protocol, scale: float, window: tuple[int, int]) -> dict:
    """What a live session records of its window for ``studyapp replay`` (``Store.record_layout``): the
    window's size in pixels (where the gaze is logged and the stimulus shown) and, per condition, its backend
    and its views (:meth:`LiveStimulus.views`, the function the live window places its eyes with): the render
    size, one eye or both side by side. Replay follows the record, not the rules of a later studyapp."""
    window = (int(window[0]), int(window[1]))
    scene = protocol.scenes[0]  # the views and backend of a condition do not depend on the scene
    conditions = {}
    for c in protocol.conditions:
        lv = live_stimulus(protocol, c, scene, scale)
        conditions[c] = {"backend": lv.backend, "views": [v.record() for v in lv.views(window)]}
    return {"window_px": list(window), "scale": float(scale), "conditions": conditions}


def window_image(window: tuple[int, int], views, images) -> np.ndarray:
    """What the window showed: ``images`` (8-bit sRGB, one per view, each ``render_height x render_width``)
    drawn over their viewports on black, magnified as the window's textures are (``GL_LINEAR``: bilinear
    between the four texels nearest each pixel centre, clamped at the edges: OpenGL 4.6 core profile, section 8.14.2),
    ``(height, width, 3)`` uint8."""
    ww, wh = window
    out = np.zeros((wh, ww, 3), dtype=np.uint8)
    for v, img in zip(views, images):
        img = np.asarray(img, dtype=np.float64)
        if img.shape != (v.render_height, v.render_width, 3):
            raise ValueError(f"an image of {img.shape} for a view rendered at {v.render_width}x{v.render_height}")
        # texel coordinates of the pixel centres (EyeView.to_render), minus half a texel: texel centres
        u = (np.arange(v.width) + 0.5) * v.render_width / v.width - 0.5
        t = (np.arange(v.height) + 0.5) * v.render_height / v.height - 0.5
        i0, j0 = np.floor(u).astype(int), np.floor(t).astype(int)
        a, b = (u - i0)[None, :, None], (t - j0)[:, None, None]
        i0, i1 = np.clip(i0, 0, v.render_width - 1), np.clip(i0 + 1, 0, v.render_width - 1)
        j0, j1 = np.clip(j0, 0, v.render_height - 1), np.clip(j0 + 1, 0, v.render_height - 1)
        top = img[j0][:, i0] * (1 - a) + img[j0][:, i1] * a
        bottom = img[j1][:, i0] * (1 - a) + img[j1][:, i1] * a
        out[v.y0:v.y0 + v.height, v.x0:v.x0 + v.width] = np.round(top * (1 - b) + bottom * b)
    return out


def check_live_sizes(protocol, scale: float = 1.0) -> None:
    """Refuse (one line) a live protocol whose renderer conditions cannot render at ``scale``, before anything is
    created: each condition's eye views (:meth:`LiveStimulus.views`) at the render size times ``scale``, checked
    as the renderer checks every live frame (:func:`renderers.registry.check_geometry`; e.g. a LaFR buffer of
    too few rows). The render size does not depend on the scene, so one check per condition covers every scene.
    Every rendered condition counts (catch and practice ones, each level of an adaptive ladder), not a varied
    condition's template."""
    from data_schema.errors import UserError
    from data_schema.geometry import ViewingGeometry, eye_views
    from renderers.registry import check_geometry

    varied = protocol.adaptive.varied if protocol.adaptive is not None else {}
    g = protocol.render_geometry(scale)
    for name, cond in protocol.conditions.items():
        if not cond.renderer or name in varied:
            continue
        views = eye_views((g.width, g.height), (g.width, g.height), eyes_of(cond.params), protocol.display.stereo,
                          eye_of(cond.params))
        for w, h in sorted({(v.render_width, v.render_height) for v in views}):
            try:
                check_geometry(cond.renderer, cond.params, ViewingGeometry.create(w, h, g.fov_y_deg, (w / 2, h / 2)))
            except ValueError as exc:
                raise UserError(f"cannot render {name} live at --scale {scale:g} ({w}x{h} px): "
                                f"{str(exc).splitlines()[0]} (use a larger --scale)") from None


def live_stimulus(protocol, condition: str, scene: str, scale: float = 1.0) -> LiveStimulus:
    """The :class:`LiveStimulus` of ``condition`` in ``scene`` for a live protocol (geometry at ``scale``).

    Exploring, the walking speed is ``explore.move_speed_m_s`` (default :data:`WALK_M_S`) in the scene's units
    (divided by its ``metres_per_unit``), so every scene is walked at the same pace whatever its unit; the mouse
    turns only if it is not the gaze (:attr:`~studyapp.runner.protocol.Protocol.mouse_is_gaze`)."""
    from renderers.catalog import resolve

    from .camera import path_samples, start_pose

    cond = protocol.conditions[condition]
    ref = protocol.scene_ref(scene)
    geometry = protocol.render_geometry(scale)
    common = dict(condition=condition, scene=ref, renderer=cond.renderer, params=dict(cond.params),
                  backend=protocol.backend_of(condition), latency_ms=cond.latency_ms, max_fps=cond.max_fps,
                  motion=protocol.motion, duration_s=float(protocol.duration_s), fov_y_deg=geometry.fov_y_deg,
                  render_size=(geometry.width, geometry.height), stereo_display=protocol.display.stereo)
    if protocol.motion == "explore":
        ex = protocol.explore
        pose = Pose(*start_pose(protocol, scene))
        model = resolve(ref)
        bounds = (ex.get("bounds") or {}).get(scene)
        if bounds is None:  # the scene's bounding box, grown to hold the start position
            v = np.vstack([model.vertices, np.asarray(pose.position, dtype=float)[None]])
            bounds = (tuple(np.min(v, axis=0)), tuple(np.max(v, axis=0)))
        return LiveStimulus(**common, start=pose,
                            move_speed=float(ex.get("move_speed_m_s", WALK_M_S)) / model.metres_per_unit,
                            turn_speed_deg=float(ex.get("turn_speed_deg", TURN_DEG_S)),
                            bounds=(tuple(bounds[0]), tuple(bounds[1])), mouse_turns=not protocol.mouse_is_gaze)
    return LiveStimulus(**common, path=tuple((t, Pose(p, q)) for t, p, q in path_samples(protocol, scene)))


#: What each move key does, in the instructions (MOVE_KEYS' (forward, right) directions).
_MOVE_WORDS = {(1, 0): "forward", (-1, 0): "back", (0, -1): "left", (0, 1): "right"}
_ARROWS = ("left", "right", "up", "down")


def key_label(key: str) -> str:
    """How the participant's instructions name a key (psychtoolbox name): ``W``, ``Left arrow``."""
    return f"{key.capitalize()} arrow" if key in _ARROWS else key.upper()


def _listed(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def controls_text(protocol) -> str:
    """The exploration controls in words, from the keys :class:`ExploreMotion` responds to
    (:data:`~studyapp.runner.protocol.MOVE_KEYS`, :data:`~studyapp.runner.protocol.TURN_KEYS`) and the gaze
    source: where the mouse is the gaze it does not turn (and the participant is told to point it where they
    look); otherwise a drag turns too."""
    move = [f"{key_label(k)} ({_MOVE_WORDS[v]})" for k, v in MOVE_KEYS.items()]
    turn = [key_label(k) for k, (yaw, _) in TURN_KEYS.items() if yaw]
    look = [key_label(k) for k, (_, pitch) in TURN_KEYS.items() if pitch]
    text = (f"Move with {_listed(move)}. Turn with the {_listed(turn)} keys, look up and down with the "
            f"{_listed(look)} keys.")
    if protocol.mouse_is_gaze:
        return text + " The mouse stands in for your eyes: keep it where you look. It does not turn the view."
    return text + " You can also turn by dragging the mouse."


def instructions_text(protocol) -> str:
    """What the participant reads before the first trial: the protocol's ``instructions`` (else its question),
    with ``{controls}`` replaced by :func:`controls_text` when exploring (without it, the controls follow as a
    paragraph of their own: an exploring participant is always told the keys)."""
    text = protocol.instructions or protocol.question
    if not (protocol.live and protocol.motion == "explore"):
        return text
    if CONTROLS in text:
        return text.replace(CONTROLS, controls_text(protocol))
    return f"{text.rstrip()}\n\n{controls_text(protocol)}"


def synthetic_gaze(duration_s: float, width: int, height: int, rng: np.random.Generator,
                   start: tuple[float, float] | None = None) -> list[tuple[float, float, float]]:
    """A simulated eye's gaze over ``duration_s`` on a ``width`` x ``height`` image: fixations of 200-400 ms
    (log-normal around 250 ms) joined by saccades whose duration follows the main sequence (2.2 ms per degree
    + 21 ms, the rule MouseGaze uses; 30 px taken as one degree here), as ``(t, x, y)`` samples at 500 Hz."""
    x, y = start if start is not None else (width / 2.0, height / 2.0)
    t, out = 0.0, []
    while t < duration_s:
        fix = float(np.clip(rng.lognormal(math.log(0.25), 0.25), 0.1, 0.6))
        for k in range(int(fix * 500)):
            out.append((t + k / 500.0, x, y))
        t += fix
        nx, ny = rng.uniform(0.1, 0.9) * width, rng.uniform(0.1, 0.9) * height
        dur = (2.2 * math.hypot(nx - x, ny - y) / 30.0 + 21.0) / 1000.0
        for k in range(max(1, int(dur * 500))):
            w = k / max(1, int(dur * 500))
            out.append((t + k / 500.0, x + w * (nx - x), y + w * (ny - y)))
        t += dur
        x, y = nx, ny
    return [s for s in out if s[0] <= duration_s]
