"""Compiled LP-buffer kernels: the bilinear inverse mapping (LP buffer -> screen) and its footprint.

LP layout: column ``c`` holds ``n[c]`` shaded rows; row ``j`` of column ``c`` is the polar angle
``theta = 2 pi (j + 0.5) / L[c]`` (VaFR: ``L[c] = l(e(c + 0.5))``, seed 001 Eq 8-9; LMFR/LaFR: ``L[c] = h``,
Eq 1), at the eccentricity of column centre ``c + 0.5``. A screen pixel with forward-mapped column ``u``
(seed 001 Eq 5 / Eq 1, 14-15) and polar angle ``theta`` is the bilinear blend of its two neighbouring columns
``c0 = floor(u - 0.5)``, ``c1 = c0 + 1``, and in each column of the two rows around
``t = theta L[c] / (2 pi) - 0.5``, rows wrapping around modulo ``n[c]`` (the angular seam).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .foveation._kernels import FORWARD, angle, point

TWO_PI = 2.0 * math.pi
#: The kernels the GPU backend translates (renderers/gpu/codegen.py ``lp_glsl``), one generated file each: a screen
#: offset's column from the u(r) table, a screen pixel's bilinear fetch from the LP buffer (which calls it), the
#: filling of an LP row, whether an LP pixel is shaded.
GLSL_FLOAT_ROOTS = ("table_u",)
GLSL_INVERSE_ROOTS = ("inverse_pixel",)
GLSL_FILL_ROOTS = ("fill_row",)
GLSL_NEEDED_ROOTS = ("needed",)


@njit(cache=True, inline="always")
def _rows(theta, Lc, nc):
    t = theta * Lc / TWO_PI - 0.5
    r0 = math.floor(t)
    f = t - r0
    r0 = int(r0) % nc
    r1 = (r0 + 1) % nc
    return r0, r1, f


@njit(cache=True, inline="always")
def footprint(method, P, dx, dy, L, n, w_eff):
    """Columns, rows and weights of the bilinear fetch of screen offset ``(dx, dy)`` from the gaze."""
    u, _ = point(method, FORWARD, dx, dy, P)
    theta = angle(dx, dy)
    uc = min(max(u - 0.5, 0.0), w_eff - 1.0)
    c0 = int(math.floor(uc))
    fu = uc - c0
    c1 = min(c0 + 1, w_eff - 1)
    a0, a1, fa = _rows(theta, L[c0], n[c0])
    b0, b1, fb = _rows(theta, L[c1], n[c1])
    return c0, c1, fu, a0, a1, fa, b0, b1, fb


@njit(cache=True, parallel=True)
def inverse_map(lp, method, P, gx, gy, L, n, w_eff, x0, y0, out):
    """Screen tile ``out[(y0 + j), (x0 + i)]`` sampled bilinearly from the LP buffer ``lp`` (h, w, 3)."""
    th, tw = out.shape[0], out.shape[1]
    for j in prange(th):
        dy = y0 + j + 0.5 - gy
        for i in range(tw):
            dx = x0 + i + 0.5 - gx
            c0, c1, fu, a0, a1, fa, b0, b1, fb = footprint(method, P, dx, dy, L, n, w_eff)
            for ch in range(3):
                va = lp[a0, c0, ch] * (1.0 - fa) + lp[a1, c0, ch] * fa
                vb = lp[b0, c1, ch] * (1.0 - fb) + lp[b1, c1, ch] * fb
                out[j, i, ch] = va * (1.0 - fu) + vb * fu


@njit(cache=True)
def mark_footprint(method, P, gx, gy, L, n, w_eff, xs, ys, need):
    """Mark in ``need`` (h, w) the LP pixels that the bilinear fetch of screen points ``(xs, ys)`` reads."""
    for q in range(xs.size):
        c0, c1, fu, a0, a1, fa, b0, b1, fb = footprint(method, P, xs[q] - gx, ys[q] - gy, L, n, w_eff)
        need[a0, c0] = True
        need[a1, c0] = True
        need[b0, c1] = True
        need[b1, c1] = True


@njit(cache=True, parallel=True)
def wrap_pad(lp, n, pad, out):
    """``out[pad + j, c] = lp[j mod n[c], c]`` for ``j`` in ``[-pad, h + pad)``: rows continued around the seam."""
    H = out.shape[0]
    for c in prange(lp.shape[1]):
        nc = n[c]
        for jj in range(H):
            j = (jj - pad) % nc
            for ch in range(lp.shape[2]):
                out[jj, c, ch] = lp[j, c, ch]


@njit(cache=True, inline="always")
def needed(border, x, y, width, height):
    """Whether an LP pixel (of the mask) is shaded: a border pixel's bilinear fetch reads it (``border``), or its
    screen position ``(x, y)`` lies on the ``width`` x ``height`` display."""
    return border or (x >= 0.0 and x < width and y >= 0.0 and y < height)


@njit(cache=True, parallel=True)
def mark_needed(need, jj, ii, x, y, width, height):
    """:func:`needed` of the LP pixels ``(jj, ii)`` at screen positions ``(x, y)``, into ``need`` (h, w) (which
    holds the border footprint)."""
    for q in prange(jj.size):
        need[jj[q], ii[q]] = needed(need[jj[q], ii[q]], x[q], y[q], width, height)


@njit(cache=True, inline="always")
def fill_row(lp, shaded, j, w):
    """Copy into each unshaded pixel of LP row ``j`` the last shaded pixel of the row at a smaller column (column
    0 if there is none), in place."""
    src = 0
    for c in range(w):
        if shaded[j, c]:
            src = c
        elif src != c:
            lp[j, c] = lp[j, src]


@njit(cache=True, parallel=True)
def fill_rows(lp, shaded):
    """:func:`fill_row` of every row of the LP buffer ``lp`` (h, w, 3), in place."""
    for j in prange(lp.shape[0]):
        fill_row(lp, shaded, j, lp.shape[1])


@njit(cache=True, inline="always")
def fast_angle(dx, dy):
    """``atan2(dy, dx)`` in ``[0, 2 pi)`` by a minimax polynomial (|error| < 1.2e-5 rad)."""
    ax, ay = abs(dx), abs(dy)
    mx = max(ax, ay)
    if mx == 0.0:
        return 0.0
    z = min(ax, ay) / mx
    s = z * z
    a = ((-0.0464964749 * s + 0.15931422) * s - 0.327622764) * s * z + z
    if ay > ax:
        a = 0.5 * math.pi - a
    if dx < 0.0:
        a = math.pi - a
    if dy < 0.0:
        a = TWO_PI - a
    if a >= TWO_PI:
        a -= TWO_PI
    return a


@njit(cache=True, inline="always")
def _rows_fast(t, nc):
    """Rows around ``t`` (>= -0.5) wrapped modulo ``nc``, and the weight of the second; no integer modulo
    unless ``t`` lies past the column's last row (the seam)."""
    if t < 0.0:
        return nc - 1, 0, t + 1.0
    r0 = int(t)
    f = t - r0
    if r0 >= nc - 1:
        r = r0 % nc
        return r, (r + 1) % nc, f
    return r0, r0 + 1, f


