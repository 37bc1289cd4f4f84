"""Compiled per-point kernels of the three mappings (numba), and the one parallel loop that applies them.

Every formula lives here once; the modules :mod:`.vafr`, :mod:`.kernel` and :mod:`.acuity` document them with
their equation numbers and only pack parameters into a flat float64 vector ``P``:

* VaFR  ``P = [c_r, delta, n, starts[n], u0[n], kind[n], omega0[n], slope[n], tan0[n]]``
* LMFR  ``P = [w, h, Lp, alpha]``
* LaFR  ``P = [w, h, Lp, Fa, U_ef, Z_ef, p, ext_slope]``

(``Lp = log1p(R)`` with ``R`` the largest gaze-to-corner distance; ``p = beta / 0.7``.)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

VAFR, LMFR, LAFR = 0, 1, 2
FORWARD, INVERSE = 0, 1
TWO_PI = 2.0 * math.pi
DEG = 180.0 / math.pi
RAD = math.pi / 180.0


@njit(cache=True, inline="always")
def log1px(x):
    """log1p(x) / x, exact near 0."""
    if abs(x) < 1e-8:
        return 1.0 - 0.5 * x + x * x / 3.0
    return math.log1p(x) / x


@njit(cache=True, inline="always")
def expm1x(y):
    """expm1(y) / y, exact near 0."""
    if abs(y) < 1e-8:
        return 1.0 + 0.5 * y + y * y / 6.0
    return math.expm1(y) / y


@njit(cache=True, inline="always")
def angle(dx, dy):
    th = math.atan2(dy, dx)
    if th < 0.0:
        th += TWO_PI
        if th >= TWO_PI:
            th = 0.0
    return th


# --- VaFR: the acuity mapping ----------------------------------------------------------------------------------
@njit(cache=True)
def vafr_segment_by_e(e, P):
    n = int(P[2])
    k = 0
    for i in range(1, n):
        if e >= P[3 + i]:
            k = i
    return k


@njit(cache=True)
def vafr_segment_by_u(u, P):
    n = int(P[2])
    k = 0
    for i in range(1, n):
        if u >= P[3 + n + i]:
            k = i
    return k


@njit(cache=True)
def vafr_u_in_segment(k, e, t, P):
    """Seed 001 Eq 5 / 12 on segment k (linear MAR) or the Nyquist segment ``u = u_k + (tan e - tan e_k)/c_r``."""
    n = int(P[2])
    e0 = P[3 + k]
    u0 = P[3 + n + k]
    if P[3 + 2 * n + k] == 0.0:
        w0 = P[3 + 3 * n + k]
        d = e - e0
        return u0 + 2.0 * d / w0 * log1px(P[3 + 4 * n + k] * d / w0)
    return u0 + (t - P[3 + 5 * n + k]) / P[0]


@njit(cache=True)
def vafr_u_of_e(e, t, P):
    return vafr_u_in_segment(vafr_segment_by_e(e, P), e, t, P)


@njit(cache=True)
def vafr_e_of_u(u, P):
    """Seed 001 Eq 10 (segmented); returns (e_deg, tan e)."""
    if u < 0.0:
        u = 0.0
    n = int(P[2])
    k = vafr_segment_by_u(u, P)
    du = u - P[3 + n + k]
    if P[3 + 2 * n + k] == 0.0:
        w0 = P[3 + 3 * n + k]
        e = P[3 + k] + w0 * 0.5 * du * expm1x(P[3 + 4 * n + k] * 0.5 * du)
        if e > 90.0:
            e = 90.0
        return e, math.tan(e * RAD)
    t = P[3 + 5 * n + k] + P[0] * du
    return math.atan(t) * DEG, t


@njit(cache=True)
def vafr_du_de(e, P):
    """Seed 001 Eq 4: du/de = 2 f(e) = 2 / omega(e) (Nyquist segment: the radial pixel density)."""
    n = int(P[2])
    k = vafr_segment_by_e(e, P)
    if P[3 + 2 * n + k] == 0.0:
        return 2.0 / (P[3 + 3 * n + k] + P[3 + 4 * n + k] * (e - P[3 + k]))
    c = math.cos(e * RAD)
    return RAD / (P[0] * c * c)


@njit(cache=True)
def vafr_height(e, t, P):
    """Seed 001 Eq 9 / 19: l(e) = Delta 360 sin e cos e du/de, with sin e cos e = t / (1 + t^2)."""
    return P[1] * 360.0 * (t / (1.0 + t * t)) * vafr_du_de(e, P)


@njit(cache=True)
def vafr_forward(dx, dy, P):
    r = math.hypot(dx, dy)
    t = P[0] * r
    e = math.atan(t) * DEG
    u = vafr_u_of_e(e, t, P)
    return u, angle(dx, dy) / TWO_PI * vafr_height(e, t, P)


@njit(cache=True)
def vafr_inverse(u, v, P):
    e, t = vafr_e_of_u(u, P)
    l = vafr_height(e, t, P)
    th = TWO_PI * v / l if l > 0.0 else 0.0
    r = t / P[0]
    return r * math.cos(th), r * math.sin(th)


# --- LMFR: u = w z^alpha, z = log1p(r) / Lp (seed 001 Eq 1, 14) ------------------------------------------------
@njit(cache=True)
def lmfr_forward(dx, dy, P):
    z = math.log1p(math.hypot(dx, dy)) / P[2]
    return P[0] * z ** P[3], angle(dx, dy) / TWO_PI * P[1]


@njit(cache=True)
def lmfr_inverse(u, v, P):
    un = u / P[0] if u > 0.0 else 0.0
    r = math.expm1(P[2] * un ** (1.0 / P[3]))
    th = TWO_PI * v / P[1]
    return r * math.cos(th), r * math.sin(th)


# --- LaFR (seed 001 Eq 15 as repaired in kernel.py) ------------------------------------------------------------
@njit(cache=True)
def lafr_un_of_z(z, P):
    Fa, U, Z, p, s = P[3], P[4], P[5], P[6], P[7]
    if z <= Z:
        return (z * (1.0 - Fa)) ** (1.0 / Fa)
    if z <= 1.0:
        X = (Z / z - 1.0) / (1.0 - Z)
        if X < -1.0:
            X = -1.0
        g = (2.0 * math.acos(X) - math.pi) / math.pi
        return g ** p * (1.0 - U) + U
    return 1.0 + s * (z - 1.0)


@njit(cache=True)
def lafr_z_of_un(un, P):
    Fa, U, Z, p, s = P[3], P[4], P[5], P[6], P[7]
    if un <= 0.0:
        return 0.0
    if un <= U:
        return un ** Fa / (1.0 - Fa)  # the LaFR kernel K_f(u) = u^Fa / (1 - Fa)
    if un <= 1.0:
        g = ((un - U) / (1.0 - U)) ** (1.0 / p)
        X = math.cos(0.5 * math.pi * (g + 1.0))
        return Z / (1.0 + X * (1.0 - Z))
    return 1.0 + (un - 1.0) / s


@njit(cache=True)
def lafr_forward(dx, dy, P):
    z = math.log1p(math.hypot(dx, dy)) / P[2]
    return P[0] * lafr_un_of_z(z, P), angle(dx, dy) / TWO_PI * P[1]


@njit(cache=True)
def lafr_inverse(u, v, P):
    r = math.expm1(P[2] * lafr_z_of_un(u / P[0], P))
    th = TWO_PI * v / P[1]
    return r * math.cos(th), r * math.sin(th)


# --- the loops -------------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def point(method, direction, a, b, P):
    if method == VAFR:
        if direction == FORWARD:
            return vafr_forward(a, b, P)
        return vafr_inverse(a, b, P)
    if method == LMFR:
        if direction == FORWARD:
            return lmfr_forward(a, b, P)
        return lmfr_inverse(a, b, P)
    if direction == FORWARD:
        return lafr_forward(a, b, P)
    return lafr_inverse(a, b, P)


@njit(cache=True, parallel=True)
def map_points(method, direction, a, b, P, shift_a, shift_b, out_a, out_b):
    """Apply one mapping to 1-D arrays: ``out = point(a - shift)`` (forward) or ``point(a) + shift`` (inverse)."""
    for i in prange(a.size):
        if direction == FORWARD:
            x, y = point(method, direction, a[i] - shift_a, b[i] - shift_b, P)
        else:
            x, y = point(method, direction, a[i], b[i], P)
            x += shift_a
            y += shift_b
        out_a[i] = x
        out_b[i] = y


@njit(cache=True, parallel=True)
def map_screen(method, width, height, gx, gy, P, out_u, out_v):
    """Forward map of every pixel centre ``(i + 0.5, j + 0.5)`` without building coordinate arrays."""
    for j in prange(height):
        dy = j + 0.5 - gy
        for i in range(width):
            u, v = point(method, FORWARD, i + 0.5 - gx, dy, P)
            out_u[j, i] = u
            out_v[j, i] = v


@njit(cache=True)
def vafr_e_of_u_array(u, P):
    e = np.empty_like(u)
    t = np.empty_like(u)
    for i in range(u.size):
        e[i], t[i] = vafr_e_of_u(u[i], P)
    return e, t


@njit(cache=True)
def vafr_u_of_e_array(e, P):
    out = np.empty_like(e)
    for i in range(e.size):
        out[i] = vafr_u_of_e(e[i], math.tan(e[i] * RAD), P)
    return out


@njit(cache=True)
def vafr_du_de_array(e, P):
    out = np.empty_like(e)
    for i in range(e.size):
        out[i] = vafr_du_de(e[i], P)
    return out


@njit(cache=True)
def lafr_un_of_z_array(z, P):
    out = np.empty_like(z)
    for i in range(z.size):
        out[i] = lafr_un_of_z(z[i], P)
    return out


@njit(cache=True)
def vafr_height_array(e, P):
    out = np.empty_like(e)
    for i in range(e.size):
        out[i] = vafr_height(e[i], math.tan(e[i] * RAD), P)
    return out
