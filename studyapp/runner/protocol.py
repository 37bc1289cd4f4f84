"""Study protocols: YAML files checked against ``data_schema/protocol.schema.json`` plus cross-references.

:func:`load_protocol` returns a frozen :class:`Protocol` with every default filled in. Errors are
:class:`~data_schema.protocol_schema.ProtocolError` with one line ``FILE:LINE: FIELD: problem``.

Viewing geometry
----------------
The protocol's ``display`` (pixels, physical width, viewing distance) is a :class:`data_schema.geometry.Display`:
the only source of the visual angle the stimuli subtend. Every stimulus is rendered at ``stimulus.render_px``
(default: the display's pixels) with a camera of the display's vertical visual angle, and shown over the
whole display (:meth:`Protocol.render_geometry`).

Full size
---------
A protocol may carry a ``full`` block: the render size and per-condition renderer parameters of its
full-size variant (e.g. seed 003's 2048 + 2048 ground-truth samples), loaded with ``full=True``
(``studyapp prepare/run --full``). The variant is the same protocol with those values in place: its own content
hash (a study database of one variant refuses the other) and its stimuli in ``<stimuli_dir>/full``.
"""

from __future__ import annotations

import copy
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

from data_schema import families
from data_schema.errors import UserError
from data_schema.geometry import Display, ViewingGeometry
from data_schema.intensity import grid
from data_schema.names import check_name, check_unique
from data_schema.protocol_schema import LoadedYAML, load_yaml, validate_document

from .adaptive import DEFAULT_YES_NO_GUESS, AdaptiveDesign, Varied, check_spec, level_condition

#: Keys of free exploration (``motion: explore``; psychtoolbox key names): move forward/back/left/right, turn.
#: A protocol's answer and switch keys may not use them.
MOVE_KEYS = {"w": (1, 0), "s": (-1, 0), "a": (0, -1), "d": (0, 1)}
TURN_KEYS = {"left": (-1, 0), "right": (1, 0), "up": (0, 1), "down": (0, -1)}
EXPLORE_KEYS = tuple(MOVE_KEYS) + tuple(TURN_KEYS)
#: psychopy.iohub's simulated eye tracker (MouseGaze): the mouse is the gaze, as with ``gaze: mouse``.
MOUSE_GAZE_DEVICE = "eyetracker.hw.mouse.EyeTracker"
#: In a live exploring protocol's instructions, replaced by the controls
#: (:func:`studyapp.runner.live.controls_text`).
CONTROLS = "{controls}"
#: Seconds each condition x scene of a live protocol is rendered before the first trial
#: (``stimulus.fps_check_s``, :mod:`studyapp.runner.fpscheck`).
FPS_CHECK_S = 2.0

DEFAULT_SIMULATION = {"jnd": 0.02, "sensitivity_sd": 0.25, "bias_sd": 0.25, "lapse": 0.02, "criterion_jnd": 1.0,
                      "rt_mu_s": 0.55, "rt_sigma_s": 0.08, "rt_tau_s": 0.25}


@dataclass(frozen=True)
class Condition:
    """How a condition's stimuli are made: renderer + params, a folder, or a degraded copy of another one."""

    name: str
    renderer: str | None = None
    params: dict = field(default_factory=dict)
    folder: Path | None = None
    derive_from: str | None = None
    blur_sigma_px: float = 0.0
    noise: float = 0.0
    label: str = ""
    quality: float | None = None
    role: str = "main"
    backend: str | None = None  # None: cpu for pre-rendered stimuli, gpu for live ones
    latency_ms: float = 0.0  # live: delay added to the gaze
    max_fps: float | None = None  # live: frame-rate cap

    @property
    def source(self) -> str:
        return "renderer" if self.renderer else ("folder" if self.folder else "derive")

    @property
    def eyes(self) -> int:
        """2 for a binocular renderer (``stereo: dup`` or ``rep``: both eyes rendered and timed), else 1."""
        return eyes_of(self.params)

    @property
    def eye(self) -> str:
        """The eye a monoscopic display shows of a binocular renderer (its ``eye`` parameter, default left)."""
        return eye_of(self.params)


def eye_of(params: dict) -> str:
    """The eye a monoscopic display shows of a binocular renderer with ``params``: its ``eye``, default left."""
    return str(params.get("eye", "left"))


def eyes_of(params: dict) -> int:
    """How many eyes a renderer with ``params`` renders: 2 with ``stereo: dup`` or ``rep``, else 1."""
    return 2 if params.get("stereo", "mono") in ("dup", "rep") else 1


