"""The built-in renderer plug-ins: ``gt``, ``vafr``, ``lmfr``, ``lafr`` (seed 001 §5.2.1, §6, §7).

Common parameters: ``shadows`` (cast shadow rays; the scene and each light may also opt out), ``light_cull``
(the culling fraction ``eps`` of :mod:`._shade`), ``stereo`` (``mono``: the scene camera; ``dup``: both eyes
rendered, cameras ``-/+ ipd/2`` along the right vector; VaFR also ``rep``: right eye reprojected, seed §5.1) and
``eye`` (which eye's image is returned; both are rendered and timed). Foveated renderers add ``pipeline``
(``raycast``, seed §6.1, or ``deferred``, §3.4).
"""

from __future__ import annotations

import functools
import math
import re

from data_schema.errors import UserError
from data_schema.geometry import ViewingGeometry

from . import pipeline as pl
from .foveation import DEFAULT_PIVOTS, PRESETS, mapping_for
from .plugin_types import Param, RendererPlugin, StrengthSpec

COMMON = {
    "shadows": Param(bool, True, help="cast shadow rays"),
    "light_cull": Param(float, 0.01, 0.0, 1.0, high_open=True,
                        help="drop lights whose summed unshadowed share is <= this fraction"),
    "stereo": Param(str, "mono", choices=("mono", "dup"), help="mono, or both eyes rendered (dup)"),
    "eye": Param(str, "left", choices=("left", "right"), help="eye returned when stereo"),
}
FOVEATED = {"pipeline": Param(str, "raycast", choices=("raycast", "deferred"), help="ray casting or deferred")}


def _eyes(ctx):
    """Cameras of the eyes to render: ``[scene camera]`` or ``[left, right]``."""
    if ctx.params["stereo"] == "mono":
        return [ctx.camera]
    ipd = ctx.scene.display.ipd
    return [ctx.camera.eye(-ipd / 2.0), ctx.camera.eye(ipd / 2.0)]


def _pick(ctx, images):
    ctx.extra["eyes"] = len(images)
    if len(images) > 1:  # both eyes for a binocular presenter (live trials show them side by side)
        ctx.extra["eye_images"] = list(images)
    return images[-1] if (ctx.params["eye"] == "right" and len(images) > 1) else images[0]


def gt_spp(params: dict) -> int:
    """The checked ``spp`` of a GT render (a square number: the samples form a grid of strata)."""
    spp = int(params.get("spp", 1))
    if math.isqrt(spp) ** 2 != spp:
        raise UserError(f"gt.spp={spp} is invalid: must be a square number (1, 4, 9, 16, ...)")
    return spp


def run_gt(ctx):
    spp, filt = gt_spp(ctx.params), ctx.params.get("filter", "box")
    return _pick(ctx, [pl.render_gt(ctx.tracer, cam, ctx.width, ctx.height, spp, filt) for cam in _eyes(ctx)])


def _mapping_params(method: str, p: dict) -> dict:
    if method == "vafr":
        return {"preset": p["preset"], "e_max": p["e_max"], "acuity_scale": p["acuity_scale"]}
    if method == "lmfr":
        return {"delta": p["delta"], "alpha": p["alpha"]}
    return {"delta": p["delta"], "alpha": p["alpha"], "beta": p["beta"], "a": p["a"]}


def foveation_mapping(method: str, geometry, params: dict, coverage: bool = False):
    """The mapping of renderer ``method`` with its checked ``params`` for ``geometry`` (both backends).

    The mappings refuse parameters under which they are undefined for the display (no LP column to shade,
    fewer than 4 LP rows, LaFR's ``Fa`` outside (0, 1)) and, with ``coverage``, those that leave part of the
    display without samples (``check_coverage``); the refusal names the renderer's parameter
    (``vafr.e_max=...``)."""
    mp = _mapping_params(method, params)
    try:
        mapping = mapping_for(method, geometry, **mp)
        if coverage:
            mapping.check_coverage()
        return mapping
    except UserError as exc:
        names = "|".join(map(re.escape, mp))
        raise UserError(re.sub(rf"(?<![\w.])({names})=", rf"{method}.\1=", str(exc))) from None


