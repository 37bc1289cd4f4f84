"""The FPSM of seed 003 §3.1 (Eq 1–8) and the AFSM of ``sl_as`` on the GPU, from the G-buffer and the
low-resolution render of :mod:`renderers.gpu.lightcuts`: the per-pixel budgets without a round trip through the
CPU's memory for the full-resolution maps.

The passes of ``shaders/fpsm.comp`` (``PASS``) evaluate, in float32, the per-pixel kernels of
:mod:`renderers.lightcuts.fpsm` that the CPU evaluates in float64 (GLSL generated from them, ``fpsm_gen.glsl``):

1. Eq 3's input: the luminance of ``fb'`` upsampled bicubically to ``w × h`` (``resample_at``). The cubic
   B-spline coefficients of ``fb'`` (``w/8 × h/8``: a few thousand values) are prefiltered on the CPU by scipy's
   own spline filter (``fpsm.upsampling``), as the CPU's resampling does;
2. and 3. levels 1 and 2 of the Laplacian pyramid (``blur5`` at every second pixel);
4. Eq 2 (``acuity``), Eq 1 (``gradient_at``, ``feature``: Sobel of normals, albedo and screen velocity), Eq 3
   (``resample_at`` of the levels, ``contrast_at``, ``feature``);
5. Eq 4–7 under the reading (``rho_at``; ``retained``: the map itself) and the frame's extreme finite ρ;
6. Eq 8 (``map_at``), ``#L = max(1, ceil(map · MAX_lspp))`` and the glossy rays (``budget``) into the controls
   ``ctl``.
"""

from __future__ import annotations

import numpy as np

from ..lightcuts.fpsm import BLUR, DERIVED, EPSILON, LUMA, RETAINED, upsampling
from ..projection import view_projection

#: ``READING`` of the shader: the readings of Eq 4–8, and the AFSM (``fb_st``, no Eq 3–8).
READINGS = {"derived": DERIVED, "blur": BLUR, "retained": RETAINED, "afsm": 3}


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
    bufs = {**g.buffers, "fp_px": px}
    defines = {"READING": READINGS[reading], "LUMINANCE": int(low is not None)}

    def run(n: int, pass_: int) -> None:
        lc.run("fpsm.comp", n, bufs, uni, defines={**defines, "PASS": pass_})

    if low is not None:
        lum = low.read("rad")[:, :3].astype(np.float64).reshape(low.height, low.width, 3) @ LUMA
        coef, lo, hi = upsampling(lum, 3, floor=0.0)
        coef = coef.astype(np.float32)
        g1, g2 = (_half(w), _half(h)), (_half(_half(w)), _half(_half(h)))
        at1 = coef.size
        at2 = at1 + g1[0] * g1[1]
        bufs["fp_low"] = low_buf = lc.fr.pool.get("lc_fp_low", 4 * (at2 + g2[0] * g2[1]))
        low_buf.write(coef.tobytes())
        uni.update(u_coef=(coef.shape[1], coef.shape[0]), u_scale=(low.width / w, low.height / h),
                   u_range=(lo, hi), u_g1=g1, u_g2=g2, u_g1_at=at1, u_g2_at=at2)
        run(g.n, 1)
        run(g1[0] * g1[1], 2)
        run(g2[0] * g2[1], 3)
    bufs["ctl"] = lc.common["ctl"] = lc.fr.pool.get("lc_ctl", 16 * g.n)
    run(g.n, 4)
    if reading != "afsm":
        run(g.n, 5)
    run(g.n, 6)


def read_map(lc, g) -> np.ndarray:
    """The map of the controls (``(h, w)`` float32)."""
    ctl = np.empty((g.n, 4), dtype=np.int32)
    lc.common["ctl"].read_into(ctl, size=ctl.nbytes)
    return ctl[:, 2].copy().view(np.float32).reshape(g.height, g.width)
