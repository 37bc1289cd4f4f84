"""The trial families, one module each: :mod:`.two_afc`, :mod:`.preference`, :mod:`.yes_no` (see :mod:`.base`).

>>> from data_schema import families
>>> families.get("2afc").default_keys(5)["answer"]
{'1': 'A', '2': 'B'}
"""

from __future__ import annotations

from ..errors import UserError
from .base import Observer, TrialFamily
from .preference import FAMILY as _PREFERENCE
from .two_afc import FAMILY as _TWO_AFC
from .yes_no import FAMILY as _YES_NO

#: name -> family, in the order the schema and the reports list them.
FAMILIES: dict[str, TrialFamily] = {f.name: f for f in (_TWO_AFC, _PREFERENCE, _YES_NO)}
NAMES: tuple[str, ...] = tuple(FAMILIES)


def get(name: str) -> TrialFamily:
    """The family ``name``; ValueError naming the allowed ones."""
    try:
        return FAMILIES[name]
    except KeyError:
        raise UserError(f"unknown trial family {name!r}: allowed {', '.join(FAMILIES)}") from None


def single_stimulus() -> TrialFamily:
    """The family whose trial shows one stimulus alone, played once (``yes_no``): what a labelled reference or a
    preview display is shown as."""
    return next(f for f in FAMILIES.values() if f.stimuli_range(1) == (1, 1) and not f.loops)


__all__ = ["FAMILIES", "NAMES", "Observer", "TrialFamily", "get", "single_stimulus"]
