"""Kernel log-polar mappings: LMFR (Meng et al.) and LaFR (Shi et al.), as analysed in seed 001 §3.1, §4.

Both use an LP buffer of ``w x h = round(W / delta) x round(H / delta)`` pixels, all of them shaded, and the
normalised log distance of seed 001 Eq 1 / Eq 14

    z = ln(1 + r) / ln(1 + R),       R = largest distance in pixels from the gaze to a display corner.

Repair of Eq 1 (documented choice): the seed writes ``ln r / L`` with ``L = ln R``. That is ``-inf`` at the
gaze and negative inside ``r < 1`` px, where ``z^alpha`` with a non-integer exponent is undefined, and it
collapses the unit disc so that no inverse exists there. ``ln(1 + r)`` is a bijection of ``[0, R]`` onto
``[0, 1]`` and differs from ``ln r`` by less than ``1 / r`` (< 0.2 % of ``z`` beyond 10 px), so every curve of
the seed is reproduced while the mapping stays invertible and finite everywhere.

The angle is ``v = h theta / (2 pi)`` (Eq 1), so the tangential shading rate is the seed's Eq 20:
``h / (720 sin e cos e)`` cycles per degree.
"""

from __future__ import annotations

import math

import numpy as np

from data_schema.errors import UserError
from data_schema.geometry import RAD_PER_DEG, ViewingGeometry
from data_schema.ranges import check_range

from . import _kernels as K
from .base import FoveationMapping

#: Fewest LP rows of LMFR and LaFR. Rows are the angles 2 pi (j + 0.5) / h (Eq 1) and a gaze in a corner of
#: the display sees one quadrant of it: with h >= 4 every quadrant holds a row. (Not more: the simulated
#: observer's 64 x 36 thumbnails of a coarse catch condition, LaFR delta = 8, have 4 rows.)
MIN_LP_ROWS = 4
#: LaFR's foveal boundary (seed 001 Eq 15, Fig 6).
LAFR_FOVEAL_BOUNDARY_DEG = 4.89


class _KernelMapping(FoveationMapping):
    """Shared parts of LMFR and LaFR: the LP buffer, ``z(r)`` and the tangential rate."""

    def __init__(self, display: ViewingGeometry, delta: float):
        super().__init__(display)
        self.delta = check_range("delta", delta, 1.0, None)
        self.lp_width = max(1, int(round(display.width / self.delta)))
        self.lp_height = max(1, int(round(display.height / self.delta)))
        if self.lp_height < MIN_LP_ROWS:
            raise UserError(
                f"delta={self.delta:g} is out of range on this display: the LP buffer has {self.lp_height} rows "
                f"(round(H / delta), seed 001 Eq 1), fewer than {MIN_LP_ROWS}, so a quadrant around the gaze may "
                f"hold no row of samples; allowed delta <= {display.height / (MIN_LP_ROWS - 0.5):.4g}")
        self.R = display.corner_distance()
        self.Lp = math.log1p(self.R)

    @property
    def lp_shape(self) -> tuple[int, int]:
        return (self.lp_width, self.lp_height)

    @property
    def nominal_shading_points(self) -> float:
        """``W H / delta^2``: the count the seed prints in Table 1 (the real buffer is rounded to pixels)."""
        return self.display.pixels / self.delta ** 2

    def shaded_mask(self) -> np.ndarray:
        return np.ones((self.lp_height, self.lp_width), dtype=bool)

    @property
    def shading_points(self) -> int:
        return self.lp_width * self.lp_height

    def z_of_e(self, e_deg):
        """Normalised log distance ``z`` at eccentricity ``e`` (seed 001 §4.1, with the ``ln(1 + r)`` repair)."""
        return np.log1p(self.display.radius(e_deg)) / self.Lp

    def dz_de(self, e_deg):
        """``dz/de = dr/de / ((1 + r) Lp)``; with Eq 7, ``dr/de = (pi/180) / (c_r cos^2 e)``."""
        return self.display.dr_de(e_deg) / ((1.0 + self.display.radius(e_deg)) * self.Lp)

    def _tangential_rate(self, e_deg):
        # Seed 001 Eq 20: (h) / (720 sin e cos e); infinite at the gaze itself.
        s = np.sin(2.0 * e_deg * RAD_PER_DEG)
        with np.errstate(divide="ignore"):
            return np.where(s > 0, self.lp_height / (360.0 * np.where(s > 0, s, 1.0)), np.inf)