@dataclass(frozen=True)
class Protocol:
    """A validated protocol with defaults filled in (see ``data_schema/protocol.schema.json``)."""

    path: Path
    data: dict
    name: str
    version: str
    family: str
    question: str
    instructions: str
    block: str
    display: Display
    render_size: tuple[int, int]
    fixation: tuple[float, float]
    fixation_mark: bool
    scenes: tuple[str, ...]
    conditions: dict[str, Condition]
    design_conditions: tuple[str, ...]
    stimulus_kind: str
    duration_s: float | None
    fps: float
    camera_path: tuple[dict, ...]
    black_s: float
    max_response_s: float | None
    answer_keys: dict[str, str]
    switch_keys: dict[str, int]
    repetitions: int
    scene_order: str
    trial_order: str
    max_run: int
    min_repeat_distance: int
    position_balance: bool
    n_picks: int
    reference: str | None
    reference_label: str
    practice: dict | None
    breaks: dict | None
    catch: dict | None
    simulation: dict
    analysis: dict
    stimuli_dir: Path
    content_hash: str
    motion: str = "path"  # live: path | explore
    gaze_source: str = "fixation"  # live: tracker | mouse | fixation
    min_fps: float | None = None  # live: the timing check's floor
    fps_check_s: float = FPS_CHECK_S  # live: seconds each condition x scene is rendered before the first trial (0: off)
    explore: dict = field(default_factory=dict)
    eyetracker: dict | None = None
    full: bool = False  # the full-size variant (the protocol's full block in place)
    key_reminder: str = "bottom"  # presentation.key_reminder: where trials recall their keys (bottom|top|off)
    adaptive: AdaptiveDesign | None = None  # design.adaptive (None: a fixed design)

    @property
    def shown_conditions(self) -> tuple[str, ...]:
        """The conditions the design's trials show: the design's, or for an adaptive design the reference and
        every level of every varied condition (the ladder ``studyapp prepare`` renders)."""
        if self.adaptive is None:
            return self.design_conditions
        return (self.adaptive.reference, *self.adaptive.level_conditions())

    def timed_conditions(self) -> tuple[str, ...]:
        """The renderer conditions the live frame-rate check renders: every one, except that a varied condition
        is rendered only at its weakest foveation (its slowest level), not as its template or at every level."""
        if self.adaptive is None:
            return tuple(c for c, cond in self.conditions.items() if cond.renderer)
        levels = self.adaptive.level_conditions()
        weakest = {level_condition(c, min(v.levels) if v.stronger == "higher" else max(v.levels))
                   for c, v in self.adaptive.varied.items()}
        return tuple(c for c, cond in self.conditions.items() if cond.renderer
                     and c not in self.adaptive.varied and (c not in levels or c in weakest))

    @property
    def mouse_is_gaze(self) -> bool:
        """Whether the mouse stands in for the eye (``gaze: mouse``, or the MouseGaze tracker): then it may not
        also turn an exploring camera."""
        return self.gaze_source == "mouse" or (self.gaze_source == "tracker" and (self.eyetracker or {}).get(
            "device") == MOUSE_GAZE_DEVICE)

    @property
    def live(self) -> bool:
        """Stimuli rendered every refresh where the participant looks (``stimulus.kind: live``)."""
        return self.stimulus_kind == "live"

    def backend_of(self, condition: str) -> str:
        """The renderer backend of ``condition``: its own, else gpu for live stimuli and cpu otherwise."""
        return self.conditions[condition].backend or ("gpu" if self.live else "cpu")

    @property
    def n_frames(self) -> int:
        """Frames per stimulus: 1 for images, ``round(duration_s * fps)`` for sequences, 0 for live stimuli
        (rendered during the trial, nothing prepared)."""
        if self.stimulus_kind == "live":
            return 0
        if self.stimulus_kind == "image":
            return 1
        return max(1, round(self.duration_s * self.fps))

    def render_geometry(self, scale: float = 1.0) -> ViewingGeometry:
        """The viewing geometry of the stimuli: ``render_px`` (times ``scale``), the display's vertical visual
        angle, the gaze at the fixation point."""
        w, h = self.render_size
        g = ViewingGeometry.create(w, h, self.display.fov_y_deg, (self.fixation[0] * w, self.fixation[1] * h))
        return g if scale == 1.0 else g.scaled(scale)

    @property
    def ground_truth(self) -> str | None:
        """Condition the simulated observer compares against (simulation.ground_truth, else reference/catch)."""
        return self.simulation.get("ground_truth") or self.reference or (self.catch or {}).get("good")

    def scene_ref(self, scene: str) -> str:
        """What the renderers resolve for ``scene``: a built-in name, or the scene file next to the protocol."""
        from renderers.catalog import BUILTIN_SCENES, scene_file

        if scene in BUILTIN_SCENES:
            return scene
        path = scene_file(scene, self.path.resolve().parent)
        return str(path) if path is not None else scene

    def describe(self) -> str:
        n = len(self.design_conditions)
        d, (w, h) = self.display, self.render_size
        design = (f"{self.repetitions} repetition(s)" if self.adaptive is None else
                  f"adaptive: {len(self.adaptive.varied)} varied condition(s) x {len(self.scenes)} scene(s), "
                  f"{self.adaptive.cap} trials each")
        return (f"{self.name} {self.version}: {self.family}, {len(self.scenes)} scene(s), {n} condition(s), "
                f"{design}, display {d.width_px}x{d.height_px} ({d.fov_y_deg:.1f}° high, "
                f"{d.ppd:.1f} px/deg), stimuli rendered at {w}x{h}{' (full size)' if self.full else ''}")


def content_hash(data: dict) -> str:
    """SHA-256 of the protocol's canonical JSON (key order, whitespace and comments do not matter)."""
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=True, default=str)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def _registry():
    try:
        from renderers import registry
        registry.available()
    except Exception:  # noqa: BLE001 - any failure means "not available here"
        return None
    return registry


def renderer_names() -> set[str] | None:
    """Names in ``renderers.registry`` if it is importable, else None (renderer names are then not checked)."""
    reg = _registry()
    return None if reg is None else set(reg.available())


def _conditions(doc: LoadedYAML, data: dict, base: Path, check_renderers: bool) -> dict[str, Condition]:
    out = {}
    reg = _registry() if check_renderers else None  # False: a library caller that renders nothing (the demo)
    known = None if reg is None else set(reg.available())
    for name, spec in data["conditions"].items():
        where = ("conditions", name)
        sources = [k for k in ("renderer", "folder", "derive") if k in spec]
        if len(sources) != 1:
            raise doc.error(where, "give exactly one of renderer, folder or derive"
                            + (f" (has {', '.join(sources)})" if sources else ""))
        if "params" in spec and "renderer" not in spec:
            raise doc.error(where + ("params",), "params belong to a renderer condition")
        if "renderer" in spec and known is not None and spec["renderer"] not in known:
            raise doc.error(where + ("renderer",), f"unknown renderer {spec['renderer']!r}: allowed "
                            f"{', '.join(sorted(known))}")
        elif "renderer" in spec and known is not None:
            try:
                reg.resolve_params(spec["renderer"], spec.get("params", {}))
            except ValueError as exc:
                raise doc.error(where + ("params",), str(exc)) from None
        _check_eye(doc, where, spec.get("params", {}), data["display"].get("stereo", False))
        derive = spec.get("derive", {})
        if derive and derive["from"] not in data["conditions"]:
            raise doc.error(where + ("derive", "from"), f"unknown condition {derive['from']!r}")
        if derive and data["conditions"][derive["from"]].get("derive"):
            raise doc.error(where + ("derive", "from"), "cannot derive from a derived condition")
        out[name] = Condition(name=name, renderer=spec.get("renderer"), params=dict(spec.get("params", {})),
                              folder=_inside(doc, base, where + ("folder",), spec["folder"]) if "folder" in spec
                              else None,
                              derive_from=derive.get("from"), blur_sigma_px=float(derive.get("blur_sigma_px", 0)),
                              noise=float(derive.get("noise", 0)), label=spec.get("label", name),
                              quality=spec.get("quality"), role=spec.get("role", "main"),
                              backend=spec.get("backend"), latency_ms=float(spec.get("latency_ms", 0.0)),
                              max_fps=spec.get("max_fps"))
    return out


