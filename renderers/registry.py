"""Renderer plug-ins: one registration route (the ``studyapp.renderers`` entry-point group), and :func:`render`.

Every renderer, the built-in ones included, is an entry point of the group ``studyapp.renderers`` naming a
:class:`~renderers.plugin_types.RendererPlugin` (or a callable returning one); another package adds one the
same way, without touching this code::

    [project.entry-points."studyapp.renderers"]
    my_renderer = "my_package.module:PLUGIN"

A plug-in's presets (e.g. ``sl_e``, ``sl_f``, ``sl_p`` of ``sl``) are listed as renderers of their own. The
plug-in types live in :mod:`renderers.plugin_types`; the output contract is stated there and checked here.
"""

from __future__ import annotations

import importlib
import math
import resource
import time
from dataclasses import asdict, replace

import numpy as np

from data_schema.errors import UserError
from data_schema.geometry import ViewingGeometry, check_gaze

from .plugin_types import Param, RenderContext, RendererPlugin, StrengthSpec

__all__ = ["ENTRY_POINT_GROUP", "Param", "RenderContext", "RendererPlugin", "StrengthSpec", "available", "get",
           "render", "resolve_params", "check_resolution", "check_geometry", "foveation_strength", "BACKENDS"]

ENTRY_POINT_GROUP = "studyapp.renderers"
BACKENDS = ("cpu", "gpu")
#: Largest side accepted (pixels) and the share of the available memory a render may plan to use.
MAX_SIDE = 32768
MEMORY_SHARE = 0.5

_PLUGINS: dict[str, RendererPlugin] | None = None


def _entry_points():
    from importlib.metadata import entry_points

    return entry_points(group=ENTRY_POINT_GROUP)


def available() -> dict[str, RendererPlugin]:
    """Every renderer of the ``studyapp.renderers`` entry-point group, presets included, by name."""
    global _PLUGINS
    if _PLUGINS is None:
        plugins: dict[str, RendererPlugin] = {}
        for ep in _entry_points():
            obj = ep.load()
            plugin = obj if isinstance(obj, RendererPlugin) else obj()
            if not isinstance(plugin, RendererPlugin) or plugin.name != ep.name:
                raise UserError(f"entry point {ep.name} = {ep.value} of {ENTRY_POINT_GROUP} is not the "
                                f"RendererPlugin {ep.name!r}")
            for name in (plugin.name, *plugin.presets):
                if name in plugins:
                    raise UserError(f"renderer {name!r} is registered twice in {ENTRY_POINT_GROUP}")
                plugins[name] = plugin if name == plugin.name else plugin.preset(name)
        _PLUGINS = plugins
    return dict(_PLUGINS)


def get(name: str) -> RendererPlugin:
    plugins = available()
    if name not in plugins:
        raise UserError(f"renderer={name!r} is unknown: allowed {', '.join(sorted(plugins))}")
    return plugins[name]


def foveation_strength(method: str) -> StrengthSpec | None:
    """The continuous foveation strength of renderer ``method``, or ``None`` when it has none (``gt``, ``sl_gt``).

    The plug-in's :class:`~renderers.plugin_types.StrengthSpec` (its one declaration, on the plug-in) with
    ``range`` and ``default`` taken from the parameter's :class:`Param`: e.g. ``vafr`` -> ``acuity_scale``,
    stronger = ``"lower"``; ``lafr`` -> ``delta``, stronger = ``"higher"``. An unknown ``method`` is a
    :class:`UserError` (one line)."""
    plugin = get(method)
    spec = plugin.strength
    if spec is None:
        return None
    param = plugin.params[spec.param]
    return replace(spec, range=param.range, default=param.default)


def _load(ref):
    """A callable, or the function a ``"module:function"`` reference names."""
    if callable(ref):
        return ref
    module, _, attr = ref.partition(":")
    return getattr(importlib.import_module(module), attr)


def resolve_params(name: str, params: dict | None) -> dict:
    """Full, checked parameter dict of renderer ``name`` (defaults filled in)."""
    plugin = get(name)
    params = dict(params or {})
    unknown = sorted(set(params) - set(plugin.params))
    if unknown:
        raise UserError(f"renderer {name!r} has no parameter {unknown[0]!r}: allowed "
                        f"{', '.join(plugin.params) or 'none'}")
    return {k: spec.coerce(f"{name}.{k}", params.get(k, spec.default)) for k, spec in plugin.params.items()}


def preview_params(name: str, params: dict | None) -> dict:
    """``params`` for a thumbnail render of renderer ``name`` (its plug-in's ``preview``; see
    :class:`~renderers.plugin_types.RendererPlugin`)."""
    plugin = get(name)
    params = dict(params or {})
    return plugin.preview(params) if plugin.preview is not None else params


