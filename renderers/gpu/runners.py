"""The GPU implementations of the built-in plug-ins: ``run(ctx) -> image`` like the CPU ones.

``ctx`` is the registry's :class:`~renderers.registry.RenderContext` with ``ctx.tracer`` a
:class:`~renderers.gpu.upload.DeviceScene`; parameters have the CPU plug-in's names and defaults.
"""

from __future__ import annotations

from ..builtin_renderers import _eyes, _pick, gt_spp
from . import pipelines as P
from .frame import Frame


def _finish(fr: Frame, ctx, images):
    fr.close()
    ctx.extra["gpu"] = {"renderer": fr.dev.renderer, "context": fr.dev.source, "timing": fr.timer.method}
    ctx.extra["finite_checked"] = True  # the gather pass counts non-finite samples (Frame.close refuses them)
    return _pick(ctx, images)


def run_gt(ctx):
    """GT on the GPU (see :func:`renderers.builtin_renderers.run_gt`)."""
    fr = Frame(ctx.tracer)
    spp, filt = gt_spp(ctx.params), ctx.params.get("filter", "box")
    images = []
    for cam in _eyes(ctx):
        buf = P.render_gt(fr, cam, ctx.width, ctx.height, spp, filt)
        images.append(P.read_image(buf, ctx.width, ctx.height))
    return _finish(fr, ctx, images)