#: Procedure settings that belong to one method only (a setting of the other method is refused, not ignored).
_METHOD_KEYS = {"quest_plus": ("function", "threshold", "slope", "lapse", "guess"),
                "staircase": ("rule", "steps", "estimate_reversals")}


def _adaptive(doc: LoadedYAML, data: dict, conditions: dict, fam) -> tuple[AdaptiveDesign, dict[str, Condition]]:
    """``design.adaptive`` checked (the refusals of issue 28 item 9, one line each) and its level conditions:
    ``NAME(level)`` for every level of every varied condition, the condition's params with the level in place."""
    spec = data["design"]["adaptive"]
    where = ("design", "adaptive")
    procedure = dict(spec.get("procedure", {}))
    method = procedure.get("method", "quest_plus")
    for other, keys in _METHOD_KEYS.items():
        wrong = [k for k in keys if k in procedure and other != method]
        if wrong:
            raise doc.error(where + ("procedure", wrong[0]), f"belongs to method {other}, not {method}")
    if "guess" in procedure and fam.guess_rate is not None:
        raise doc.error(where + ("procedure", "guess"), f"{fam.name} trials guess {fam.guess_rate:g} by design: "
                        "remove guess (a yes_no design estimates its false-alarm rate)")
    guess = (fam.guess_rate,) if fam.guess_rate is not None else tuple(procedure.pop("guess", DEFAULT_YES_NO_GUESS))
    procedure.pop("guess", None)
    reg = _registry()
    varied, levels_out = {}, {}
    for name, v in spec["vary"].items():
        at = where + ("vary", name)
        cond = conditions[name]
        if cond.renderer is None:
            raise doc.error(at, f"condition {name!r} has no renderer: only a renderer's parameter can be varied")
        strength = reg.foveation_strength(cond.renderer) if reg is not None and hasattr(
            reg, "foveation_strength") else None
        param = v.get("param") or (strength.param if strength else None)
        if param is None:
            raise doc.error(at, f"renderer {cond.renderer!r} has no foveation strength to vary: give param")
        info = reg.get(cond.renderer).params.get(param) if reg is not None else None
        if reg is not None and info is None:
            raise doc.error(at + ("param",), f"renderer {cond.renderer!r} has no parameter {param!r}: allowed "
                            f"{', '.join(reg.get(cond.renderer).params)}")
        if info is not None and (info.type not in (int, float) or info.choices):
            raise doc.error(at + ("param",), f"{cond.renderer}.{param} is not numeric (allowed {info.allowed()}): "
                            "only a numeric parameter can be varied")
        if param in cond.params:
            raise doc.error(("conditions", name, "params", param), f"is varied by design.adaptive.vary.{name}: "
                            "remove it here")
        stronger = v.get("stronger") or (strength.stronger if strength and strength.param == param else None)
        if stronger is None:
            raise doc.error(at, f"{cond.renderer}.{param} is not the renderer's foveation strength: give stronger "
                            "(higher or lower: which way foveation grows)")
        scale = v.get("scale", "log")
        levels = _levels(doc, at, v, scale)
        if info is not None and info.type is int:
            if any(lv != round(lv) for lv in levels) and not isinstance(v["levels"], int):
                raise doc.error(at + ("levels",), f"{cond.renderer}.{param} takes whole numbers")
            levels = sorted({float(round(lv)) for lv in levels})
            if len(levels) < 2:
                raise doc.error(at + ("levels",), "a ladder of one level cannot be adapted: give at least 2 levels")
        for lv in levels:
            if scale == "log" and lv <= 0:
                raise doc.error(at + ("levels",), f"{lv:g} is not above 0: a log domain needs positive levels "
                                "(or scale: linear)")
            if info is not None:
                try:
                    info.range.check(f"{cond.renderer}.{param}", int(lv) if info.type is int else lv)
                except UserError as exc:
                    raise doc.error(at + ("levels",), f"{exc}: the domain must lie inside the parameter's "
                                    "allowed range") from None
        start = v.get("start")
        varied[name] = Varied(name, param, scale, stronger, tuple(levels),
                              None if start is None else float(start))
        for lv in levels:
            lname = level_condition(name, lv)
            if lname in conditions:
                raise doc.error(at, f"level condition {lname!r} is also a condition of the protocol: rename it")
            value = int(lv) if info is not None and info.type is int else lv
            levels_out[lname] = Condition(
                name=lname, renderer=cond.renderer, params={**cond.params, param: value}, label=cond.label,
                quality=cond.quality, role="main", backend=cond.backend, latency_ms=cond.latency_ms,
                max_fps=cond.max_fps)
    design = AdaptiveDesign(reference=spec["reference"], varied=varied, procedure=procedure,
                            stop=dict(spec["stop"]), guess=tuple(float(g) for g in guess))
    for name in varied:
        try:
            check_spec(design.spec(name))
        except UserError as exc:
            field = "stop" if "stop" in str(exc) or "stopping" in str(exc) else "procedure"
            raise doc.error(where + (field,), str(exc)) from None
    return design, levels_out


