"""Visual-acuity model of VaFR and the closed-form radial mapping it induces (seed 001 Eq 2, 4-5, 10, 12).

The minimum angle of resolution (MAR, degrees per cycle) is piecewise linear in eccentricity between pivots
``(e_k, f_k)`` (seed 001 Eq 2 and its segmented form Eq 12): ``omega(e) = m_k e + omega_k`` on
``[e_k, e_{k+1})``, with ``omega(e_k) = 1 / f_k``, so the acuity ``f = 1 / omega`` matches every pivot.

Two optional caps lower the acuity where the display cannot show it (seed 001 §3.3, Fig 3):

* a constant cap ``cap_cpd`` (the seed's HTC VIVE Pro Eye: 9 cpd, Pimax Crystal: 18 cpd), i.e.
  ``omega >= 1 / cap_cpd``;
* the display's own radial Nyquist rate, half its pixels per degree at each eccentricity
  (``omega >= 2 / (dr/de) = 2 c_r cos^2(e) * 180/pi``). On such a segment ``du/de`` equals the screen's
  radial pixel density, so the LP buffer spends exactly one pixel per screen pixel there: ``u = r + const``.

The mapping ``u(e)`` integrates Eq 4, ``du/de = 2 f(e)``. On a linear-MAR segment (Eq 5)

    u(e) = u_k + (2 / m_k) ln(1 + m_k (e - e_k) / omega(e_k)),

evaluated as ``2 (e - e_k) / omega(e_k) * log1p(x) / x`` so that it stays exact as ``m_k -> 0`` (a flat cap).
The inverse (Eq 10) is ``e = e_k + omega(e_k) (u - u_k) / 2 * expm1(y) / y`` with ``y = m_k (u - u_k) / 2``.
``u_k`` are the seed's integration constants ``c_k`` of Eq 12, chosen so that ``u`` is continuous and
``u(0) = 0``. Beyond the last pivot the acuity is held constant (the mapping stays monotone and finite for any
eccentricity below 90°; such points lie outside the LP buffer).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from data_schema.errors import UserError
from data_schema.geometry import DEG_PER_RAD, RAD_PER_DEG
from data_schema.ranges import check_range

from . import _kernels as K

#: Seed 001 §3.3: f(0°)=40, f(10°)=10, f(20°)=6, f(30°)=5, f(60°)=4 cpd.
DEFAULT_PIVOTS: tuple[tuple[float, float], ...] = ((0.0, 40.0), (10.0, 10.0), (20.0, 6.0), (30.0, 5.0),
                                                   (60.0, 4.0))

LINEAR = 0
NYQUIST = 1


def validate_pivots(pivots) -> tuple[tuple[float, float], ...]:
    try:
        pts = tuple((float(e), float(f)) for e, f in pivots)
    except (TypeError, ValueError):
        raise UserError("pivots is invalid: must be a sequence of (eccentricity_deg, cpd) pairs") from None
    if len(pts) < 2:
        raise UserError(f"pivots has {len(pts)} point(s): at least 2 (eccentricity, cpd) pairs are needed")
    if pts[0][0] != 0.0:
        raise UserError(f"pivots must start at eccentricity 0°, got {pts[0][0]:g}°")
    for e, f in pts:
        check_range("pivot eccentricity", e, 0.0, 90.0, low_open=False)
        check_range("pivot cpd", f, 0.0, None)
    for (e0, _), (e1, _) in zip(pts, pts[1:]):
        if not e1 > e0:
            raise UserError(f"pivots must be strictly increasing in eccentricity: {e0:g}° is followed by {e1:g}°")
    return pts


def scale_falloff(pivots, acuity_scale: float) -> tuple[tuple[float, float], ...]:
    """The pivots of the acuity curve with its eccentricity fall-off scaled by ``acuity_scale`` (``s``).

    Seed 001 Eq 2, ``omega(e) = m e + omega_0``, with every segment's MAR slope divided by ``s`` (Eq 12's
    ``m_k -> m_k / s``) and the foveal MAR ``omega_0`` kept:

        omega_s(e) = omega_0 + (omega(e) - omega_0) / s,   i.e. f_k' = 1 / (omega_0 + (1 / f_k - omega_0) / s)

    at every pivot ``(e_k, f_k)``. ``s = 1`` is the seed's curve, returned unchanged (bit for bit); ``s < 1``
    lowers the acuity, and with it ``du/de = 2 f`` (Eq 4), at every eccentricity beyond the fovea, the more the
    farther out: fewer LP columns and shorter ones, fewer shading points. Guenter et al. 2012 fitted this slope
    (1.32-1.65 arcmin per degree) from a study of foveation levels; ``s`` is the factor a threshold study varies.
    """
    pts = validate_pivots(pivots)
    s = check_range("acuity_scale", acuity_scale, 0.0, None)
    if s == 1.0:
        return pts
    w0 = 1.0 / pts[0][1]
    scaled = tuple((e, 1.0 / (w0 + (1.0 / f - w0) / s)) for e, f in pts)
    return validate_pivots(scaled)  # a rising curve (f_k > f_0) scaled far enough has no positive MAR: refused


@dataclass(frozen=True)
class Segment:
    e0: float      # start eccentricity (deg)
    e1: float      # end eccentricity (deg); the last segment extends to 90°
    kind: int      # LINEAR or NYQUIST
    omega0: float  # MAR at e0 (deg / cycle); LINEAR only
    slope: float   # dMAR/de; LINEAR only
    u0: float      # u(e0): the seed's integration constant c_k of Eq 12


class AcuityMapping:
    """The radial part of VaFR: acuity ``f(e)``, ``u(e)``, its inverse and ``du/de``.

    Parameters
    ----------
    pivots : sequence of (eccentricity_deg, cpd)
        Acuity at pivot eccentricities, strictly increasing from 0°, cpd > 0 (seed 001 §3.3 defaults).
    c_r : float
        Display constant of seed 001 Eq 3 (needed for the Nyquist cap and the tangent identities).
    cap_cpd : float or None
        Constant cap on the acuity (seed 001 Fig 3 headset curves).
    nyquist_cap : bool
        Cap the acuity at the display's local radial Nyquist rate.
    """

    def __init__(self, pivots=DEFAULT_PIVOTS, *, c_r: float, cap_cpd: float | None = None,
                 nyquist_cap: bool = False):
        self.pivots = validate_pivots(pivots)
        self.c_r = float(c_r)
        self.cap_cpd = None if cap_cpd is None else check_range("cap_cpd", cap_cpd, 0.0, None)
        self.nyquist_cap = bool(nyquist_cap)
        self.segments = self._build_segments()

    # -- construction -------------------------------------------------------------------------------------------
    def _nyquist_omega(self, e):
        c = np.cos(np.asarray(e, dtype=np.float64) * RAD_PER_DEG)
        return 2.0 * DEG_PER_RAD * self.c_r * c * c

    def _build_segments(self) -> list[Segment]:
        pts = list(self.pivots)
        pts.append((90.0, pts[-1][1]))  # hold the last acuity beyond the last pivot
        cap_omega = None if self.cap_cpd is None else 1.0 / self.cap_cpd
        pieces: list[tuple[float, float, int, float, float]] = []  # e0, e1, kind, omega(e0), slope
        for (ea, fa), (eb, fb) in zip(pts, pts[1:]):
            if ea >= 90.0:
                break
            wa, wb = 1.0 / fa, 1.0 / fb
            m = (wb - wa) / (eb - ea)

            def lin(e, ea=ea, wa=wa, m=m):
                return wa + m * (e - ea)

            # Candidate MAR curves; the capped MAR is their maximum. Find where the winner changes.
            cands = [("lin", lin)]
            if cap_omega is not None:
                cands.append(("cap", lambda e, c=cap_omega: c + 0.0 * e))
            if self.nyquist_cap:
                cands.append(("nyq", self._nyquist_omega))
            cuts = {ea, eb}
            grid = np.linspace(ea, eb, 513)
            for i in range(len(cands)):
                for j in range(i + 1, len(cands)):
                    g = cands[i][1](grid) - cands[j][1](grid)
                    for k in np.nonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0)[0]:
                        fi, fj = cands[i][1], cands[j][1]
                        cuts.add(brentq(lambda e, fi=fi, fj=fj: float(fi(e) - fj(e)), grid[k], grid[k + 1],
                                        xtol=1e-14, rtol=1e-15))
            cuts = sorted(cuts)
            for c0, c1 in zip(cuts, cuts[1:]):
                if c1 - c0 <= 1e-12:
                    continue
                mid = 0.5 * (c0 + c1)
                name, fn = max(cands, key=lambda c: float(c[1](mid)))
                if name == "lin":
                    pieces.append((c0, c1, LINEAR, float(lin(c0)), m))
                elif name == "cap":
                    pieces.append((c0, c1, LINEAR, cap_omega, 0.0))
                else:
                    pieces.append((c0, c1, NYQUIST, float("nan"), float("nan")))
        # Merge neighbours of the same kind and line, then integrate the constants u_k.
        merged: list[list] = []
        for p in pieces:
            if merged:
                q = merged[-1]
                same_line = (q[2] == LINEAR and p[2] == LINEAR and math.isclose(q[4], p[4], rel_tol=0, abs_tol=1e-15)
                             and math.isclose(q[3] + q[4] * (p[0] - q[0]), p[3], rel_tol=1e-12))
                if same_line or (q[2] == NYQUIST and p[2] == NYQUIST):
                    q[1] = p[1]
                    continue
            merged.append(list(p))
        # Pack the kernel vector, then integrate the constants u_k segment by segment (Eq 12's c_k).
        n = len(merged)
        P = np.zeros(3 + 6 * n)
        P[0], P[1], P[2] = self.c_r, 1.0, n
        for k, (e0, _e1, kind, w0, m) in enumerate(merged):
            P[3 + k], P[3 + 2 * n + k] = e0, kind
            P[3 + 3 * n + k], P[3 + 4 * n + k] = w0, m
            P[3 + 5 * n + k] = math.tan(e0 * RAD_PER_DEG)
        for k in range(n - 1):
            e1 = merged[k][1]
            P[3 + n + k + 1] = K.vafr_u_in_segment(k, e1, math.tan(e1 * RAD_PER_DEG), P)
        self._P = P
        return [Segment(e0, e1, kind, w0, m, float(P[3 + n + k]))
                for k, (e0, e1, kind, w0, m) in enumerate(merged)]

    # -- evaluation (compiled kernels, see _kernels.py) -------------------------------------------------------------
    def params_vector(self, delta: float = 1.0) -> np.ndarray:
        """The parameter vector ``P`` of the compiled VaFR kernels."""
        P = self._P.copy()
        P[1] = delta
        return P

    def omega(self, e_deg):
        """MAR (degrees per cycle) after the caps, seed 001 Eq 2 / Eq 12."""
        return 2.0 / self.du_de(e_deg)

    def acuity(self, e_deg):
        """Acuity ``f(e) = 1 / omega(e)`` in cycles per degree."""
        return 0.5 * self.du_de(e_deg)

    def u_of_e(self, e_deg):
        """Seed 001 Eq 5 / Eq 12: LP-buffer column of eccentricity ``e`` (degrees)."""
        e = np.asarray(e_deg, dtype=np.float64)
        return K.vafr_u_of_e_array(e.reshape(-1), self._P).reshape(e.shape)

    def e_of_u(self, u):
        """Seed 001 Eq 10 (segmented): eccentricity of LP column ``u``; returns ``(e_deg, tan_e)``."""
        u = np.asarray(u, dtype=np.float64)
        e, t = K.vafr_e_of_u_array(u.reshape(-1), self._P)
        return e.reshape(u.shape), t.reshape(u.shape)

    def du_de(self, e_deg):
        """Seed 001 Eq 4: ``du/de = 2 f(e)`` (LP pixels per degree)."""
        e = np.asarray(e_deg, dtype=np.float64)
        return K.vafr_du_de_array(e.reshape(-1), self._P).reshape(e.shape)