@njit(cache=True, inline="always")
def table_u(utab, exact, inv_step, kmax, method, P, dx, dy):
    """Column ``u`` of screen offset ``(dx, dy)`` from the gaze: ``utab[k] = u(k / inv_step)`` interpolated
    linearly, or the exact kernel in the intervals flagged in ``exact``. Every mapping's column depends on the
    distance from the gaze only (seed 001 Eq 5; Eq 1, 14-15), so the table is exact up to interpolation."""
    s = math.sqrt(dx * dx + dy * dy) * inv_step
    k = min(int(s), kmax)
    if exact[k] == 0:
        f = s - k
        return utab[k] * (1.0 - f) + utab[k + 1] * f
    u, _ = point(method, FORWARD, dx, dy, P)
    return u


@njit(cache=True, inline="always")
def _blend(lp, ch, c0, c1, a0, a1, b0, b1, w00, w01, w10, w11):
    """Channel ``ch`` of the bilinear blend of LP pixels (rows a0, a1 of column c0; b0, b1 of c1)."""
    return w00 * lp[a0, c0, ch] + w01 * lp[a1, c0, ch] + w10 * lp[b0, c1, ch] + w11 * lp[b1, c1, ch]


@njit(cache=True, inline="always")
def inverse_pixel(lp, utab, inv_step, exact, kmax, method, P, gx, gy, Lr, n, w_eff, x, y):
    """Colour ``(r, g, b)`` of the screen pixel at column ``x``, row ``y``: :func:`footprint` with ``u`` from
    :func:`table_u` and the polynomial polar angle :func:`fast_angle`; ``Lr = L / (2 pi)``."""
    dx = x + 0.5 - gx
    dy = y + 0.5 - gy
    u = table_u(utab, exact, inv_step, kmax, method, P, dx, dy)
    theta = fast_angle(dx, dy)
    uc = min(max(u - 0.5, 0.0), w_eff - 1.0)
    c0 = int(uc)
    fu = uc - c0
    c1 = min(c0 + 1, w_eff - 1)
    a0, a1, fa = _rows_fast(theta * Lr[c0] - 0.5, n[c0])
    b0, b1, fb = _rows_fast(theta * Lr[c1] - 0.5, n[c1])
    w00 = (1.0 - fu) * (1.0 - fa)
    w01 = (1.0 - fu) * fa
    w10 = fu * (1.0 - fb)
    w11 = fu * fb
    return (_blend(lp, 0, c0, c1, a0, a1, b0, b1, w00, w01, w10, w11),
            _blend(lp, 1, c0, c1, a0, a1, b0, b1, w00, w01, w10, w11),
            _blend(lp, 2, c0, c1, a0, a1, b0, b1, w00, w01, w10, w11))


@njit(cache=True, parallel=True, fastmath=True)
def inverse_map_table(lp, utab, inv_step, exact, method, P, gx, gy, Lr, n, w_eff, y0, out):
    """:func:`inverse_map` with ``u(r)`` read from a table (:func:`table_u`) and a polynomial polar angle
    (:func:`inverse_pixel`)."""
    th, tw = out.shape[0], out.shape[1]
    kmax = utab.size - 2
    # Blocks of 64 columns x the tile's rows: a compact screen block reads a compact part of the LP buffer.
    nb = (tw + 63) // 64
    for blk in prange(nb * th):
        b = blk // th
        j = blk - b * th
        for i in range(b * 64, min(tw, b * 64 + 64)):
            out[j, i, 0], out[j, i, 1], out[j, i, 2] = inverse_pixel(lp, utab, inv_step, exact, kmax, method, P,
                                                                     gx, gy, Lr, n, w_eff, i, y0 + j)