def _levels(doc: LoadedYAML, at: tuple, v: dict, scale: str) -> list[float]:
    """The ladder of a varied condition: ``levels`` as given (6 significant digits: they name folders), or that
    many levels from ``min`` to ``max`` evenly spaced on ``scale``."""
    given = v["levels"]
    if isinstance(given, int):
        if "min" not in v or "max" not in v:
            raise doc.error(at + ("levels",), f"levels: {given} needs min and max (or give the levels as a list)")
        lo, hi = float(v["min"]), float(v["max"])
        if not lo < hi:
            raise doc.error(at + ("min",), f"{lo:g} is not below max {hi:g}")
        if given < 2:
            raise doc.error(at + ("levels",), "a ladder of one level cannot be adapted: give at least 2 levels")
        if scale == "log" and lo <= 0:
            raise doc.error(at + ("min",), f"{lo:g} is not above 0: a log domain needs positive levels (or scale: "
                            "linear)")
        return grid(scale, lo, hi, given)
    if "min" in v or "max" in v:
        raise doc.error(at + ("min" if "min" in v else "max",), "min and max go with a number of levels; the listed "
                        "levels are the domain")
    levels = [float(f"{float(x):.6g}") for x in given]
    if len(levels) < 2:
        raise doc.error(at + ("levels",), "a ladder of one level cannot be adapted: give at least 2 levels")
    if len(set(levels)) != len(levels):
        raise doc.error(at + ("levels",), "a level is listed twice (levels are compared to 6 significant digits)")
    return sorted(levels)


def _check_eye(doc: LoadedYAML, where: tuple, params: dict, stereo_display: bool) -> None:
    """``eye`` picks the eye a monoscopic display shows of a binocular renderer: refused where it would choose
    nothing (a one-view renderer; a stereo display, which shows both eyes) rather than silently ignored."""
    if "eye" not in params:
        return
    if eyes_of(params) == 1:
        raise doc.error(where + ("params", "eye"), f"eye: {params['eye']} means nothing for a one-view renderer "
                        "(stereo: mono): remove it, or render both eyes (stereo: dup or rep)")
    if stereo_display:
        raise doc.error(where + ("params", "eye"), "the display is stereo (display.stereo: true) and shows both "
                        "eyes side by side: remove eye, or set display.stereo: false to show this one eye")


def _display(doc: LoadedYAML, data: dict) -> tuple[Display, tuple[int, int]]:
    """The display, and the render size of the stimuli (same aspect ratio: a stimulus covers the display)."""
    disp = dict(data["display"])
    stated = disp.pop("fov_y_deg", None)
    display = Display(**disp)
    if stated is not None and abs(stated - display.fov_y_deg) > 0.1:
        raise doc.error(("display", "fov_y_deg"), f"{stated:g}° disagrees with the display's size: "
                        f"{display.width_px}x{display.height_px} px, {display.width_cm:g} cm wide, seen from "
                        f"{display.distance_cm:g} cm subtend {display.fov_y_deg:.2f}° (remove fov_y_deg, or fix "
                        "width_cm/distance_cm)")
    w, h = (data.get("stimulus") or {}).get("render_px", (display.width_px, display.height_px))
    if abs(w * display.height_px / display.width_px - h) > 1.0:
        raise doc.error(("stimulus", "render_px"), f"{w}x{h} has not the display's aspect ratio "
                        f"({display.width_px}x{display.height_px}): a stimulus covers the whole display")
    _check_stimulus_pixels(doc, data, ("stimulus", "render_px"), int(w), int(h))
    return display, (int(w), int(h))


def _check_stimulus_pixels(doc: LoadedYAML, data: dict, field: tuple, w: int, h: int) -> None:
    """Pre-rendered stimuli are read back as PNGs: a render size over the image readers' limit
    (:data:`data_schema.images.MAX_IMAGE_PIXELS`) would be prepared, then refused at the first trial."""
    from data_schema.images import MAX_IMAGE_PIXELS, limit_text

    if (data.get("stimulus") or {}).get("kind", "image") != "live" and w * h > MAX_IMAGE_PIXELS:
        raise doc.error(field, f"{w}x{h} pixels is over the limit of {limit_text()} for a pre-rendered stimulus "
                        "image: render smaller (render_px; it is upscaled to the display when shown)")


def _check_live(doc: LoadedYAML, data: dict, conditions: dict, family: str, check_renderers: bool) -> None:
    """Live stimuli: a duration, a motion, a gaze source with what it needs, renderer conditions with a
    version for their backend, frame-rate caps the display can show, and no pre-rendered sources; and no field
    contradicting another (explore bounds and start, duration, frame-rate floor and caps, gaze delay)."""
    stim = data["stimulus"]
    if "duration_s" not in stim:
        raise doc.error(("stimulus",), "a live stimulus needs duration_s (the longest a trial shows it)")
    if "fps" in stim:
        raise doc.error(("stimulus", "fps"), "live stimuli are rendered every refresh: no fps (use max_fps per "
                        "condition to cap the frame rate)")
    motion = stim.get("motion", "path")
    if motion == "explore" and "camera_path" in stim:
        raise doc.error(("stimulus", "camera_path"), "explore moves the camera from the participant's keys: no "
                        "camera_path")
    if motion == "path" and "explore" in stim:
        raise doc.error(("stimulus", "explore"), "explore settings belong to motion: explore (this stimulus "
                        "follows its camera_path): remove them, or set motion: explore")
    gaze = stim.get("gaze", "fixation")
    if gaze == "tracker" and "eyetracker" not in data:
        raise doc.error(("stimulus", "gaze"), "gaze: tracker needs an eyetracker block (device, settings)")
    for name in (stim.get("explore") or {}).get("bounds", {}) | (stim.get("explore") or {}).get("start", {}):
        if name not in data["scenes"] and name != (data.get("practice") or {}).get("scene"):
            raise doc.error(("stimulus", "explore"), f"scene {name!r} is not one of the protocol's scenes")
    _check_explore_region(doc, stim.get("explore") or {})
    refresh = float(data["display"].get("refresh_hz", 60.0))
    duration = float(stim["duration_s"])
    if duration * refresh < 2:
        raise doc.error(("stimulus", "duration_s"), f"{duration:g} s is shorter than two refreshes of the display "
                        f"({refresh:g} Hz): a live trial needs at least two frames")
    min_fps = stim.get("min_fps")
    if min_fps is not None and min_fps > refresh:
        raise doc.error(("stimulus", "min_fps"), f"{min_fps:g} fps is above the display's refresh rate "
                        f"({refresh:g} Hz): every trial would be flagged as too slow")
    reg = _registry() if check_renderers else None
    for name, cond in conditions.items():
        where = ("conditions", name)
        if cond.renderer is None:
            raise doc.error(where, "live stimuli are rendered: every condition needs a renderer (not a folder or "
                            "a derived copy)")
        if cond.max_fps is not None and cond.max_fps > refresh:
            raise doc.error(where + ("max_fps",), f"{cond.max_fps:g} fps is above the display's refresh rate "
                            f"({refresh:g} Hz): a cap the display cannot show")
        if cond.max_fps is not None and duration * cond.max_fps < 2:
            raise doc.error(where + ("max_fps",), f"at {cond.max_fps:g} fps a {duration:g} s stimulus shows fewer "
                            "than two frames")
        if cond.latency_ms >= 1000.0 * duration:
            raise doc.error(where + ("latency_ms",), f"a gaze delay of {cond.latency_ms:g} ms is not shorter than "
                            f"the stimulus (duration_s {duration:g} s): the gaze would never drive the foveation")
        backend = cond.backend or "gpu"
        if reg is not None and backend == "gpu" and reg.get(cond.renderer).gpu is None:
            raise doc.error(where + ("renderer",), f"renderer {cond.renderer!r} has no GPU version for live "
                            "stimuli: use backend: cpu (slow) or another renderer")