@functools.lru_cache(maxsize=256)
def _check_display(method: str, params: tuple, width: int, height: int, fov_y_deg: float) -> None:
    # The gaze at the display's centre: the refusals do not depend on the gaze (a live trial moves it; LaFR's
    # foveal-boundary and Fa conditions are hardest there, where the farthest corner is nearest). Cached: the
    # registry runs the check before every frame.
    centre = ViewingGeometry.create(width, height, fov_y_deg, (width / 2.0, height / 2.0))
    foveation_mapping(method, centre, dict(params), coverage=True)


def _checker(method: str):
    def check(params: dict, geometry) -> None:
        _check_display(method, tuple(sorted(_mapping_params(method, params).items())), geometry.width,
                       geometry.height, geometry.fov_y_deg)
    return check


def _gt_check(params: dict, geometry) -> None:
    gt_spp(params)


def run_foveated(method: str):
    def run(ctx):
        p = ctx.params
        t = ctx.tracer
        mapping = foveation_mapping(method, ctx.geometry, p)
        layout = pl.LPLayout(mapping)
        ctx.extra["lp_shape"] = [layout.w, layout.h]
        ctx.extra["lp_pixels"] = int(layout.mask.sum())
        exposure = ctx.exposure  # FXAA's luma only: the image stays unexposed
        eyes = _eyes(ctx)
        images = []
        if p["stereo"] == "rep":
            lp, jj, ii, xs, ys, prim, tfar = pl.render_lp(t, eyes[0], layout, p["pipeline"], ctx.width, ctx.height)
            right_lp, reshaded = pl.reproject(t, layout, lp, jj, ii, xs, ys, prim, tfar, eyes[0], eyes[1],
                                              ctx.width, ctx.height)
            t.counters.reshaded_pixels += reshaded
            ctx.extra["reshaded_share"] = reshaded / max(1, len(jj))
            for buf in (lp, right_lp):
                images.append(pl.finish(t, layout, buf, p, ctx.width, ctx.height, exposure, (jj, ii)))
        else:
            for cam in eyes:
                lp, jj, ii = pl.render_lp(t, cam, layout, p["pipeline"], ctx.width, ctx.height)[:3]
                images.append(pl.finish(t, layout, lp, p, ctx.width, ctx.height, exposure, (jj, ii)))
        return _pick(ctx, images)
    return run


#: Smallest VaFR ``e_max`` (degrees) that leaves an LP column to shade on any display: column 0 is shaded when
#: ``u(e_max) >= 0.5`` (seed 001 §3.2.2) and ``u(e) = integral of du/de = 2 f(e)`` (Eq 4-5) is at most
#: ``2 f_max e`` with the curve's peak acuity ``f_max = f(0)`` (40 cpd; the caps only lower it): 0.5 / 80 deg.
#: A capped curve (``auto``: the display's Nyquist rate) needs more; the mapping checks that per display.
E_MAX_LOW = 0.5 / (2.0 * max(cpd for _, cpd in DEFAULT_PIVOTS))

#: The range of VaFR's ``acuity_scale`` (:func:`renderers.foveation.acuity.scale_falloff`). Below: the LP columns
#: of a steep enough fall-off spread too thinly to cover the display (``check_coverage`` refuses 0.02 on a
#: 7680 x 4320 display at 110 deg, 0.005 at 1920 x 1080 and 20 deg); at 0.05 about 6,100 points are shaded (0.6 %
#: of the seed's 1,061,630), at 2 (the MAR slope halved) 3.0 million, the largest load accepted.
ACUITY_SCALE = (0.05, 2.0)