class LMFRMapping(_KernelMapping):
    """LMFR / kernel foveated rendering: ``u = w z^alpha``, ``v = h theta / 2 pi`` (seed 001 Eq 1, 14).

    This is the original authors' convention (the LMFR demo: screen -> LP ``u = (ln r / L)^alpha``, LP -> screen
    ``r = exp(L u^(1/alpha))``); the inverted kernel ``u = z^(1/alpha)`` of some ports is a bug that puts half
    the LP columns within 2 px of the gaze. Seed 001 writes the kernel as ``K(z) = z^alpha`` with ``alpha = 4``
    (Eq 14). ``alpha`` here is that exponent (> 0); ``delta`` (> 1) is the buffer reduction, ``delta^2`` screen
    pixels per LP pixel.

    Radial shading rate (Eq 16 with the ``ln(1 + r)`` repair): ``0.5 w alpha z^(alpha-1) dz/de``.
    """

    method = "lmfr"
    _kernel = K.LMFR
    coverage_params = ("delta", "alpha")

    def __init__(self, display: ViewingGeometry, *, delta: float = 1.8, alpha: float = 4.0):
        super().__init__(display, delta)
        self.alpha = check_range("alpha", alpha, 0.0, None)
        self._P = np.array([self.lp_width, self.lp_height, self.Lp, self.alpha], dtype=np.float64)

    def params(self) -> dict:
        return {"delta": self.delta, "alpha": self.alpha}

    def _params_vector(self):
        return self._P

    def _radial_du_de(self, e_deg):
        z = self.z_of_e(e_deg)
        with np.errstate(divide="ignore"):
            dudz = self.lp_width * self.alpha * np.power(z, self.alpha - 1.0)
        return dudz * self.dz_de(e_deg)