def _check_explore_region(doc: LoadedYAML, explore: dict) -> None:
    """Explore bounds with min <= max on every axis, and a start position inside its scene's bounds."""
    bounds = explore.get("bounds", {})
    for scene, (lo, hi) in bounds.items():
        for axis, a, b in zip("xyz", lo, hi):
            if a > b:
                raise doc.error(("stimulus", "explore", "bounds", scene), f"{axis} min {a:g} is above {axis} max "
                                f"{b:g}: the bounds [[xmin, ymin, zmin], [xmax, ymax, zmax]] hold no position")
    for scene, start in explore.get("start", {}).items():
        if scene in bounds:
            lo, hi = bounds[scene]
            outside = [f"{axis} = {v:g} not in [{a:g}, {b:g}]" for axis, v, a, b in zip("xyz", start["position"],
                                                                                          lo, hi) if not a <= v <= b]
            if outside:
                raise doc.error(("stimulus", "explore", "start", scene, "position"), "outside stimulus.explore."
                                f"bounds.{scene} ({'; '.join(outside)}): the camera would jump at the first frame")


def _check_live_poses(doc: LoadedYAML, protocol: Protocol) -> None:
    """Every camera pose of a live stimulus has a view: the camera path's, sampled and interpolated as the
    runner follows it, and the explore start (which must also lie inside the given bounds), in every scene."""
    from renderers.catalog import resolve

    from .camera import path_problem, path_samples, start_pose, view_problem

    scenes = protocol.scenes + ((protocol.practice["scene"],) if protocol.practice else ())
    for scene in dict.fromkeys(scenes):
        up = resolve(protocol.scene_ref(scene)).camera.up
        if protocol.motion == "explore":
            position, look_at = start_pose(protocol, scene)
            given = scene in (protocol.explore.get("start") or {})
            where = ("stimulus", "explore", "start", scene) if given else (
                ("scenes", protocol.scenes.index(scene)) if scene in protocol.scenes else ("practice", "scene"))
            problem = view_problem(position, look_at, up)
            if problem:
                raise doc.error(where, f"{problem}{'' if given else f' (the camera of scene {scene})'}")
            bounds = (protocol.explore.get("bounds") or {}).get(scene)
            if bounds and not given and not all(a <= v <= b for v, a, b in zip(position, *bounds)):
                raise doc.error(("stimulus", "explore", "bounds", scene), f"the scene's camera at "
                                f"{list(position)} (the start: no explore.start for {scene}) is outside these "
                                "bounds: the camera would jump at the first frame")
            continue
        samples = path_samples(protocol, scene)
        found = path_problem([(p, q) for _, p, q in samples], up)
        if found:
            k = min(int(found[0]), len(samples) - 2)
            t = samples[k][0] + (found[0] - k) * (samples[k + 1][0] - samples[k][0])
            keys = protocol.camera_path
            i = min(range(len(keys)), key=lambda j: abs(keys[j]["t"] - t)) if keys else None
            raise doc.error(("stimulus", "camera_path") + ((i,) if i is not None else ()),
                            f"in scene {scene} at t = {t:.3g}: {found[1]}")


def _check_camera_path(doc: LoadedYAML, stim: dict) -> None:
    """Keyframe times that increase, and keyframes that are all used: every key in the first keyframe (a key
    first given later would be ignored) and no look_at beside yaw_deg/pitch_deg (the offsets replace it)."""
    path = stim.get("camera_path") or []
    first = set(path[0]) if path else set()
    for i, key in enumerate(path):
        if i and key["t"] <= path[i - 1]["t"]:
            raise doc.error(("stimulus", "camera_path", i, "t"), f"{key['t']:g} is not after the previous keyframe's "
                            f"t = {path[i - 1]['t']:g}: keyframe times must increase")
        late = sorted(set(key) - first)
        if late:
            raise doc.error(("stimulus", "camera_path", i, late[0]), "not in the first keyframe, so never used: give "
                            "it in the first keyframe too")
        if "look_at" in key and {"yaw_deg", "pitch_deg"} & set(key):
            raise doc.error(("stimulus", "camera_path", i, "look_at"), "yaw_deg/pitch_deg turn the scene camera's "
                            "view and replace look_at: give one or the other")