def check_geometry(name: str, params: dict | None, geometry: ViewingGeometry) -> None:
    """Refuse (one line) a renderer that cannot render for ``geometry`` with ``params`` (the plug-in's
    ``check``; e.g. LaFR whose fovea does not fit on the display)."""
    plugin = get(name)
    full = resolve_params(name, params)
    if plugin.check is not None:
        _load(plugin.check)(full, geometry)


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
            raise UserError(f"{k}={v!r} is out of range: allowed whole pixels in [1, {MAX_SIDE}]")
    need = float(width) * float(height) * bytes_per_pixel + 3e8
    avail = _available_bytes() * MEMORY_SHARE
    if need > avail:
        raise UserError(f"resolution {int(width)}x{int(height)} is too large for memory: needs about "
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
           gaze: tuple[float, float] | None = None, camera: dict | None = None, backend: str = "cpu"):
    """Render ``scene`` with ``renderer``: ``(image (H, W, 3) float32 linear unexposed RGB, stats)``.

    Parameters
    ----------
    scene : str, Path or Scene
        A built-in scene name, a YAML scene file or a :class:`~renderers.scene.Scene`.
    renderer : str
        A registered renderer (``studyapp renderers`` lists them).
    params : dict
        Renderer parameters (strings are converted; unknown names are rejected).
    width, height : int
        Resolution in pixels.
    gaze : (x, y), optional
        Gaze point in pixels, inside the image; default the scene display's gaze or the centre.
    camera : dict, optional
        Overrides of the scene camera: ``position``, ``look_at``, ``up``, ``fov_y`` (a study's stimuli get the
        protocol display's vertical visual angle here), and ``previous`` (the overrides of the previous frame's
        camera, for renderers that use screen-space velocity).
    backend : {"cpu", "gpu"}
        The CPU renderers, or the plug-in's GPU version (OpenGL compute, :mod:`renderers.gpu`).

    Returns
    -------
    image : ndarray (H, W, 3) float32
        Linear, unexposed radiance (the output contract of :mod:`renderers.plugin_types`).
    stats : dict
        ``shading_points``, ``rays_primary``, ``rays_shadow``, ``seconds`` {visibility, shading, antialias,
        inverse_map, total} (``total`` is the frame: everything after the scene and its BVH are ready, which
        ``setup_seconds`` reports), ``peak_mb`` (the process's peak resident memory during the render, Linux VmHWM
        after a reset), skip counters ``missed_rays``, ``offscreen_lp_pixels``, ``shadow_rays_skipped``,
        ``glossy_evaluations``, ``lights_culled``, and renderer extras (``lp_shape``, ``reshaded_share``...).
    """
    from .catalog import resolve

    t_start = time.perf_counter()
    if backend not in BACKENDS:
        raise UserError(f"backend={backend!r} is invalid: allowed {', '.join(BACKENDS)}")
    plugin = get(renderer)
    full = resolve_params(renderer, params)
    width, height = check_resolution(width, height, plugin.bytes_per_pixel)
    sc = resolve(scene)
    cam = sc.camera.override(camera)
    if gaze is None:
        gaze = sc.display.gaze if (sc.display.gaze is not None and sc.display.width == width
                                   and sc.display.height == height) else (width / 2.0, height / 2.0)
    geometry = ViewingGeometry.create(width, height, cam.fov_y, check_gaze(gaze, width, height))
    if plugin.check is not None:  # the refusals of validation, for both backends, before any work
        _load(plugin.check)(full, geometry)
    if backend == "gpu":
        if plugin.gpu is None:
            raise UserError(f"renderer {renderer!r} has no GPU version: use --backend cpu")
        run = _load(plugin.gpu)
        reset = _reset_peak()
        tracer = _load("renderers.gpu:device_scene")(sc, full)
    else:
        from .tracer import Tracer

        run = _load(plugin.run)
        reset = _reset_peak()
        tracer = Tracer(sc, shadows=bool(full.get("shadows", True)), light_cull=float(full.get("light_cull", 0.0)))
    # Scene loading and the BVH build (once per scene) are setup, not part of the frame time.
    setup = time.perf_counter() - t_start
    t_start = time.perf_counter()
    ctx = RenderContext(sc, cam, geometry, full, tracer, exposure=sc.exposure,
                        previous_camera=sc.camera.previous(camera))
    img = run(ctx)
    c = tracer.counters
    c.seconds["total"] = time.perf_counter() - t_start
    stats = {k: v for k, v in asdict(c).items() if k != "seconds"}
    stats["seconds"] = {k: round(float(v), 6) for k, v in c.seconds.items()}
    stats["setup_seconds"] = round(setup, 6)
    stats.update(renderer=renderer, backend=backend, params=full, width=width, height=height, gaze=list(gaze),
                 fov_y_deg=geometry.fov_y_deg, scene=sc.name, lights=sc.light_count(), peak_mb=round(_peak_mb(), 1),
                 peak_mb_is_per_render=reset, **ctx.extra)
    check_output(renderer, img, width, height, full)
    return img, stats


def _described(renderer: str, params: dict | None) -> str:
    """``renderer 'vafr' (e_max=1e-300, preset='auto')``: the renderer and the parameters set off their default."""
    plugin = get(renderer)
    changed = {k: v for k, v in (params or {}).items() if k not in plugin.params or v != plugin.params[k].default}
    shown = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v!r}" for k, v in changed.items())
    return f"renderer {renderer!r} ({shown or 'default parameters'})"


def check_output(renderer: str, img, width: int, height: int, params: dict | None = None) -> None:
    """The output contract (:mod:`renderers.plugin_types`): float32 ``(height, width, 3)``, finite, >= 0.

    A wrong type or shape is a bug in the plug-in, reported as such (RuntimeError). Bad values are the last
    guard behind the parameter ranges: such an image is never returned, and the one-line :class:`UserError`
    names the renderer and its parameters. Two reductions check the values (``min`` and ``max`` propagate
    NaN; ``max`` finds +inf) without a boolean temporary of the image's size."""
    if not isinstance(img, np.ndarray) or img.dtype != np.float32 or img.shape != (height, width, 3):
        got = f"{getattr(img, 'dtype', type(img).__name__)} {getattr(img, 'shape', '')}"
        raise RuntimeError(f"renderer {renderer!r} broke the output contract: returned {got}, not float32 "
                           f"({height}, {width}, 3)")
    lo, hi = float(img.min()), float(img.max())
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise UserError(f"{_described(renderer, params)} produced non-finite pixels: refused")
    if lo < 0.0:
        raise UserError(f"{_described(renderer, params)} produced negative radiance ({lo:g}): refused")
