"""Log-polar foveation mappings: VaFR, LMFR and LaFR (seed 001), their shading rates and reference curves.

>>> from renderers.foveation import make_mapping
>>> m = make_mapping("vafr", 2560, 1440, fov_y_deg=100)
>>> m.lp_shape
(901, 1638)
"""

from __future__ import annotations

import inspect

from data_schema.errors import UserError
from data_schema.geometry import ViewingGeometry

from .acuity import DEFAULT_PIVOTS, AcuityMapping
from .base import FoveationMapping
from .kernel import LAFR_FOVEAL_BOUNDARY_DEG, LaFRMapping, LMFRMapping
from .reference import acuity_curve, guenter_step
from .vafr import PRESETS, SEED_PRESET_REDUCTION, VaFRMapping

MAPPINGS: dict[str, type[FoveationMapping]] = {"vafr": VaFRMapping, "lmfr": LMFRMapping, "lafr": LaFRMapping}


def make_mapping(method: str, width: int, height: int, fov_y_deg: float, gaze=None, **params) -> FoveationMapping:
    """Create a foveation mapping.

    Parameters
    ----------
    method : {"vafr", "lmfr", "lafr"}
    width, height : int
        Display resolution in pixels (>= 1).
    fov_y_deg : float
        Vertical field of view of the camera, in (0, 180) degrees; gives ``c_r`` (seed 001 Eq 3).
    gaze : (x, y), optional
        Gaze point in pixel coordinates (default: the display centre); may lie outside the display.
    **params
        Method parameters: VaFR ``pivots``, ``e_max``, ``preset``, ``cap_cpd``, ``tangential_factor``;
        LMFR ``delta``, ``alpha``; LaFR ``delta``, ``alpha``, ``beta``, ``a``, ``foveal_boundary_deg``.

    Raises
    ------
    ValueError
        Naming the invalid parameter and its allowed range.
    """
    return mapping_for(method, ViewingGeometry.create(width, height, fov_y_deg, gaze), **params)


def mapping_for(method: str, geometry: ViewingGeometry, **params) -> FoveationMapping:
    """The mapping ``method`` for an image of the given viewing geometry (see :func:`make_mapping`)."""
    try:
        cls = MAPPINGS[str(method).lower()]
    except KeyError:
        raise UserError(f"method={method!r} is invalid: allowed {', '.join(MAPPINGS)}") from None
    allowed = [p for p in inspect.signature(cls.__init__).parameters if p not in ("self", "display")]
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise UserError(f"{method}: unknown parameter {unknown[0]!r}: allowed {', '.join(allowed)}")
    return cls(geometry, **params)


__all__ = ["make_mapping", "mapping_for", "MAPPINGS", "FoveationMapping", "VaFRMapping", "LMFRMapping",
           "LaFRMapping", "AcuityMapping", "DEFAULT_PIVOTS", "PRESETS", "SEED_PRESET_REDUCTION",
           "LAFR_FOVEAL_BOUNDARY_DEG", "acuity_curve", "guenter_step"]
