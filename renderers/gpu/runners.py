"""The GPU implementations of the built-in plug-ins: ``run(ctx) -> image`` like the CPU ones.

``ctx`` is the registry's :class:`~renderers.registry.RenderContext` with ``ctx.tracer`` a
:class:`~renderers.gpu.upload.DeviceScene`; parameters have the CPU plug-in's names and defaults.
"""

from __future__ import annotations

from ..builtin_renderers import _eyes, _mapping_params, _pick, gt_spp
from . import pipelines as P
from .frame import Frame


def _finish(fr: Frame, ctx, images, closed: bool = False):
    if not closed:
        fr.close()
    ctx.extra["gpu"] = {"renderer": fr.dev.renderer, "context": fr.dev.source, "timing": fr.timer.method}
    return _pick(ctx, images)


def run_gt(ctx):
    """GT on the GPU (see :func:`renderers.builtin_renderers.run_gt`)."""
    ctx.tracer.check_lights()
    fr = Frame(ctx.tracer)
    spp, filt = gt_spp(ctx.params), ctx.params.get("filter", "box")
    images = []
    for cam in _eyes(ctx):
        buf = P.render_gt(fr, cam, ctx.width, ctx.height, spp, filt)
        images.append(P.read_image(buf, ctx.width, ctx.height))
    return _finish(fr, ctx, images)


def run_foveated(method: str):
    """The GPU ``run`` of a foveated plug-in (see :func:`renderers.builtin_renderers.run_foveated`)."""

    def run(ctx):
        p = ctx.params
        ctx.tracer.check_lights()
        fr = Frame(ctx.tracer)
        tables = P.lp_tables(fr, method, _mapping_params(method, p), ctx.geometry)
        ctx.extra["lp_shape"] = [tables.w, tables.h]
        ctx.extra["lp_pixels"] = tables.n_mask
        exposure = ctx.exposure  # FXAA's luma only: the image stays unexposed
        eyes = _eyes(ctx)
        images = []
        if p["stereo"] == "rep":
            lp = P.render_lp(fr, tables, eyes[0], ctx.width, ctx.height, ctx.gaze, p["pipeline"])
            right = P.reproject(fr, tables, lp, eyes[0], eyes[1], ctx.width, ctx.height, ctx.gaze)
            for buf in (lp, right):  # both eyes read back: a binocular presenter shows both (eye_images)
                img = P.finish_lp(fr, tables, buf, p, ctx.width, ctx.height, exposure, ctx.gaze)
                images.append(P.read_image(img, ctx.width, ctx.height))
            totals = fr.close()
            ctx.extra["reshaded_share"] = totals["holes"] / max(1, totals["samples"])
            return _finish(fr, ctx, images, closed=True)
        for cam in eyes:
            lp = P.render_lp(fr, tables, cam, ctx.width, ctx.height, ctx.gaze, p["pipeline"])
            img = P.finish_lp(fr, tables, lp, p, ctx.width, ctx.height, exposure, ctx.gaze)
            images.append(P.read_image(img, ctx.width, ctx.height))
        return _finish(fr, ctx, images)

    return run


run_vafr = run_foveated("vafr")
run_lmfr = run_foveated("lmfr")
run_lafr = run_foveated("lafr")
