"""The FPSM of seed 003 §3.1 (Eq 1–8) and the AFSM of ``sl_as`` on the GPU, from the G-buffer and the
low-resolution render of :mod:`renderers.gpu.lightcuts`: the per-pixel budgets without a round trip through the
CPU's memory for the full-resolution maps.

The passes follow :mod:`renderers.lightcuts.fpsm` formula by formula, in float32 (``shaders/fpsm_*.comp``):

1. ``fpsm_lum`` — Eq 3's input: the luminance of ``fb'`` upsampled bicubically to ``w × h``. The cubic B-spline
   coefficients of ``fb'`` (``w/8 × h/8``: a few thousand values) are prefiltered on the CPU by scipy's own spline
   filter (:func:`bicubic_coefficients`), so the GPU evaluates exactly scikit-image's ``resize(order=3)``;
2. ``fpsm_down`` (twice) — levels 1 and 2 of the Laplacian pyramid (5 × 5 binomial blur, every second pixel);
3. ``fpsm_features`` — Eq 2 (``fb_f``), Eq 1 (``fb_st``: Sobel of normals, albedo and screen velocity), Eq 3
   (``fb_l = max(fb_f, |LP_1| / (LP_3 + ε))``);
4. ``fpsm_rho`` — Eq 4–7 under the reading (``fpsm.rho_map``; ``retained``: the map itself) and the frame's
   extreme finite ρ;
5. ``fpsm_budget`` — Eq 8, ``#L = max(1, ceil(map · MAX_lspp))`` and the glossy rays, into the controls ``ctl``.
"""

from __future__ import annotations

import numpy as np

from ..lightcuts.fpsm import D_TOL, EPSILON, LUMA
from ..projection import view_projection

#: Edge padding of ``fb'`` before the spline prefilter (scipy pads modes ``nearest`` by 12 for its filter).
PAD = 12
#: ``READING`` of the shaders: the readings of Eq 4–8, and the AFSM (``fb_st``, no Eq 3–8).
READINGS = {"derived": 0, "blur": 1, "retained": 2, "afsm": 3}


def bicubic_coefficients(image: np.ndarray) -> np.ndarray:
    """Cubic B-spline coefficients of ``image`` (h', w') padded by :data:`PAD` replicated pixels: what
    ``scipy.ndimage.zoom(order=3, mode="nearest", grid_mode=True)`` (skimage's ``resize`` with ``mode="edge"``)
    interpolates."""
    from scipy import ndimage

    return ndimage.spline_filter(np.pad(np.asarray(image, dtype=np.float64), PAD, mode="edge"), order=3,
                                 mode="mirror")


def _half(n: int) -> int:
    return (n + 1) // 2  # the size of a[::2]


def fpsm_controls(lc, g, low, reading: str, alpha: float, max_lspp: int, max_rspp: int) -> None:
    """Fill ``lc``'s controls (``ctl``: budget, glossy rays, map) of the G-buffer ``g`` from the FPSM under
    ``reading`` (with ``low``, the low-resolution G-buffer whose ``rad`` holds ``fb'``) or, for
    ``reading="afsm"``, from ``fb_st`` alone."""
    ctx = lc.ctx
    w, h = g.width, g.height
    geo = ctx.geometry
    uni = {"u_width": w, "u_height": h, "u_first": 0, "u_alpha": float(alpha), "u_max_lspp": int(max_lspp),
           "u_max_rspp": int(max_rspp), "u_gaze": tuple(float(v) for v in geo.gaze), "u_c_r": float(geo.c_r),
           "u_eps": EPSILON, "u_moving": int(ctx.previous_camera is not None)}
    if ctx.previous_camera is not None:
        uni["u_vp"] = tuple(view_projection(ctx.camera, w, h).T.reshape(-1))
        uni["u_vp_prev"] = tuple(view_projection(ctx.previous_camera, w, h).T.reshape(-1))
    px = lc.fr.pool.get("lc_fp_px", 16 * g.n)
    bufs = {**g.buffers, 14: px}
    defines = {"READING": READINGS[reading], "LUMINANCE": int(low is not None), "PAD": PAD, "D_TOL": D_TOL,
               "LEVEL": 1}
    if low is not None:
        lum = low.read(12)[:, :3].astype(np.float64).reshape(low.height, low.width, 3) @ LUMA
        coef = bicubic_coefficients(lum).astype(np.float32)
        g1, g2 = (_half(w), _half(h)), (_half(_half(w)), _half(_half(h)))
        at1 = coef.size
        at2 = at1 + g1[0] * g1[1]
        bufs[15] = low_buf = lc.fr.pool.get("lc_fp_low", 4 * (at2 + g2[0] * g2[1]))
        low_buf.write(coef.tobytes())
        uni.update(u_coef=(coef.shape[1], coef.shape[0]), u_scale=(low.width / w, low.height / h),
                   u_range=(float(lum.min()), float(lum.max())), u_g1=g1, u_g2=g2, u_g1_at=at1, u_g2_at=at2)
        lc.run("fpsm_lum.comp", g.n, bufs, uni, defines=defines)
        lc.run("fpsm_down.comp", g1[0] * g1[1], bufs, uni, defines=defines)
        lc.run("fpsm_down.comp", g2[0] * g2[1], bufs, uni, defines={**defines, "LEVEL": 2})
    bufs[7] = lc.fr.pool.get("lc_ctl", 16 * g.n)
    lc.common[7] = bufs[7]
    lc.run("fpsm_features.comp", g.n, bufs, uni, defines=defines)
    if reading != "afsm":
        lc.run("fpsm_rho.comp", g.n, bufs, uni, defines=defines)
    lc.run("fpsm_budget.comp", g.n, bufs, uni, defines=defines)


def read_map(lc, g) -> np.ndarray:
    """The map of the controls (``(h, w)`` float32)."""
    ctl = np.empty((g.n, 4), dtype=np.int32)
    lc.common[7].read_into(ctl, size=ctl.nbytes)
    return ctl[:, 2].copy().view(np.float32).reshape(g.height, g.width)
