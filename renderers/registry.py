"""Renderer plug-ins: named renderers with declarative parameter specs, and :func:`render`.

A plug-in is a :class:`RendererPlugin` — a name, a description, a ``{name: Param}`` table (type, default,
range or choices) and a ``run(ctx) -> image`` function. Built-in plug-ins are registered here; another package
adds one without touching this code through the entry-point group ``studyapp.renderers`` (the entry point
loads a :class:`RendererPlugin`, or a callable returning one)::

    [project.entry-points."studyapp.renderers"]
    my_renderer = "my_package.module:PLUGIN"
"""

from __future__ import annotations

import math
import os
import resource
import time
from dataclasses import asdict, dataclass, field
from typing import Any, Callable

import numpy as np

ENTRY_POINT_GROUP = "studyapp.renderers"
#: Largest side accepted (pixels) and the share of the available memory a render may plan to use.
MAX_SIDE = 32768
MEMORY_SHARE = 0.5


@dataclass(frozen=True)
class Param:
    """One renderer parameter: ``type`` (bool, int, float, str), ``default``, range ``[low, high]`` (open ends
    with ``low_open``/``high_open``) or ``choices``."""

    type: type
    default: Any
    low: float | None = None
    high: float | None = None
    choices: tuple | None = None
    low_open: bool = False
    high_open: bool = False
    help: str = ""

    def allowed(self) -> str:
        if self.choices:
            return ", ".join(map(str, self.choices))
        if self.type is bool:
            return "true, false"
        lo = "(-inf" if self.low is None else ("(" if self.low_open else "[") + f"{self.low:g}"
        hi = "inf)" if self.high is None else f"{self.high:g}" + (")" if self.high_open else "]")
        return f"{lo}, {hi}"

    def coerce(self, where: str, value):
        """``value`` (possibly a string from the command line) as this parameter's type, checked."""
        bad = ValueError(f"{where}={value!r} is invalid: allowed {self.allowed()}")
        if self.type is bool:
            if isinstance(value, str):
                v = value.strip().lower()
                if v not in ("1", "0", "true", "false", "yes", "no", "on", "off"):
                    raise bad
                value = v in ("1", "true", "yes", "on")
            elif not isinstance(value, (bool, np.bool_)):
                raise bad
            return bool(value)
        if self.type in (int, float):
            try:
                x = float(value)
            except (TypeError, ValueError):
                raise bad from None
            if isinstance(value, bool) or not math.isfinite(x) or (self.type is int and not x.is_integer()):
                raise bad
            if self.low is not None and (x <= self.low if self.low_open else x < self.low):
                raise ValueError(f"{where}={value!r} is out of range: allowed {self.allowed()}")
            if self.high is not None and (x >= self.high if self.high_open else x > self.high):
                raise ValueError(f"{where}={value!r} is out of range: allowed {self.allowed()}")
            return int(x) if self.type is int else x
        value = str(value)
        if self.choices and value not in self.choices:
            raise bad
        return value


@dataclass(frozen=True)
class RendererPlugin:
    name: str
    description: str
    params: dict[str, Param]
    run: Callable[["RenderContext"], np.ndarray]
    #: Rough bytes per screen pixel this renderer holds at once (for the memory check).
    bytes_per_pixel: float = 16.0


@dataclass
class RenderContext:
    """What a plug-in's ``run`` receives; it adds counters to ``tracer`` and extras to ``extra``."""

    scene: Any
    camera: Any
    width: int
    height: int
    gaze: tuple[float, float]
    params: dict
    tracer: Any
    extra: dict = field(default_factory=dict)
    previous_camera: Any = None  # the previous frame's camera (screen-space velocity), or None


_REGISTRY: dict[str, RendererPlugin] = {}
_entry_points_loaded = False


def register(plugin: RendererPlugin) -> RendererPlugin:
    """Add ``plugin`` to the registry (a name may be registered once)."""
    if not isinstance(plugin, RendererPlugin):
        raise ValueError(f"renderer plug-in {plugin!r} is invalid: must be a RendererPlugin")
    if plugin.name in _REGISTRY and _REGISTRY[plugin.name] is not plugin:
        raise ValueError(f"renderer {plugin.name!r} is already registered")
    _REGISTRY[plugin.name] = plugin
    return plugin


def _load_entry_points():
    global _entry_points_loaded
    if _entry_points_loaded:
        return
    _entry_points_loaded = True
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name in _REGISTRY:
            continue
        obj = ep.load()
        register(obj if isinstance(obj, RendererPlugin) else obj())


def available() -> dict[str, RendererPlugin]:
    """All renderers: built-in and those of the ``studyapp.renderers`` entry-point group."""
    from . import builtin_renderers  # noqa: F401  (registers the built-in plug-ins)

    _load_entry_points()
    return dict(_REGISTRY)


def get(name: str) -> RendererPlugin:
    plugins = available()
    if name not in plugins:
        raise ValueError(f"renderer={name!r} is unknown: allowed {', '.join(sorted(plugins))}")
    return plugins[name]


