"""GPU backend: the built-in renderers (GT, VaFR, LMFR, LaFR) as OpenGL 4.3 compute shaders via moderngl.

The same scenes, shading model, light culling, foveation mappings, anti-aliasing and stats record as the CPU
renderers; see ``docs/gpu.md``. Importing this package imports nothing from OpenGL: moderngl loads when the
first context is made (:func:`renderers.gpu.context.get_device`).

>>> from renderers.gpu import render
>>> img, stats = render("cornell", "vafr", {}, 320, 240)      # doctest: +SKIP
"""

from __future__ import annotations

#: The GPU implementation of each built-in plug-in ("module:function", imported on first use).
GPU_RUNNERS = {
    "gt": "renderers.gpu.runners:run_gt",
    "vafr": "renderers.gpu.runners:run_vafr",
    "lmfr": "renderers.gpu.runners:run_lmfr",
    "lafr": "renderers.gpu.runners:run_lafr",
}


def device_scene(scene, params: dict):
    """The uploaded scene the registry passes as ``ctx.tracer`` (see :mod:`.upload`)."""
    from .upload import device_scene as make

    return make(scene, params)


def runner(name: str):
    """The GPU ``run(ctx)`` of renderer ``name`` (ValueError naming the renderers that have one)."""
    import importlib

    spec = GPU_RUNNERS.get(name)
    if spec is None:
        from data_schema.errors import UserError

        raise UserError(f"renderer {name!r} has no GPU implementation (GPU: {', '.join(GPU_RUNNERS)}): "
                        "use --backend cpu")
    module, func = spec.split(":")
    return getattr(importlib.import_module(module), func)


def render(scene, renderer: str, params: dict | None, width: int, height: int, gaze=None, camera=None):
    """:func:`renderers.registry.render` on the GPU: ``(image (H, W, 3) float32 linear RGB, stats)``.

    Same arguments, checks and stats record; ``ctx.tracer`` is the uploaded scene (:func:`device_scene`) and
    ``setup_seconds`` includes the upload (once per scene and process). Stage seconds come from GPU timer
    queries (llvmpipe: wall clock; ``stats["gpu"]["timing"]`` says which).
    """
    import time
    from dataclasses import asdict

    from .. import registry as R
    from ..catalog import resolve
    from ..scene import check_gaze

    t_start = time.perf_counter()
    plugin = R.get(renderer)
    run = runner(renderer)
    full = R.resolve_params(renderer, params)
    width, height = R.check_resolution(width, height, plugin.bytes_per_pixel)
    sc = resolve(scene)
    cam = sc.camera.override(camera)
    if gaze is None:
        gaze = sc.display.gaze if (sc.display.gaze is not None and sc.display.width == width
                                   and sc.display.height == height) else (width / 2.0, height / 2.0)
    gaze = check_gaze(gaze, width, height)
    reset = R._reset_peak()
    ds = device_scene(sc, full)
    setup = time.perf_counter() - t_start
    t_start = time.perf_counter()
    ctx = R.RenderContext(sc, cam, width, height, gaze, full, ds, previous_camera=sc.camera.previous(camera))
    img = run(ctx)
    c = ds.counters
    c.seconds["total"] = time.perf_counter() - t_start
    stats = {k: v for k, v in asdict(c).items() if k != "seconds"}
    stats["seconds"] = {k: round(float(v), 6) for k, v in c.seconds.items()}
    stats["setup_seconds"] = round(setup, 6)
    stats.update(renderer=renderer, params=full, width=width, height=height, gaze=list(gaze), scene=sc.name,
                 lights=sc.light_count(), peak_mb=round(R._peak_mb(), 1), peak_mb_is_per_render=reset,
                 backend="gpu", **ctx.extra)
    return img, stats
