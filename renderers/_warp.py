"""Forward grid warping in the LP buffer (Wissmann et al. 2020, done in the LP buffer as seed 001 §5.1 says): the
rasteriser of :func:`renderers.pipeline.reproject`, one source for both backends.

:func:`warp_quad` (a quad of neighbouring left samples: the depth-discontinuity test, its two triangles) and
:func:`raster_triangle` (a warped triangle's LP pixel centres and barycentric weights) are the kernels that
``renderers/gpu/codegen.py`` (:func:`~renderers.gpu.codegen.warp_glsl`) translates for ``rep_warp.comp``. What a
covered pixel centre does, :func:`fragment`, differs: the CPU depth-tests sequentially, the GPU in phases of
atomics (``rep_warp.comp``), so the GPU keeps its own (the translator calls it by name, ``Translator.externals``).
"""

from __future__ import annotations

import math

from numba import njit

#: The functions translated into GLSL (float32, prefixed ``rep_``) and their callees.
GLSL_FLOAT_ROOTS = ("warp_quad",)


@njit(cache=True)
def quad_continuous(za, zb, zc, zd, max_ratio):
    """A quad whose corner depths are finite, positive and differ by at most ``max_ratio`` has no depth
    discontinuity: it is warped."""
    zmin = min(min(za, zb), min(zc, zd))
    zmax = max(max(za, zb), max(zc, zd))
    return not (not (zmax < math.inf) or zmin <= 0.0 or zmax > zmin * max_ratio)


@njit(cache=True)
def fragment(idx, z, b0, b1, b2, ka, kb, kc, col, zbuf, out, covered):
    """The CPU's fragment: LP pixel ``idx`` takes the barycentric colour of the triangle's corners (left samples
    ``ka, kb, kc``) if its interpolated depth ``z`` is the nearest so far."""
    if z < zbuf[idx]:
        zbuf[idx] = z
        for k in range(3):
            out[idx, k] = b0 * col[ka, k] + b1 * col[kb, k] + b2 * col[kc, k]
        covered[idx] = True


@njit(cache=True)
def raster_triangle(ka, kb, kc, u, phi, z, col, L, n, w_eff, w, zbuf, out, covered, max_extent):
    """Rasterise the triangle of left samples ``ka, kb, kc`` warped to the right view's LP coordinates ``u, phi``
    (depths ``z``) into the LP buffer: every LP pixel centre inside it is a :func:`fragment` with its depth and
    barycentric weights. A triangle straddling the angle seam is unwrapped first; one wider than ``max_extent`` LP
    pixels is stretched (skipped)."""
    two_pi = 2.0 * math.pi
    pu0, pu1, pu2 = u[ka], u[kb], u[kc]
    pp0, pp1, pp2 = phi[ka], phi[kb], phi[kc]
    if max(pp0, max(pp1, pp2)) - min(pp0, min(pp1, pp2)) > math.pi:
        if pp0 < math.pi:
            pp0 += two_pi
        if pp1 < math.pi:
            pp1 += two_pi
        if pp2 < math.pi:
            pp2 += two_pi
    umin = min(pu0, min(pu1, pu2))
    umax = max(pu0, max(pu1, pu2))
    if umax - umin > max_extent:
        return
    c0 = max(0, int(math.ceil(umin - 0.5)))
    c1 = min(w_eff - 1, int(math.floor(umax - 0.5)))
    det = (pu1 - pu0) * (pp2 - pp0) - (pu2 - pu0) * (pp1 - pp0)
    if abs(det) < 1e-18:
        return
    pmin = min(pp0, min(pp1, pp2))
    pmax = max(pp0, max(pp1, pp2))
    for c in range(c0, c1 + 1):
        if n[c] <= 0:
            continue
        per = L[c] / two_pi  # rows per radian in this column
        if (pmax - pmin) * per > max_extent:
            continue
        uc = c + 0.5
        j0 = int(math.ceil(pmin * per - 0.5))
        j1 = int(math.floor(pmax * per - 0.5))
        for j in range(j0, j1 + 1):   # j >= 0: the angles are in [0, 4 pi)
            pc_ = (j + 0.5) / per
            b1 = ((uc - pu0) * (pp2 - pp0) - (pu2 - pu0) * (pc_ - pp0)) / det
            b2 = ((pu1 - pu0) * (pc_ - pp0) - (uc - pu0) * (pp1 - pp0)) / det
            b0 = 1.0 - b1 - b2
            if b0 < -1e-9 or b1 < -1e-9 or b2 < -1e-9:
                continue
            zf = b0 * z[ka] + b1 * z[kb] + b2 * z[kc]
            fragment((j % n[c]) * w + c, zf, b0, b1, b2, ka, kb, kc, col, zbuf, out, covered)


@njit(cache=True)
def warp_quad(a, b, cc, d, u, phi, z, col, L, n, w_eff, w, zbuf, out, covered, max_ratio, max_extent):
    """The quad of left samples ``a, b`` (a row) and ``cc, d`` (the next row), if it has no depth discontinuity
    (:func:`quad_continuous`): its two triangles ``(a, b, d)`` and ``(a, d, cc)``, rasterised."""
    if quad_continuous(z[a], z[b], z[cc], z[d], max_ratio):
        raster_triangle(a, b, d, u, phi, z, col, L, n, w_eff, w, zbuf, out, covered, max_extent)
        raster_triangle(a, d, cc, u, phi, z, col, L, n, w_eff, w, zbuf, out, covered, max_extent)


@njit(cache=True)
def grid_warp(grid, u, phi, z, col, L, n, w_eff, w, zbuf, out, covered, max_ratio, max_extent):
    """Forward grid warping (Wissmann et al. 2020) in the LP buffer: the left LP samples ``grid[j, c]`` (index
    into ``u, phi, z, col``, or -1) form quads with their row and column neighbours; each quad whose corners
    are all valid is warped (:func:`warp_quad`): split into two triangles, warped to the right view's LP
    coordinates and rasterised with a depth test."""
    for c in range(w_eff - 1):
        for j in range(grid.shape[0] - 1):
            a, b = grid[j, c], grid[j, c + 1]
            cc, d = grid[j + 1, c], grid[j + 1, c + 1]
            if a >= 0 and b >= 0 and cc >= 0 and d >= 0:
                warp_quad(a, b, cc, d, u, phi, z, col, L, n, w_eff, w, zbuf, out, covered, max_ratio, max_extent)
