"""studyapp renderers: scenes, the renderer plug-ins (GT, VaFR, LMFR, LaFR) and the stimulus cache.

Importing this package is cheap: Embree, numba kernels and pyvista load on first use.

>>> from renderers import render
>>> img, stats = render("cornell", "vafr", {}, 320, 240)      # doctest: +SKIP
"""

from __future__ import annotations


def render(scene, renderer, params, width, height, gaze=None, camera=None):
    """Render a scene; see :func:`renderers.registry.render`."""
    from .registry import render as _render

    return _render(scene, renderer, params, width, height, gaze=gaze, camera=camera)


def available_renderers():
    """Names and parameter specs of every registered renderer."""
    from .registry import available

    return available()


__all__ = ["render", "available_renderers"]
