"""Display geometry: pixels, gaze and the eccentricity <-> radius conversion of seed 001 Eq 3.

Screen coordinates are continuous pixel coordinates: pixel ``(i, j)`` covers ``[i, i+1) x [j, j+1)`` and its
centre is ``(i + 0.5, j + 0.5)``; ``y`` grows downwards, as in an image array. The gaze point uses the same
coordinates and may lie anywhere, also outside the display.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

RAD_PER_DEG = math.pi / 180.0
DEG_PER_RAD = 180.0 / math.pi


def check_finite(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name}={value!r} is invalid: must be a finite number")
    return value


def check_range(name: str, value: float, low: float | None, high: float | None, *,
                low_open: bool = True, high_open: bool = True) -> float:
    """Return ``value`` as float or raise ValueError naming the parameter and its allowed range."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}={value!r} is invalid: must be a number") from None
    lo_ok = low is None or (value > low if low_open else value >= low)
    hi_ok = high is None or (value < high if high_open else value <= high)
    if math.isnan(value) or not (lo_ok and hi_ok):
        lo = "(-inf" if low is None else (f"({low:g}" if low_open else f"[{low:g}")
        hi = "inf)" if high is None else (f"{high:g})" if high_open else f"{high:g}]")
        raise ValueError(f"{name}={value:g} is out of range: allowed {lo}, {hi}")
    return value


@dataclass(frozen=True)
class DisplayGeometry:
    """A flat display seen through a pinhole camera of vertical field of view ``fov_y_deg``.

    ``c_r`` is the seed's constant of Eq 3: film height over focal length, divided by the display height in
    pixels, so that ``r = tan(e) / c_r`` is the distance in pixels from the gaze point of a point at
    eccentricity ``e`` (the gaze is taken to lie on the optical axis, as in the seed).
    """

    width: int
    height: int
    fov_y_deg: float
    gaze_x: float
    gaze_y: float

    @classmethod
    def create(cls, width, height, fov_y_deg, gaze=None) -> "DisplayGeometry":
        for name, value in (("width", width), ("height", height)):
            if isinstance(value, bool) or not float(value).is_integer() or value < 1:
                raise ValueError(f"{name}={value!r} is out of range: must be a whole number of pixels >= 1")
        fov = check_range("fov_y_deg", fov_y_deg, 0.0, 180.0)
        if gaze is None:
            gx, gy = width / 2.0, height / 2.0
        else:
            try:
                gx, gy = (float(g) for g in gaze)
            except (TypeError, ValueError):
                raise ValueError(f"gaze={gaze!r} is invalid: must be a pair (x, y) of pixel coordinates") from None
            gx, gy = check_finite("gaze x", gx), check_finite("gaze y", gy)
        return cls(int(width), int(height), fov, gx, gy)

    @property
    def gaze(self) -> tuple[float, float]:
        return (self.gaze_x, self.gaze_y)

    @property
    def c_r(self) -> float:
        """Seed 001 Eq 3: ``c_r = (film height / focal length) / H = 2 tan(fov_y / 2) / H``."""
        return 2.0 * math.tan(0.5 * self.fov_y_deg * RAD_PER_DEG) / self.height

    @property
    def pixels(self) -> int:
        return self.width * self.height

    def radius(self, e_deg):
        """Pixel distance from the gaze of eccentricity ``e_deg`` (seed 001 Eq 3, ``r = tan e / c_r``)."""
        return np.tan(np.asarray(e_deg, dtype=np.float64) * RAD_PER_DEG) / self.c_r

    def eccentricity(self, r_px):
        """Eccentricity in degrees of a point ``r_px`` pixels from the gaze (``e = atan(c_r r)``)."""
        return np.arctan(self.c_r * np.asarray(r_px, dtype=np.float64)) * DEG_PER_RAD

    def dr_de(self, e_deg):
        """Radial pixels per degree at eccentricity ``e``: the inverse of seed 001 Eq 7."""
        c = np.cos(np.asarray(e_deg, dtype=np.float64) * RAD_PER_DEG)
        return RAD_PER_DEG / (self.c_r * c * c)

    def corner_distance(self) -> float:
        """Largest distance in pixels from the gaze to a corner of the display."""
        xs = (0.0, float(self.width))
        ys = (0.0, float(self.height))
        return max(math.hypot(x - self.gaze_x, y - self.gaze_y) for x in xs for y in ys)

    def max_eccentricity(self) -> float:
        return float(self.eccentricity(self.corner_distance()))

    def contains(self, x, y):
        """Boolean mask of the points that fall on the display."""
        x = np.asarray(x)
        y = np.asarray(y)
        return (x >= 0) & (x < self.width) & (y >= 0) & (y < self.height)

    def pixel_centres(self):
        """Coordinates of every pixel centre, shape ``(height, width)`` each."""
        x = np.arange(self.width, dtype=np.float64) + 0.5
        y = np.arange(self.height, dtype=np.float64) + 0.5
        return np.meshgrid(x, y)
