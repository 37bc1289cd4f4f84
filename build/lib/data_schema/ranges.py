"""Range checks: the one place that says whether a number is allowed, and how the refusal reads.

Every option, parameter and field with a numeric range is checked through :class:`Range`, so the messages are
the same everywhere::

    --scale=nan is invalid: must be a finite number
    --seed=9223372036854775808 is out of range: allowed [0, 9223372036854775807]
    vafr.e_max=90 is out of range: allowed (0, 90)

A refusal is a :class:`~data_schema.errors.UserError` (one line; exit status 2 on the CLI).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import UserError

#: The largest integer SQLite stores (signed 64 bit): seeds and counts that reach the study database.
INT64_MAX = 2 ** 63 - 1


@dataclass(frozen=True)
class Range:
    """An allowed interval ``[low, high]`` (either end open or absent); ``integer`` asks for whole numbers."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    integer: bool = False

    def describe(self) -> str:
        lo = "(-inf" if self.low is None else ("(" if self.low_open else "[") + _g(self.low)
        hi = "inf)" if self.high is None else _g(self.high) + (")" if self.high_open else "]")
        return f"{lo}, {hi}"

    def contains(self, x: float) -> bool:
        lo_ok = self.low is None or (x > self.low if self.low_open else x >= self.low)
        hi_ok = self.high is None or (x < self.high if self.high_open else x <= self.high)
        return lo_ok and hi_ok

    def check(self, name: str, value):
        """``value`` as int (``integer``) or float, or a :class:`UserError` naming ``name`` and the range."""
        if isinstance(value, bool):
            raise UserError(f"{name}={value!r} is invalid: must be a number")
        if isinstance(value, int):
            x = value
        else:
            try:
                x = float(value)
            except (TypeError, ValueError, OverflowError):
                raise UserError(f"{name}={value!r} is invalid: must be a number") from None
            if not math.isfinite(x):
                raise UserError(f"{name}={value!r} is invalid: must be a finite number")
            if self.integer:
                if not x.is_integer():
                    raise UserError(f"{name}={value!r} is invalid: must be a whole number")
                x = int(x)
        if not self.contains(x):
            raise UserError(f"{name}={_g(x)} is out of range: allowed {self.describe()}")
        return int(x) if self.integer else float(x)


def _g(x) -> str:
    return str(x) if isinstance(x, int) else f"{x:g}"


def check(name: str, value, low=None, high=None, *, low_open=False, high_open=False, integer=False):
    """Shorthand for ``Range(...).check(name, value)``."""
    return Range(low, high, low_open, high_open, integer).check(name, value)


def argtype(option: str, rng: Range):
    """An argparse ``type=`` that checks ``rng`` and names ``option`` (``--scale``) in the one-line error."""

    import argparse

    def parse(text: str):
        try:
            try:
                value = int(text) if rng.integer else float(text)
            except ValueError:
                value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option}={text!r} is invalid: must be a number") from None
        try:
            return rng.check(option, value)
        except UserError as exc:  # argparse reports ArgumentTypeError messages as they are
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = option.lstrip("-").replace("-", "_")
    return parse


#: Ranges used by several commands.
SEED = Range(0, INT64_MAX, integer=True)
SCALE = Range(0.0, 1.0, low_open=True)
FOV_Y = Range(0.0, 180.0, low_open=True, high_open=True)


def check_range(name: str, value, low=None, high=None, *, low_open: bool = True, high_open: bool = True) -> float:
    """A float in ``(low, high)`` (ends open unless said otherwise), e.g. a mapping parameter."""
    return Range(low, high, low_open, high_open).check(name, value)
