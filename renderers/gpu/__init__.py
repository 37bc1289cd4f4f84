"""GPU backend: the built-in renderers (GT, VaFR, LMFR, LaFR) as OpenGL 4.3 compute shaders via moderngl.

The same scenes, shading model, light culling, foveation mappings, anti-aliasing and stats record as the CPU
renderers; see ``docs/gpu.md``. Reached through the one registration route of the renderers: a plug-in names
its GPU version (``RendererPlugin.gpu``, e.g. ``"renderers.gpu.runners:run_vafr"``) and
:func:`renderers.registry.render` with ``backend="gpu"`` runs it on the scene :func:`device_scene` uploaded.
Importing this package imports nothing from OpenGL: moderngl loads with the first context
(:func:`renderers.gpu.context.get_device`).

>>> from renderers.gpu import render
>>> img, stats = render("cornell", "vafr", {}, 320, 240)      # doctest: +SKIP
"""

from __future__ import annotations


def device_scene(scene, params: dict):
    """The uploaded scene the registry passes as ``ctx.tracer`` on the GPU backend (see :mod:`.upload`)."""
    from .upload import device_scene as make

    return make(scene, params)


def render(scene, renderer: str, params: dict | None, width: int, height: int, gaze=None, camera=None):
    """:func:`renderers.registry.render` with ``backend="gpu"``."""
    from ..registry import render as registry_render

    return registry_render(scene, renderer, params, width, height, gaze=gaze, camera=camera, backend="gpu")