def _check_renderers_on_display(doc, conditions, display, render_size, fixation) -> None:
    """Each renderer condition must work on this display (e.g. LaFR's fovea must fit inside it)."""
    reg = _registry()
    if reg is None:
        return
    fix = fixation or {"x": 0.5, "y": 0.5}
    w, h = render_size
    geometry = ViewingGeometry.create(w, h, display.fov_y_deg, (fix["x"] * w, fix["y"] * h))
    for name, cond in conditions.items():
        if cond.renderer:
            try:
                reg.check_geometry(cond.renderer, cond.params, geometry)
            except ValueError as exc:
                raise doc.error(("conditions", name, "renderer"), f"{cond.renderer} cannot render for this "
                                f"display ({w}x{h} px, {display.fov_y_deg:.1f}°): {exc}") from None


def _full_size(doc: LoadedYAML, data: dict, check_renderers: bool) -> dict:
    """``data`` with its ``full`` block in place: ``stimulus.render_px`` and the conditions' params replaced."""
    spec = data.get("full")
    if spec is None:
        raise doc.error(("name",), "the protocol has no full block (full: {render_px: [W, H], conditions: "
                        "{NAME: {params: {...}}}}): --full needs one")
    out = copy.deepcopy(data)
    w, h = spec["render_px"]
    d = data["display"]
    if abs(w * d["height_px"] / d["width_px"] - h) > 1.0:
        raise doc.error(("full", "render_px"), f"{w}x{h} has not the display's aspect ratio "
                        f"({d['width_px']}x{d['height_px']}): a stimulus covers the whole display")
    _check_stimulus_pixels(doc, data, ("full", "render_px"), w, h)
    out.setdefault("stimulus", {})["render_px"] = [w, h]
    reg = _registry() if check_renderers else None
    for name, over in spec.get("conditions", {}).items():
        where = ("full", "conditions", name)
        cond = out["conditions"].get(name)
        if cond is None:
            raise doc.error(where, f"unknown condition {name!r}: defined are {', '.join(out['conditions'])}")
        if "renderer" not in cond:
            raise doc.error(where, f"condition {name!r} has no renderer: only renderer conditions have params")
        cond["params"] = {**cond.get("params", {}), **over["params"]}
        if reg is not None:
            try:
                reg.resolve_params(cond["renderer"], cond["params"])
            except ValueError as exc:
                raise doc.error(where + ("params",), str(exc)) from None
    return out


def _inside(doc: LoadedYAML, base: Path, field: tuple, relative: str) -> Path:
    """``base / relative``, refused when it leaves the protocol's folder (``..``, an absolute path): a protocol
    file never makes studyapp read or write elsewhere; a folder elsewhere is given on the command line."""
    target = (base / relative).resolve()
    if Path(relative).is_absolute() or not target.is_relative_to(base):
        raise doc.error(field, f"{relative!r} is outside the protocol's folder {base}: give a folder inside it, "
                        "or the folder on the command line (--stimuli DIR)")
    return target


def _check_names(doc: LoadedYAML, data: dict) -> None:
    """Condition and scene names become folder and file names (``<stimuli>/<condition>/<scene>.png``, a replay's
    folders): each must pass :func:`data_schema.names.check_name`, and no two may differ only in case."""
    scenes = [(("scenes", i), s) for i, s in enumerate(data["scenes"])]
    if data.get("practice"):
        scenes.append((("practice", "scene"), data["practice"]["scene"]))
    for kind, named in (("condition", [(("conditions", n), n) for n in data["conditions"]]), ("scene", scenes)):
        for where, name in named:
            try:
                check_name(kind, name)
            except UserError as exc:
                raise doc.error(where, str(exc)) from None
        try:
            check_unique(kind, [n for _, n in named])
        except UserError as exc:
            raise doc.error(named[0][0][:1], str(exc)) from None


def _stimuli_dir(doc: LoadedYAML, base: Path, relative: str) -> Path:
    """The protocol's ``stimuli_dir``: a folder strictly inside ``base`` (the protocol's folder, or the current
    one for a shipped protocol), never ``base`` itself (``.``): the stimulus cache goes next to the stimulus
    folder, so ``.`` would put it in ``base``'s parent."""
    target = _inside(doc, base, ("stimuli_dir",), relative)
    if target == base:
        raise doc.error(("stimuli_dir",), f"{relative!r} is the protocol's folder {base} itself: give a subfolder "
                        "(e.g. stimuli/NAME; its cache goes next to it)")
    return target


def _check_scenes(doc: LoadedYAML, data: dict, base: Path) -> None:
    """Every scene a renderer condition renders must be a built-in scene or a scene file next to the protocol."""
    try:
        from renderers.catalog import BUILTIN_SCENES, scene_exists
    except ImportError:  # an analysis-only install: scenes are checked where they are rendered
        return
    names = [(("scenes", i), s) for i, s in enumerate(data["scenes"])]
    if data.get("practice"):
        names.append((("practice", "scene"), data["practice"]["scene"]))
    for where, name in names:
        if not scene_exists(name, base):
            raise doc.error(where, f"unknown scene {name!r}: neither a built-in scene ({', '.join(BUILTIN_SCENES)}) "
                            f"nor a scene file {name}.yaml next to the protocol")


def _check_condition(doc, conditions, field_path, name, allow_roles=("main", "catch", "practice")):
    if name not in conditions:
        raise doc.error(field_path, f"unknown condition {name!r}: defined are {', '.join(conditions)}")
    if conditions[name].role not in allow_roles:
        raise doc.error(field_path, f"condition {name!r} has role {conditions[name].role}")


