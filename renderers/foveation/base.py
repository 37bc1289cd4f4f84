"""Common interface of the log-polar foveation mappings (VaFR, LMFR, LaFR).

Conventions shared by every mapping:

* Screen coordinates ``(x, y)`` are continuous pixel coordinates (see :mod:`.geometry`).
* LP-buffer coordinates ``(u, v)`` are continuous too: ``u`` runs along the buffer's width (eccentricity),
  ``v`` along its height (polar angle); LP pixel ``(i, j)`` has centre ``(i + 0.5, j + 0.5)``.
* The polar angle is ``theta = atan2(y - y0, x - x0)`` taken in ``[0, 2 pi)`` (seed 001 Eq 1's indicator).
* ``shaded_mask()`` has shape ``(lp_height, lp_width)`` (rows are ``v``), like an image.
* Shading rates are in cycles per degree, one cycle being two LP pixels (seed 001 Eq 13).
"""

from __future__ import annotations

import abc
import math

import numpy as np

from data_schema.errors import UserError
from data_schema.geometry import ViewingGeometry

from . import _kernels as K

TWO_PI = 2.0 * math.pi
#: LP pixels inverted per block when counting the on-screen ones: bounds temporary memory.
CHUNK = 1 << 20


class FoveationMapping(abc.ABC):
    """Screen <-> log-polar buffer mapping of one foveated-rendering method."""

    method: str = ""

    def __init__(self, display: ViewingGeometry):
        self.display = display

    # -- to implement -------------------------------------------------------------------------------------------
    #: Kernel id in :mod:`._kernels` (VAFR, LMFR or LAFR).
    _kernel: int = -1

    @property
    @abc.abstractmethod
    def lp_shape(self) -> tuple[int, int]:
        """LP buffer ``(width, height)`` in pixels."""

    @abc.abstractmethod
    def _params_vector(self) -> np.ndarray:
        """The kernel parameter vector ``P`` (see :mod:`._kernels`)."""

    @abc.abstractmethod
    def shaded_mask(self) -> np.ndarray:
        """Boolean array ``(lp_height, lp_width)`` of the LP pixels that are shaded."""

    @abc.abstractmethod
    def _radial_du_de(self, e_deg):
        """``du/de`` along a ray from the gaze, LP pixels per degree."""

    @abc.abstractmethod
    def _tangential_rate(self, e_deg):
        """Tangential shading rate in cpd (seed 001 Eq 19-20 convention)."""

    def params(self) -> dict:
        """The parameters that define this mapping (for records and cache keys)."""
        return {}

    #: The renderer parameters :meth:`check_coverage` names when it refuses.
    coverage_params: tuple[str, ...] = ()

    def _column_centres(self) -> np.ndarray:
        """``u`` of the centres of the LP columns that hold shaded pixels."""
        return np.arange(self.lp_shape[0]) + 0.5

    def check_coverage(self) -> None:
        """Refuse (one line) parameters that leave part of the display's radius without samples.

        The LP columns are rings around the gaze at ``r(u)``, the inverse mapping at the column centres (seed
        001 Eq 10-11; Eq 1, 14-15); the screen between two rings is interpolated from them and beyond the outer
        one clamped to it. No gap between neighbouring rings (the gaze, and the farthest corner at ``R``,
        included) may exceed ``R / 2``: else more than half of every ray from the gaze is reconstructed from one
        ring of samples (VaFR ``e_max`` far below the display's corners; LMFR ``alpha -> 0`` puts every ring on
        the gaze itself, ``alpha`` large empties the fovea; LaFR ``beta -> 0`` folds the periphery onto its
        foveal boundary, ``beta`` large onto the farthest corner). Called with the gaze at the display's centre,
        so that the answer does not depend on where the observer looks (live trials move the gaze).
        """
        u = self._column_centres()
        gx, gy = self.display.gaze
        x, y = self.inverse(u, np.full(u.shape, 0.5))
        R = self.display.corner_distance()
        # rings beyond the farthest corner (VaFR's columns out to e_max) sample nothing on the display
        rings = np.sort(np.concatenate([[0.0], np.minimum(np.hypot(x - gx, y - gy), R), [R]]))
        gap = float(np.max(np.diff(rings)))
        if not gap <= 0.5 * R:
            p = self.params()
            names = ", ".join(f"{k}={p[k]:g}" if isinstance(p[k], float) else f"{k}={p[k]!r}"
                              for k in self.coverage_params)
            raise UserError(f"{names} are out of range on this display: {gap:.3g} of the {R:.3g} px from the "
                            "centre to the farthest corner lie between two neighbouring LP columns or beyond the "
                            "last (more than half: reconstructed from one ring of samples)")

    # -- shared implementation ----------------------------------------------------------------------------------
    def _map(self, direction, a, b):
        a = np.asarray(a, dtype=np.float64)
        b = np.asarray(b, dtype=np.float64)
        a, b = np.broadcast_arrays(a, b)
        fa = np.ascontiguousarray(a).reshape(-1)
        fb = np.ascontiguousarray(b).reshape(-1)
        out_a = np.empty(fa.shape, dtype=np.float64)
        out_b = np.empty(fb.shape, dtype=np.float64)
        gx, gy = self.display.gaze
        K.map_points(self._kernel, direction, fa, fb, self._params_vector(), gx, gy, out_a, out_b)
        return out_a.reshape(a.shape), out_b.reshape(a.shape)

    def forward(self, x, y):
        """Screen position ``(x, y)`` -> LP-buffer position ``(u, v)``; vectorised, float64."""
        return self._map(K.FORWARD, x, y)

    def inverse(self, u, v):
        """LP-buffer position ``(u, v)`` -> screen position ``(x, y)``; vectorised, float64."""
        return self._map(K.INVERSE, u, v)

    def forward_screen(self):
        """Forward map of every pixel centre: ``(u, v)``, each of shape ``(height, width)``.

        Builds no coordinate arrays: peak memory is the two float64 outputs.
        """
        W, H = self.display.width, self.display.height
        u = np.empty((H, W), dtype=np.float64)
        v = np.empty((H, W), dtype=np.float64)
        K.map_screen(self._kernel, W, H, self.display.gaze_x, self.display.gaze_y, self._params_vector(), u, v)
        return u, v

    def shaded_coordinates(self):
        """``(u, v)`` centres of the shaded LP pixels, in row-major order of the mask."""
        jj, ii = np.nonzero(self.shaded_mask())
        return ii + 0.5, jj + 0.5

    @property
    def shading_points(self) -> int:
        """Number of shaded LP pixels."""
        return int(np.count_nonzero(self.shaded_mask()))

    @property
    def shading_points_on_screen(self) -> int:
        """Shaded LP pixels whose inverse mapping falls inside the display."""
        mask = self.shaded_mask()
        total = 0
        # Column blocks keep the temporaries small even for the largest LP buffers.
        width = mask.shape[1]
        step = max(1, CHUNK // max(1, mask.shape[0]))
        for c0 in range(0, width, step):
            jj, ii = np.nonzero(mask[:, c0:c0 + step])
            x, y = self.inverse(ii + c0 + 0.5, jj + 0.5)
            total += int(np.count_nonzero(self.display.contains(x, y)))
        return total

    def shading_rate(self, e_deg, direction: str = "radial"):
        """Shading rate in cycles per degree at eccentricity ``e_deg`` (seed 001 Eq 13, 16-20).

        ``radial`` is ``0.5 du/de`` along a ray from the gaze (Eq 13). ``tangential`` follows the seed's
        Eq 19-20 convention: LP pixels around the circle of eccentricity ``e`` over its length measured with the
        radial conversion ``2 pi r de/dr`` (so that VaFR's tangential rate equals its radial rate, Eq 6).
        """
        e = np.asarray(e_deg, dtype=np.float64)
        if np.any(~np.isfinite(e)) or np.any(e < 0) or np.any(e >= 90):
            raise UserError("e_deg is out of range: eccentricities must lie in [0, 90) degrees")
        if direction == "radial":
            return 0.5 * self._radial_du_de(e)
        if direction == "tangential":
            return self._tangential_rate(e)
        raise UserError(f"direction={direction!r} is invalid: allowed 'radial' or 'tangential'")

    def describe(self) -> dict:
        w, h = self.lp_shape
        return {"method": self.method, "width": self.display.width, "height": self.display.height,
                "fov_y_deg": self.display.fov_y_deg, "gaze": list(self.display.gaze), "lp_width": w,
                "lp_height": h, **self.params()}
