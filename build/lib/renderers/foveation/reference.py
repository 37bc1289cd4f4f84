"""Reference curves for the shading-rate plots (seed 001 Fig 5, 8-10, 21)."""

from __future__ import annotations

import numpy as np

from data_schema.ranges import check_range

from .acuity import DEFAULT_PIVOTS, AcuityMapping


def acuity_curve(e_deg, pivots=DEFAULT_PIVOTS):
    """The piecewise-linear-MAR acuity model ``f(e)`` in cpd (seed 001 Eq 2, 12), without caps."""
    return AcuityMapping(pivots, c_r=1.0).acuity(e_deg)


def guenter_step(e_deg, display_cpd: float, factors=(1.0, 2.0, 4.0), pivots=DEFAULT_PIVOTS):
    """Step-function shading rate of layered foveated rendering (Guenter et al. 2012; seed 001 Fig 5).

    Layer ``k`` is rendered at ``1 / factors[k]`` of the display's linear resolution, i.e. at
    ``display_cpd / factors[k]`` cycles per degree. Layer ``k`` takes over from layer ``k-1`` at the first
    eccentricity where the acuity model drops to its rate, so the step never falls below acuity beyond the
    fovea's first layer. The result is discontinuous by construction, which is the point of Fig 5.
    """
    display_cpd = check_range("display_cpd", display_cpd, 0.0, None)
    factors = [check_range("factor", f, 0.0, None) for f in factors]
    e = np.asarray(e_deg, dtype=np.float64)
    fine = np.linspace(0.0, 90.0, 90001)
    acu = acuity_curve(fine, pivots)
    rate = np.full(e.shape, display_cpd / factors[0])
    for f in factors[1:]:
        r = display_cpd / f
        below = np.nonzero(acu <= r)[0]
        if below.size:
            rate = np.where(e >= fine[below[0]], r, rate)
    return rate