class LaFRMapping(_KernelMapping):
    """LaFR: locomotion-aware foveated rendering's two-part kernel (seed 001 Eq 15, 17).

    With ``Z = z(4.89°)`` (the foveal boundary ``Z_ef``), ``Fa = 1 - log_Z(alpha Z^(1-a) / (1 - a))`` and
    ``U = (Z (1 - Fa))^(1/Fa)`` (``U_ef``), the normalised column ``u_n = u / w`` is

    * fovea, ``z <= Z``: ``u_n = (z (1 - Fa))^(1/Fa)`` (Eq 15, first line; the inverse of the LaFR kernel
      ``K_f(u) = u^Fa / (1 - Fa)``);
    * periphery, ``Z < z <= 1``: ``u_n = g^(beta/0.7) (1 - U) + U`` with ``g = (2 arccos X - pi) / pi``.

    Repairs (each tested):

    1. Eq 15 prints ``X = Za = 1 / (z / Z - 1)``. That is > 1 for ``Z < z < 2Z`` (arccos undefined) and makes
       ``g`` negative, so the mapping is not defined. We use ``X = (Z / z - 1) / (1 - Z)`` (i.e.
       ``(1/z - 1/Z) / (1/Z - 1)``), the Möbius form that goes from 0 at ``z = Z`` to -1 at the farthest corner
       ``z = 1``: then ``g`` rises from 0 to 1, ``u_n`` is continuous at the boundary (``u_n(Z) = U``), reaches
       1 at the corner and is strictly increasing.
    2. Eq 17 (second line) is then the derivative up to its printed sign and constant: ours is
       ``du_n/dz = (1 - U) p g^(p-1) * 2 Z / (pi (1 - Z) z^2 sqrt(1 - X^2))`` with ``p = beta / 0.7`` (the seed's
       form drops the ``p g^(p-1)`` factor, exact for the paper's ``beta = 0.7``, and is negative as printed).
       The first line of Eq 17 is the derivative of the first line of Eq 15 as printed.
    3. ``Fa`` must lie in (0, 1) for the foveal part to exist; that holds iff ``alpha Z^(1-a) < 1 - a``, which
       needs ``a < 1``. Seed 001 says LaFR's ``a`` is LMFR's ``alpha``; in LaFR's convention the kernel runs LP ->
       screen, so LMFR's ``u = z^4`` corresponds to ``a = 1/4``, our default. Other values are checked.
    4. Beyond the farthest corner (``z > 1``, only off-screen points) the map continues linearly with the mean
       peripheral slope, so forward and inverse stay finite and monotone everywhere.

    Parameters: ``delta`` > 1 (paper 1.8, 2.2; tuned 8), ``alpha`` in (0, 1) (paper 0.85; tuned 0.78),
    ``beta`` > 0 (paper 0.7; tuned 0.9), ``a`` in (0, 1) (default 0.25).
    """

    method = "lafr"
    _kernel = K.LAFR
    coverage_params = ("delta", "alpha", "beta", "a")

    def __init__(self, display: ViewingGeometry, *, delta: float = 1.8, alpha: float = 0.85, beta: float = 0.7,
                 a: float = 0.25, foveal_boundary_deg: float = LAFR_FOVEAL_BOUNDARY_DEG):
        super().__init__(display, delta)
        self.alpha = check_range("alpha", alpha, 0.0, 1.0)
        self.beta = check_range("beta", beta, 0.0, None)
        self.a = check_range("a", a, 0.0, 1.0)
        self.foveal_boundary_deg = check_range("foveal_boundary_deg", foveal_boundary_deg, 0.0, 90.0)
        r_ef = float(display.radius(self.foveal_boundary_deg))
        if not r_ef < self.R:
            raise UserError(
                f"foveal_boundary_deg={self.foveal_boundary_deg:g} is out of range for this display: it lies "
                f"{r_ef:.1f} px from the gaze, beyond the farthest corner ({self.R:.1f} px); LaFR needs a larger "
                "display or field of view")
        self.Z_ef = math.log1p(r_ef) / self.Lp
        q = self.alpha * self.Z_ef ** (1.0 - self.a) / (1.0 - self.a)
        # Fa = 1 - ln q / ln Z_ef lies in (0, 1) iff Z_ef < q < 1 (ln Z_ef < 0): q >= 1 gives Fa >= 1, and
        # q <= Z_ef gives Fa <= 0, where the foveal kernel (z (1 - Fa))^(1/Fa) is undefined and no LP pixel maps
        # onto the display. In alpha: (1 - a) Z_ef^a < alpha < (1 - a) / Z_ef^(1 - a).
        lo, hi = (1.0 - self.a) * self.Z_ef ** self.a, (1.0 - self.a) / self.Z_ef ** (1.0 - self.a)
        self.Fa = 1.0 - math.log(q) / math.log(self.Z_ef) if q > 0.0 else -math.inf
        if not (self.Z_ef < q < 1.0 and 0.0 < self.Fa < 1.0):
            raise UserError(
                f"alpha={self.alpha:g} is out of range with a={self.a:g} on this display: LaFR's Fa must lie in "
                f"(0, 1), which needs (1 - a) Z_ef^a < alpha < (1 - a) / Z_ef^(1 - a), here ({lo:.4g}, {hi:.4g}) "
                f"(Z_ef = {self.Z_ef:.4f}, seed 001 Eq 15)")
        self.U_ef = (self.Z_ef * (1.0 - self.Fa)) ** (1.0 / self.Fa)
        self.p = self.beta / 0.7
        self.ext_slope = (1.0 - self.U_ef) / (1.0 - self.Z_ef)
        self._P = np.array([self.lp_width, self.lp_height, self.Lp, self.Fa, self.U_ef, self.Z_ef, self.p,
                            self.ext_slope], dtype=np.float64)

    def params(self) -> dict:
        return {"delta": self.delta, "alpha": self.alpha, "beta": self.beta, "a": self.a,
                "foveal_boundary_deg": self.foveal_boundary_deg}

    def _params_vector(self):
        return self._P

    def u_normalised(self, z):
        """``u_n(z)``, the repaired Eq 15."""
        z = np.asarray(z, dtype=np.float64)
        return K.lafr_un_of_z_array(z.reshape(-1), self._P).reshape(z.shape)

    def du_dz(self, z):
        """Derivative of the repaired Eq 15 (normalised), i.e. the repaired Eq 17 without ``0.5 w dz/de``."""
        z = np.asarray(z, dtype=np.float64)
        Fa, U, Z, p = self.Fa, self.U_ef, self.Z_ef, self.p
        out = np.full(z.shape, self.ext_slope)
        inner = z <= Z
        zi = z[inner]
        with np.errstate(divide="ignore", invalid="ignore"):
            out[inner] = (1.0 - Fa) / Fa * np.power(zi * (1.0 - Fa), (1.0 - Fa) / Fa)
            outer = (z > Z) & (z <= 1.0)
            zo = z[outer]
            X = np.clip((Z / zo - 1.0) / (1.0 - Z), -1.0, 0.0)
            g = (2.0 * np.arccos(X) - math.pi) / math.pi
            dg = 2.0 * Z / (math.pi * (1.0 - Z) * zo * zo * np.sqrt(1.0 - X * X))
            out[outer] = (1.0 - U) * p * np.power(g, p - 1.0) * dg  # g = 0 gives 0, 1 or inf by p
        return out

    def _radial_du_de(self, e_deg):
        return self.lp_width * self.du_dz(self.z_of_e(e_deg)) * self.dz_de(e_deg)


def seed_radial_rate_lmfr(display: ViewingGeometry, e_deg, *, delta: float = 1.8, alpha: float = 4.0):
    """Seed 001 Eq 16 exactly as printed (``z = ln(tan e / c_r) / ln L``), for comparison plots; e > 0."""
    e = np.asarray(e_deg, dtype=np.float64)
    w = display.width / delta
    L = math.log(display.corner_distance())
    z = np.log(np.tan(e * RAD_PER_DEG) / display.c_r) / L
    lw = (1.0 / L) * w * math.pi / (180.0 * np.sin(e * RAD_PER_DEG) * np.cos(e * RAD_PER_DEG))
    return 0.5 * alpha * np.power(np.clip(z, 0, None), alpha - 1.0) * lw