def load_protocol(path, stimuli_dir=None, check_renderers: bool = True, output_base: Path | None = None,
                  full: bool = False) -> Protocol:
    """Read, validate and complete a protocol file.

    Parameters
    ----------
    path : str or Path
        The YAML file.
    stimuli_dir : str or Path, optional
        Override of the protocol's ``stimuli_dir`` (default ``stimuli/<name>`` next to the protocol file).
    output_base : Path, optional
        Folder the protocol's ``stimuli_dir`` is relative to (default: the protocol's own folder; the CLI
        gives the current folder for the shipped protocols, which live inside the installed package).
    check_renderers : bool
        When ``renderers.registry`` is importable, renderer names, parameters and geometry, scenes and the
        camera poses of live stimuli are checked against it (default; ``validate`` and ``run``, simulated or
        not, always check: ``studyapp.commands.study.checked_protocol``); False skips those checks, for
        library callers that render nothing (the demo's synthetic stimuli, tests of the schedule).
    full : bool
        The full-size variant (the protocol's ``full`` block in place; stimuli in ``<stimuli_dir>/full``).

    Raises
    ------
    ProtocolError
        One line naming the file, the line and the field.
    """
    path = Path(path)
    return _build(load_yaml(path), path, stimuli_dir, check_renderers, output_base, full)


def protocol_from_data(data: dict, label: str, check_renderers: bool = True, folder=None) -> Protocol:
    """The protocol a study database recorded (its JSON), checked as a file would be; errors name ``label``.
    Its scene files are found in ``folder`` (the folder the session recorded; default the current one)."""
    from data_schema.protocol_schema import ProtocolError

    doc = LoadedYAML(data, {}, Path(label), ProtocolError)
    return _build(doc, Path(folder or Path.cwd()) / "recorded.yaml", None, check_renderers, None)