def _vafr_preview(params: dict) -> dict:
    """VaFR's shading load follows visual acuity, not the image: about a million LP pixels whatever the size
    (seed 001 §3.2.2), 470 per pixel of a 64 x 36 thumbnail. Capping the acuity curve at the thumbnail's own
    Nyquist rate (preset ``auto``) shades about as many points as it has pixels, 40-80x faster. What the cap
    removes would only supersample the thumbnail: the observer's difference from GT grows (0.059 -> 0.092 on
    cornell, 0.054 -> 0.083 street_night, 0.058 -> 0.063 temple at 64 x 36) but stays below LaFR's (delta 2.2
    and 8), so the ranking the simulated observer answers from is kept (tests/test_live.py)."""
    return {**params, "preset": "auto"}


GT = RendererPlugin(
    "gt", "ground truth: every pixel shaded, one ray per pixel centre or spp stratified samples",
    {**COMMON,
     "spp": Param(int, 1, 1, 256, help="samples per pixel, a square number (stratified, jittered); 1: the centre"),
     "filter": Param(str, "box", choices=("box", "tent"), help="pixel filter of the samples (box or 1-px tent)")},
    run_gt, gpu="renderers.gpu.runners:run_gt", check=_gt_check)
VAFR = RendererPlugin(
    "vafr", "visual-acuity-consistent foveated rendering (seed 001): constant LP buffer, FXAA in the LP buffer",
    {**COMMON, **FOVEATED,
     "stereo": Param(str, "mono", choices=("mono", "dup", "rep"), help="mono, dup (both eyes) or rep "
                     "(right eye reprojected from the left LP buffer)"),
     "fxaa": Param(bool, True, help="FXAA 3.11 (preset 12) in the LP buffer"),
     "preset": Param(str, "default", choices=tuple(PRESETS), help="acuity curve"),
     "e_max": Param(float, 60.0, E_MAX_LOW, 90.0, high_open=True, help="largest eccentricity (deg)"),
     "acuity_scale": Param(float, 1.0, *ACUITY_SCALE, help="scale of the acuity fall-off (seed 001 Eq 2's MAR "
                           "slope / acuity_scale): 1 the seed's curve, below 1 fewer shading points outside the "
                           "fovea")},
    run_foveated("vafr"), bytes_per_pixel=40.0, check=_checker("vafr"), preview=_vafr_preview,
    gpu="renderers.gpu.runners:run_vafr", strength=StrengthSpec("acuity_scale", "lower"))
_AA = {"aa": Param(bool, True, help="LMFR anti-aliasing: 3x3 Gaussian in the LP buffer + foveal Gaussian")}
LMFR = RendererPlugin(
    "lmfr", "kernel log-polar foveated rendering (Meng et al.), u = w z^alpha",
    {**COMMON, **FOVEATED, **_AA,
     "delta": Param(float, 1.8, 1.0, 16.0, low_open=True, help="LP buffer = screen / delta per axis"),
     "alpha": Param(float, 4.0, 0.0, 16.0, low_open=True, help="kernel exponent")},
    run_foveated("lmfr"), bytes_per_pixel=40.0, check=_checker("lmfr"), gpu="renderers.gpu.runners:run_lmfr",
    strength=StrengthSpec("delta", "higher"))
LAFR = RendererPlugin(
    "lafr", "locomotion-aware foveated rendering (Shi et al.), two-part kernel",
    {**COMMON, **FOVEATED, **_AA,
     "delta": Param(float, 1.8, 1.0, 16.0, low_open=True, help="LP buffer = screen / delta per axis"),
     "alpha": Param(float, 0.85, 0.0, 1.0, low_open=True, high_open=True, help="foveal kernel parameter"),
     "beta": Param(float, 0.7, 0.0, 10.0, low_open=True, help="peripheral kernel parameter"),
     "a": Param(float, 0.25, 0.0, 1.0, low_open=True, high_open=True, help="LMFR exponent in LaFR convention")},
    run_foveated("lafr"), bytes_per_pixel=40.0, check=_checker("lafr"), gpu="renderers.gpu.runners:run_lafr",
    strength=StrengthSpec("delta", "higher"))


