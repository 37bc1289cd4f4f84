"""VaFR: the visual-acuity-consistent log-polar mapping (seed 001 §3.2-3.3, §9; Eq 2-12, 18-19).

Forward (screen -> LP buffer), for a point at distance ``r`` and polar angle ``theta`` from the gaze:

* eccentricity ``e = atan(c_r r)`` (Eq 3);
* column ``u = u(e)``, the integral of ``du/de = 2 f(e)`` (Eq 4-5, segmented Eq 12; see :mod:`.acuity`);
* row ``v = theta / 360° * l(e)`` (Eq 8, 19) with the shading height

      l(e) = Delta(e) * 2 pi r du/dr = Delta(e) * 360 sin(e) cos(e) du/de,

  which is Eq 9's ``360 sin(2e) / (m e + omega_0)`` on a linear-MAR segment. Eq 6 (equal tangential and radial
  screen-pixel lengths) gives it; ``Delta(e)`` is the tangential factor of Eq 19 (1 by default).

Inverse (Eq 10-11): ``e = e(u)``, ``r = tan(e) / c_r``, ``theta = 360° v / l(e)``.

The LP buffer is ``ceil(u(e_max)) x ceil(max l(e))`` for ``e <= e_max`` (§3.2.2). LP pixel ``(i, j)`` is
shaded when its centre lies in the semi-ellipse: ``i + 0.5 <= u(e_max)`` and ``j + 0.5 < l(e(i + 0.5))``.
With the default pivots this gives 899.8 x 1637.4 -> a 900 x 1638 buffer with 1,061,7xx shaded pixels; the
seed's printed 932 x 1800 (and e' ~ 45°) do not follow from its own pivots (the continuous integral of the
column heights is 1,061,734, matching the seed's Fig 4 count of 1,061,735). The number of shading points does
not depend on the display or the gaze, except with the display-dependent ``"auto"`` Nyquist cap.

Sin and cos of ``e`` are taken from ``t = tan e = c_r r`` (``sin e cos e = t / (1 + t^2)``), which is exact and
spares two transcendental calls per pixel.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy.optimize import minimize_scalar

from data_schema.errors import UserError
from data_schema.geometry import ViewingGeometry
from data_schema.ranges import check_range

from . import _kernels as K
from .acuity import DEFAULT_PIVOTS, AcuityMapping, scale_falloff
from .base import FoveationMapping

#: Seed 001 §3.3 / Fig 3 acuity curves; "auto" caps at the display's own radial Nyquist rate.
PRESETS: dict[str, dict] = {
    "default": {"pivots": DEFAULT_PIVOTS, "cap_cpd": None, "nyquist_cap": False},
    "vive_pro_eye": {"pivots": DEFAULT_PIVOTS, "cap_cpd": 9.0, "nyquist_cap": False},
    "pimax_crystal": {"pivots": DEFAULT_PIVOTS, "cap_cpd": 18.0, "nyquist_cap": False},
    "auto": {"pivots": DEFAULT_PIVOTS, "cap_cpd": None, "nyquist_cap": True},
}
#: Shading-load reductions the seed prints for its headset curves (§3.3).
SEED_PRESET_REDUCTION = {"vive_pro_eye": 0.20, "pimax_crystal": 0.08}


class VaFRMapping(FoveationMapping):
    """Visual-acuity-consistent log-polar mapping (seed 001 §3.2-3.3).

    Parameters
    ----------
    display : ViewingGeometry
    pivots : sequence of (eccentricity_deg, cpd), optional
        Acuity pivots (Eq 12); default f(0)=40, f(10)=10, f(20)=6, f(30)=5, f(60)=4 cpd.
    e_max : float, optional
        Largest eccentricity kept in the LP buffer (§3.2.2), default: the last pivot (60°). In (0, 90).
    preset : {"default", "vive_pro_eye", "pimax_crystal", "auto"}
        Acuity cap: none, 9 cpd, 18 cpd (seed Fig 3) or the display's Nyquist rate.
    cap_cpd : float, optional
        Explicit constant cap (overrides the preset's).
    tangential_factor : float or callable, optional
        ``Delta(e)`` of Eq 19 (> 0); a callable receives eccentricities in degrees (numpy array).
    acuity_scale : float, optional
        Scale ``s`` of the acuity fall-off (:func:`.acuity.scale_falloff`: Eq 2's MAR slope divided by ``s``,
        before the caps); 1 (default) is the seed's curve, below 1 shades fewer points in the periphery.
    """

    method = "vafr"
    _kernel = K.VAFR
    coverage_params = ("e_max", "preset", "acuity_scale")

    def __init__(self, display: ViewingGeometry, *, pivots=None, e_max: float | None = None,
                 preset: str = "default", cap_cpd: float | None = None,
                 tangential_factor: float | Callable = 1.0, acuity_scale: float = 1.0):
        super().__init__(display)
        if preset not in PRESETS:
            raise UserError(f"preset={preset!r} is invalid: allowed {', '.join(sorted(PRESETS))}")
        spec = PRESETS[preset]
        self.preset = preset
        pivots = scale_falloff(spec["pivots"] if pivots is None else pivots, acuity_scale)
        self.acuity_scale = float(acuity_scale)
        cap = spec["cap_cpd"] if cap_cpd is None else cap_cpd
        self.acuity = AcuityMapping(pivots, c_r=display.c_r, cap_cpd=cap, nyquist_cap=spec["nyquist_cap"])
        last = self.acuity.pivots[-1][0]
        self.e_max = check_range("e_max", last if e_max is None else e_max, 0.0, 90.0)
        if callable(tangential_factor):
            self._delta = tangential_factor
            self._delta_const = None
        else:
            d = check_range("tangential_factor", tangential_factor, 0.0, None)
            self._delta = lambda e, d=d: np.full(np.shape(e), d)
            self._delta_const = d
        self._tangential_factor = tangential_factor
        self._P_unit = self.acuity.params_vector(1.0)
        # The compiled kernels apply a constant Delta themselves; a callable one is applied around them.
        self._P = self.acuity.params_vector(self._delta_const or 1.0)
        self.u_max = float(self.acuity.u_of_e(self.e_max))
        if not self.u_max >= 0.5:
            # LP column 0 is shaded when its centre 0.5 lies within u(e_max) (the semi-ellipse, §3.2.2); below,
            # the buffer has no column (0 x 0) and nothing is shaded. u depends on the acuity cap (the
            # display's Nyquist rate with "auto"), so the smallest e_max does too.
            e_min = math.ceil(float(self.acuity.e_of_u(0.5)[0]) * 1e5) / 1e5  # rounded up: the bound holds
            raise UserError(
                f"e_max={self.e_max:g} is out of range for this display with preset {preset!r}: it leaves no LP "
                f"column to shade (u(e_max) = {self.u_max:.3g} < 0.5 LP pixel, seed 001 Eq 4-5); allowed "
                f"e_max >= {e_min:g}")
        self.l_max, self.e_l_max = self._max_shading_height()
        self._mask = None

    def params(self) -> dict:
        tf = self._tangential_factor
        return {"preset": self.preset, "acuity_scale": self.acuity_scale, "pivots": [list(p) for p in self.acuity.pivots], "e_max": self.e_max,
                "cap_cpd": self.acuity.cap_cpd, "nyquist_cap": self.acuity.nyquist_cap,
                "tangential_factor": tf if not callable(tf) else getattr(tf, "__name__", "callable")}

    # -- model -------------------------------------------------------------------------------------------------
    def delta(self, e_deg):
        d = np.asarray(self._delta(np.asarray(e_deg, dtype=np.float64)), dtype=np.float64)
        if np.any(~np.isfinite(d)) or np.any(d <= 0):
            raise UserError("tangential_factor must return finite values > 0")
        return d

    def shading_height(self, e_deg):
        """Seed 001 Eq 9 / Eq 19: ``l(e) = Delta(e) 360 sin(e) cos(e) du/de`` LP pixels around the circle."""
        e = np.asarray(e_deg, dtype=np.float64)
        l = K.vafr_height_array(e.reshape(-1), self._P_unit).reshape(e.shape)
        return l * (self._delta_const if self._delta_const is not None else self.delta(e))

    def _max_shading_height(self):
        e = np.linspace(0.0, self.e_max, 4001)
        l = self.shading_height(e)
        k = int(np.argmax(l))
        lo, hi = e[max(k - 1, 0)], e[min(k + 1, e.size - 1)]
        if hi > lo:
            res = minimize_scalar(lambda x: -float(self.shading_height(x)), bounds=(lo, hi), method="bounded",
                                  options={"xatol": 1e-10})
            if -res.fun > l[k]:
                return float(-res.fun), float(res.x)
        return float(l[k]), float(e[k])

    @property
    def lp_shape(self) -> tuple[int, int]:
        return (int(math.ceil(self.u_max - 1e-9)), int(math.ceil(self.l_max - 1e-9)))

    # -- mapping -----------------------------------------------------------------------------------------------
    def _params_vector(self) -> np.ndarray:
        return self._P

    def forward(self, x, y):
        u, v = super().forward(x, y)
        if self._delta_const is None:  # a callable Delta(e) scales the rows after the compiled kernel
            r = np.hypot(np.asarray(x, dtype=np.float64) - self.display.gaze_x,
                         np.asarray(y, dtype=np.float64) - self.display.gaze_y)
            v = v * self.delta(self.display.eccentricity(r))
        return u, v

    def inverse(self, u, v):
        if self._delta_const is None:
            v = np.asarray(v, dtype=np.float64) / self.delta(self.acuity.e_of_u(u)[0])
        return super().inverse(u, v)

    def forward_screen(self):
        u, v = super().forward_screen()
        if self._delta_const is None:
            x, y = self.display.pixel_centres()
            v *= self.delta(self.display.eccentricity(np.hypot(x - self.display.gaze_x, y - self.display.gaze_y)))
        return u, v

    def column_heights(self) -> np.ndarray:
        """Shaded pixels in each LP column (the discrete semi-ellipse)."""
        w, h = self.lp_shape
        uc = np.arange(w, dtype=np.float64) + 0.5
        l = self.shading_height(self.acuity.e_of_u(uc)[0])
        counts = np.clip(np.ceil(l - 0.5), 0, h).astype(np.int64)
        counts[uc > self.u_max] = 0
        return counts

    def shaded_mask(self) -> np.ndarray:
        if self._mask is None:
            w, h = self.lp_shape
            self._mask = np.arange(h)[:, None] < self.column_heights()[None, :]
            self._mask.setflags(write=False)
        return self._mask

    @property
    def shading_points(self) -> int:
        return int(self.column_heights().sum())

    def continuous_shading_points(self) -> float:
        """``∫ l(e) du`` over ``[0, u(e_max)]``: the area of the semi-ellipse (seed Fig 4's count)."""
        from scipy.integrate import quad

        total = 0.0
        bounds = sorted({0.0, self.e_max, *[s.e0 for s in self.acuity.segments if s.e0 < self.e_max]})
        for a, b in zip(bounds, bounds[1:]):
            total += quad(lambda e: float(self.shading_height(e) * self.acuity.du_de(e)), a, b,
                          epsabs=1e-6, epsrel=1e-12, limit=200)[0]
        return total

    def _column_centres(self) -> np.ndarray:
        return np.arange(int(np.count_nonzero(np.arange(self.lp_shape[0]) + 0.5 <= self.u_max))) + 0.5

    def _radial_du_de(self, e_deg):
        return self.acuity.du_de(e_deg)

    def _tangential_rate(self, e_deg):
        # l(e) / (2 * 360 sin e cos e) = Delta(e) * f(e): Eq 19 with the seed's Eq 20 convention.
        return self.delta(e_deg) * 0.5 * self.acuity.du_de(e_deg)
