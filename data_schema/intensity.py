"""The intensity axis of a varied renderer parameter: the one mapping between a parameter's value and the
intensity on which adaptive procedures place trials and psychometric functions are fitted.

Procedures (``studyapp.runner.adaptive``) and fits (``analysis.thresholds``) work on an *intensity* ``x`` in
which detection of the foveation grows. A parameter value ``v`` maps onto it by the domain's ``scale`` and the
direction in which foveation gets ``stronger`` (the renderer's declaration,
``renderers.registry.foveation_strength``)::

    scale log:     x = log10(v)  (stronger: higher)     x = -log10(v)  (stronger: lower, e.g. VaFR acuity_scale)
    scale linear:  x = v         (stronger: higher)     x = -v         (stronger: lower)

so a log domain is measured in log10 units of the parameter; the inverse is ``v = 10^(±x)`` or ``v = ±x``. It
lives here because both the runner and analysis use it and analysis may import only ``data_schema``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SCALES = ("log", "linear")
DIRECTIONS = ("higher", "lower")


@dataclass(frozen=True)
class Axis:
    """How a varied parameter's values map onto the intensity axis (module docstring for the formula).

    Parameters
    ----------
    scale : {"log", "linear"}
        ``log``: ``x = log10(v)`` (values must be > 0); ``linear``: ``x = v``.
    stronger : {"higher", "lower"}
        ``higher``: a higher value is stronger foveation (detection grows with it); ``lower``: a lower value is
        (VaFR's acuity scale, samples per pixel), and the axis is negated.
    bounds : tuple of float, optional
        The domain's ends (parameter values): the procedure's ladder, psignifit's stimulus range. Default: none
        (the levels tested stand in, :meth:`x_range`).

    Notes
    -----
    A scalar maps through :mod:`math` and comes back as a ``float``; arrays map through numpy. The scalar path
    is what procedures use, so an intensity recomputed from a stored level is bit-identical across versions
    (an exact resume replays the stored levels).
    """

    scale: str = "log"
    stronger: str = "higher"
    bounds: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if self.scale not in SCALES:
            raise ValueError(f"axis scale {self.scale!r}: expected log or linear")
        if self.stronger not in DIRECTIONS:
            raise ValueError(f"axis direction {self.stronger!r}: expected higher or lower")

    @classmethod
    def of_spec(cls, spec: dict) -> Axis:
        """The axis of a procedure spec (``scale``, default log; ``stronger``, default higher; its ``levels``'
        ends as the bounds when given)."""
        levels = spec.get("levels")
        bounds = (float(min(levels)), float(max(levels))) if levels else None
        return cls(spec.get("scale", "log"), spec.get("stronger", "higher"), bounds)

    @property
    def unit(self) -> str:
        """The unit of ``x`` (and of an SD of thresholds): ``log10`` or ``linear``."""
        return "log10" if self.scale == "log" else "linear"

    def to_intensity(self, value):
        """Parameter value(s) ``v`` -> intensity ``x = ±log10(v)`` (log) or ``±v`` (linear); minus where
        ``stronger`` is ``lower``."""
        if np.ndim(value) == 0:
            v = float(value)
            x = math.log10(v) if self.scale == "log" else v
            return -x if self.stronger == "lower" else x
        v = np.asarray(value, dtype=float)
        x = np.log10(v) if self.scale == "log" else v
        return -x if self.stronger == "lower" else x

    def to_level(self, x):
        """Intensity ``x`` -> parameter value(s) (the inverse of :meth:`to_intensity`)."""
        if np.ndim(x) == 0:
            y = -float(x) if self.stronger == "lower" else float(x)
            return 10.0 ** y if self.scale == "log" else y
        y = np.asarray(x, dtype=float)
        y = -y if self.stronger == "lower" else y
        return np.power(10.0, y) if self.scale == "log" else y

    def x_range(self, levels: np.ndarray) -> tuple[float, float]:
        """The stimulus range on the intensity axis: the bounds if declared, else the levels tested."""
        ends = self.to_intensity(np.asarray(self.bounds if self.bounds is not None else (levels.min(),
                                                                                         levels.max())))
        return float(ends.min()), float(ends.max())


def grid(scale: str, lo: float, hi: float, n: int) -> list[float]:
    """``n`` parameter values from ``lo`` to ``hi``, evenly spaced on ``scale`` (geometric for log, linear
    otherwise), rounded to 6 significant digits so that they are stable names in a cache key."""
    values = np.geomspace(lo, hi, n) if scale == "log" else np.linspace(lo, hi, n)
    return [float(f"{v:.6g}") for v in values]