def resolve_params(name: str, params: dict | None) -> dict:
    """Full, checked parameter dict of renderer ``name`` (defaults filled in)."""
    plugin = get(name)
    params = dict(params or {})
    unknown = sorted(set(params) - set(plugin.params))
    if unknown:
        raise ValueError(f"renderer {name!r} has no parameter {unknown[0]!r}: allowed "
                         f"{', '.join(plugin.params) or 'none'}")
    return {k: spec.coerce(f"{name}.{k}", params.get(k, spec.default)) for k, spec in plugin.params.items()}


def _available_bytes() -> float:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return 8e9


def check_resolution(width, height, bytes_per_pixel: float = 16.0) -> tuple[int, int]:
    """Validate the resolution and refuse renders that would not fit in memory (one-line ValueError)."""
    for k, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not float(v).is_integer() or not 1 <= v <= MAX_SIDE:
            raise ValueError(f"{k}={v!r} is out of range: allowed whole pixels in [1, {MAX_SIDE}]")
    need = float(width) * float(height) * bytes_per_pixel + 3e8
    avail = _available_bytes() * MEMORY_SHARE
    if need > avail:
        raise ValueError(f"resolution {int(width)}x{int(height)} is too large for memory: needs about "
                         f"{need / 1e9:.1f} GB, {avail / 1e9:.1f} GB available")
    return int(width), int(height)


def _reset_peak():
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def _peak_mb() -> float:
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def render(scene, renderer: str, params: dict | None, width: int, height: int,
           gaze: tuple[float, float] | None = None, camera: dict | None = None):
    """Render ``scene`` with ``renderer``: ``(image (H, W, 3) float32 linear RGB, stats)``.

    Parameters
    ----------
    scene : str, Path or Scene
        A built-in scene name, a YAML scene file or a :class:`~renderers.scene.Scene`.
    renderer : str
        A registered renderer (``gt``, ``vafr``, ``lmfr``, ``lafr`` or a plug-in).
    params : dict
        Renderer parameters (strings are converted; unknown names are rejected).
    width, height : int
        Resolution in pixels.
    gaze : (x, y), optional
        Gaze point in pixels, inside the display; default the scene display's gaze or the centre.
    camera : dict, optional
        Overrides of the scene camera: ``position``, ``look_at``, ``up``, ``fov_y``, and ``previous`` (the
        overrides of the previous frame's camera, for renderers that use screen-space velocity).

    Returns
    -------
    image : ndarray (H, W, 3) float32
    stats : dict
        ``shading_points``, ``rays_primary``, ``rays_shadow``, ``seconds`` {visibility, shading, antialias,
        inverse_map, total} (``total`` is the frame: everything after the scene and its BVH are ready, which
        ``setup_seconds`` reports), ``peak_mb`` (the process's peak resident memory during the render, Linux VmHWM
        after a reset), skip counters ``missed_rays``, ``offscreen_lp_pixels``, ``shadow_rays_skipped``,
        ``glossy_evaluations``, ``lights_culled``, and renderer extras (``lp_shape``, ``reshaded_share``...).
    """
    from .catalog import resolve
    from .scene import check_gaze
    from .tracer import Tracer

    t_start = time.perf_counter()
    plugin = get(renderer)
    full = resolve_params(renderer, params)
    width, height = check_resolution(width, height, plugin.bytes_per_pixel)
    sc = resolve(scene)
    cam = sc.camera.override(camera)
    if gaze is None:
        gaze = sc.display.gaze if (sc.display.gaze is not None and sc.display.width == width
                                   and sc.display.height == height) else (width / 2.0, height / 2.0)
    gaze = check_gaze(gaze, width, height)
    reset = _reset_peak()
    tracer = Tracer(sc, shadows=bool(full.get("shadows", True)), light_cull=float(full.get("light_cull", 0.0)))
    # Scene loading and the BVH build (once per scene) are setup, not part of the frame time.
    setup = time.perf_counter() - t_start
    t_start = time.perf_counter()
    ctx = RenderContext(sc, cam, width, height, gaze, full, tracer, previous_camera=sc.camera.previous(camera))
    img = plugin.run(ctx)
    c = tracer.counters
    c.seconds["total"] = time.perf_counter() - t_start
    stats = {k: v for k, v in asdict(c).items() if k != "seconds"}
    stats["seconds"] = {k: round(float(v), 6) for k, v in c.seconds.items()}
    stats["setup_seconds"] = round(setup, 6)
    stats.update(renderer=renderer, params=full, width=width, height=height, gaze=list(gaze),
                 scene=sc.name, lights=sc.light_count(), peak_mb=round(_peak_mb(), 1),
                 peak_mb_is_per_render=reset, **ctx.extra)
    if not ctx.extra.pop("finite_checked", False) and not np.isfinite(img).all():
        raise ValueError(f"renderer {renderer!r} produced non-finite pixels")
    return img, stats