def _build(doc: LoadedYAML, path: Path, stimuli_dir, check_renderers: bool, output_base,
           full: bool = False) -> Protocol:
    data = validate_document(doc)
    if full:
        data = _full_size(doc, data, check_renderers)
    base = path.resolve().parent
    family = data["family"]
    _check_names(doc, data)
    conditions = _conditions(doc, data, base, check_renderers)

    design = data["design"]
    fam = families.get(family)
    if ("repetitions" in design) == ("adaptive" in design):
        raise doc.error(("design",), "give repetitions (a fixed design) or adaptive (an adaptive one)"
                        + (", not both" if "adaptive" in design else ""))
    if "adaptive" in design:
        if not fam.has_correct_answer:
            able = ", ".join(f.name for f in families.FAMILIES.values() if f.has_correct_answer)
            raise doc.error(("design", "adaptive"), f"{family} trials have no correct answer for a procedure to "
                            f"adapt on: an adaptive design needs the {able} family")
        if "conditions" in design:
            raise doc.error(("design", "conditions"), "an adaptive design shows adaptive.reference and the "
                            "conditions of adaptive.vary: remove design.conditions")
        ref = design["adaptive"]["reference"]
        _check_condition(doc, conditions, ("design", "adaptive", "reference"), ref)
        for name in design["adaptive"]["vary"]:
            _check_condition(doc, conditions, ("design", "adaptive", "vary", name), name)
        if ref in design["adaptive"]["vary"]:
            raise doc.error(("design", "adaptive", "reference"), f"{ref!r} is itself varied (adaptive.vary): the "
                            "reference must be a fixed condition, e.g. the ground truth")
        design_conditions = (ref, *design["adaptive"]["vary"])
    elif "conditions" in design:
        for i, c in enumerate(design["conditions"]):
            _check_condition(doc, conditions, ("design", "conditions", i), c)
        design_conditions = tuple(design["conditions"])
    else:
        design_conditions = tuple(n for n, c in conditions.items() if c.role == "main")
    need = fam.min_conditions
    if len(design_conditions) < need:
        raise doc.error(("design",), f"{family} needs at least {need} conditions in the design, has "
                        f"{len(design_conditions)}")
    n_picks = int(design.get("n_picks", fam.default_n_picks(len(design_conditions))))
    if fam.has_picks and n_picks >= len(design_conditions):
        raise doc.error(("design", "n_picks"), f"{n_picks} picks of {len(design_conditions)} conditions: "
                        f"allowed 1..{len(design_conditions) - 1}")
    if not fam.has_picks and "n_picks" in design:
        raise doc.error(("design", "n_picks"), "only the preference family picks favourites")
    if not fam.has_positions and design.get("position_balance"):
        raise doc.error(("design", "position_balance"), "only 2afc trials have positions to balance")
    reference = design.get("reference", {})
    if reference:
        _check_condition(doc, conditions, ("design", "reference", "condition"), reference["condition"])

    stim = data.get("stimulus", {})
    kind = stim.get("kind", "image")
    if kind == "sequence" and ("duration_s" not in stim or "fps" not in stim):
        raise doc.error(("stimulus",), "a sequence needs duration_s and fps")
    if kind == "image" and "fps" in stim:
        raise doc.error(("stimulus", "fps"), "still images have no frame rate (use kind: sequence)")
    _check_camera_path(doc, stim)
    live_keys = [k for k in ("motion", "gaze", "min_fps", "fps_check_s", "explore") if k in stim]
    if kind != "live" and live_keys:
        raise doc.error(("stimulus", live_keys[0]), "only live stimuli (kind: live) have this")
    if kind != "live" and data["display"].get("stereo"):
        raise doc.error(("display", "stereo"), "a stereo display shows live binocular renderers side by side; "
                        "a prepared stimulus holds one view (its condition's eye): remove display.stereo")
    if CONTROLS in data.get("instructions", "") and not (kind == "live" and stim.get("motion") == "explore"):
        raise doc.error(("instructions",), f"{CONTROLS} names the keys that move the camera: only a live "
                        "stimulus with motion: explore has them")
    if kind == "live":
        _check_live(doc, data, conditions, family, check_renderers)
    else:
        for name, spec in data["conditions"].items():
            extra = [k for k in ("latency_ms", "max_fps") if k in spec]
            if extra:
                raise doc.error(("conditions", name, extra[0]), "only live stimuli (kind: live) have this")
    reg = _registry() if check_renderers else None
    for name, cond in conditions.items():
        if reg is not None and cond.renderer and cond.backend == "gpu" and reg.get(cond.renderer).gpu is None:
            raise doc.error(("conditions", name, "backend"), f"renderer {cond.renderer!r} has no GPU version: "
                            "use backend: cpu")

    display, render_size = _display(doc, data)
    if check_renderers:
        _check_renderers_on_display(doc, conditions, display, render_size, data.get("fixation"))
    adaptive = None
    if "adaptive" in design:
        adaptive, levels = _adaptive(doc, data, conditions, fam)
        conditions.update(levels)
        if check_renderers:
            _check_renderers_on_display(doc, levels, display, render_size, data.get("fixation"))

    keys = data.get("keys", {})
    default = fam.default_keys(len(design_conditions))
    answer_keys = dict(keys.get("answer", default["answer"]))
    switch_keys = dict(keys.get("switch", default["switch"]))
    allowed = fam.answer_values(len(design_conditions))
    for k, v in answer_keys.items():
        if v not in allowed:
            raise doc.error(("keys", "answer", k), f"answer {v!r} is not one of "
                            f"{', '.join(repr(a) for a in sorted(allowed))}")
    for k, v in switch_keys.items():
        if v > fam.max_switch(len(design_conditions)):
            raise doc.error(("keys", "switch", k), f"stimulus index {v} is out of range")
    overlap = set(answer_keys) & set(switch_keys)
    if overlap:
        raise doc.error(("keys",), f"key {min(overlap)!r} both answers and switches")
    if kind == "live" and data["stimulus"].get("motion") == "explore":
        taken = sorted((set(answer_keys) | set(switch_keys)) & set(EXPLORE_KEYS))
        if taken:
            where = ("keys", "answer" if taken[0] in answer_keys else "switch", taken[0])
            raise doc.error(where, f"key {taken[0]!r} also moves the camera when exploring (W/A/S/D and the "
                            "arrow keys): choose another")
    if "escape" in answer_keys or "escape" in switch_keys:
        raise doc.error(("keys",), "escape is reserved for pausing the session")

    if check_renderers and any(c.renderer for c in conditions.values()):
        _check_scenes(doc, data, base)

    practice = data.get("practice")
    if practice:
        for i, c in enumerate(practice["conditions"]):
            _check_condition(doc, conditions, ("practice", "conditions", i), c)
        problem = fam.practice_problem(practice["conditions"], len(design_conditions))
        if problem:
            raise doc.error(("practice", "conditions"), problem)
    catch = data.get("catch")
    if catch and not fam.catch_kinds:
        allowed_by = ", ".join(f.name for f in families.FAMILIES.values() if f.catch_kinds)
        raise doc.error(("catch",), f"catch trials are for the {allowed_by} families")
    if catch and catch["kind"] not in fam.catch_kinds:
        raise doc.error(("catch", "kind"), f"{family} catch trials are {' or '.join(fam.catch_kinds)}")
    if catch:
        catch = {"pass_fraction": 0.75, **catch}
        if catch["kind"] == "degraded":
            for key in ("good", "bad"):
                if key not in catch:
                    raise doc.error(("catch",), f"degraded catch trials need {key!r}")
                _check_condition(doc, conditions, ("catch", key), catch[key])
    simulation = {**DEFAULT_SIMULATION, **data.get("simulation", {})}
    if "ground_truth" in simulation:
        _check_condition(doc, conditions, ("simulation", "ground_truth"), simulation["ground_truth"])
    analysis = {"by": [], "alpha": 0.05, **data["analysis"]}
    if "reference" in analysis and analysis["reference"] not in design_conditions:
        raise doc.error(("analysis", "reference"), f"unknown condition {analysis['reference']!r}: the design "
                        f"has {', '.join(design_conditions)}")
    if analysis["dv"] not in fam.dvs:
        raise doc.error(("analysis", "dv"), f"{family} trials record {' or '.join(map(repr, fam.dvs))}, not "
                        f"{analysis['dv']!r}")

    fix = data.get("fixation", {"x": 0.5, "y": 0.5})
    timing = data.get("timing", {})
    sdir = Path(stimuli_dir) if stimuli_dir is not None else _stimuli_dir(
        doc, Path(output_base).resolve() if output_base is not None else base,
        data.get("stimuli_dir", f"stimuli/{data['name']}"))
    if full:
        sdir = sdir / "full"
    protocol = Protocol(
        path=path, data=data, name=data["name"], version=data["version"], family=family,
        question=data["question"], instructions=data.get("instructions", ""), block=data.get("block", ""),
        display=display, render_size=render_size, fixation=(float(fix["x"]), float(fix["y"])), fixation_mark=fix.get("mark", True),
        scenes=tuple(data["scenes"]), conditions=conditions, design_conditions=design_conditions,
        stimulus_kind=kind, duration_s=stim.get("duration_s"), fps=float(stim.get("fps", 0.0)),
        camera_path=tuple(stim.get("camera_path", ())), black_s=float(timing.get("black_s", 0.5)),
        max_response_s=timing.get("max_response_s"), answer_keys=answer_keys, switch_keys=switch_keys,
        repetitions=int(design["repetitions"]) if adaptive is None else adaptive.cap,
        scene_order=design.get("scene_order", "fixed"),
        trial_order=design.get("trial_order", "blocked"), max_run=int(design.get("max_run", 0)),
        min_repeat_distance=int(design.get("min_repeat_distance", 0)),
        position_balance=bool(design.get("position_balance", fam.has_positions)), n_picks=n_picks,
        reference=reference.get("condition"), reference_label=reference.get("label", "This is the reference"),
        practice=practice, breaks=data.get("breaks"), catch=catch, simulation=simulation, analysis=analysis,
        stimuli_dir=sdir, content_hash=content_hash(data), motion=stim.get("motion", "path"),
        gaze_source=stim.get("gaze", "fixation"), min_fps=stim.get("min_fps"),
        fps_check_s=float(stim.get("fps_check_s", FPS_CHECK_S)), explore=dict(stim.get("explore", {})),
        eyetracker=data.get("eyetracker"), full=full,
        key_reminder=data.get("presentation", {}).get("key_reminder", "bottom"), adaptive=adaptive)
    if kind == "live" and check_renderers and _registry() is not None:  # the poses need the scenes' cameras
        _check_live_poses(doc, protocol)
    return protocol
