"""Boundary validation and ranking helpers shared by the analysis modules.

Every public function of :mod:`analysis` converts its inputs through these helpers, so the
error messages are uniform: one line, naming the argument (or group, or column) at fault.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from data_schema.errors import UserError

__all__: list[str] = []  # private module


def as_float_1d(x: Any, name: str) -> np.ndarray:
    """Return ``x`` as a 1-D float64 array (NaN kept), or raise ValueError.

    Accepts lists, tuples, NumPy arrays and pandas Series/Index (nullable dtypes included:
    ``pd.NA`` becomes NaN). Booleans, strings, complex numbers and anything that is not
    one-dimensional are rejected.
    """
    if isinstance(x, (str, bytes)) or x is None:
        raise UserError(f"{name} must be a 1-D array-like of numbers, got {type(x).__name__}")
    if isinstance(x, (pd.Series, pd.Index)):
        if not pd.api.types.is_numeric_dtype(x.dtype) or pd.api.types.is_bool_dtype(x.dtype):
            raise UserError(f"{name} must be numeric, got dtype {x.dtype}")
        return x.to_numpy(dtype=np.float64, na_value=np.nan)
    if isinstance(x, pd.DataFrame):
        raise UserError(f"{name} must be 1-D, got a DataFrame")
    a = np.asarray(x)
    if a.ndim != 1:
        raise UserError(f"{name} must be 1-D, got an array with {a.ndim} dimension(s)")
    if a.dtype.kind in "iuf":
        return a.astype(np.float64, copy=False)
    if a.dtype.kind == "O":
        try:
            out = np.array([np.nan if v is None or v is pd.NA else v for v in a], dtype=np.float64)
        except (TypeError, ValueError):
            raise UserError(f"{name} must contain only numbers (or NaN)") from None
        return out
    raise UserError(f"{name} must be numeric, got dtype {a.dtype}")


def drop_nan(a: np.ndarray) -> np.ndarray:
    """Return ``a`` without its NaN entries (a view-free copy only when needed)."""
    mask = np.isnan(a)
    return a[~mask] if mask.any() else a


def check_group(a: np.ndarray, name: str) -> np.ndarray:
    """Drop NaN from a group and reject it if nothing is left."""
    a = drop_nan(a)
    if a.size == 0:
        raise UserError(f"{name} is empty (no non-NaN observations)")
    return a


def tie_blocks(sorted_values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Blocks of equal values of an ascending, NaN-free float64 array.

    Returns
    -------
    values : ndarray
        The distinct values, ascending.
    counts : ndarray of int64
        Size ``t`` of every block of equal values.
    block_ranks : ndarray of float64
        The average (mid-)rank shared by the block, as R's ``rank(ties.method =
        "average")``: a block at 0-based positions start..stop-1 has rank
        ``(start + 1 + stop) / 2``.
    """
    n = sorted_values.size
    new_block = np.empty(n, dtype=bool)
    new_block[0] = True
    np.not_equal(sorted_values[1:], sorted_values[:-1], out=new_block[1:])
    if new_block.all():  # no ties: skip the gathers (a large share of the time for big N)
        return sorted_values, np.ones(n, dtype=np.int64), np.arange(1, n + 1, dtype=np.float64)
    starts = np.flatnonzero(new_block)
    bounds = np.append(starts, n)
    return sorted_values[starts], np.diff(bounds), (starts + bounds[1:] + 1) / 2.0


def group_rank_sums(groups: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Rank the pooled groups (average ranks for ties) and sum the ranks per group.

    Parameters
    ----------
    groups : sequence of ndarray
        Non-empty, NaN-free float64 samples.

    Returns
    -------
    rank_sums : ndarray of float64, one per group
    counts, block_ranks : ndarray
        Tie blocks of the pooled sample (see :func:`tie_blocks`).
    n : int
        Pooled sample size N.

    Notes
    -----
    Sorts the pooled sample and each group once (no argsort), then looks every sorted
    group value up in the distinct values: O(N log N) and about 1 s for N = 10**7.
    Ranks are float64 half-integers; rank sums stay below 2**53 for N < ~10**8, so they
    are exact.
    """
    pooled = np.sort(np.concatenate(groups))
    values, counts, block_ranks = tie_blocks(pooled)
    rank_sums = np.array(
        [float(block_ranks[np.searchsorted(values, np.sort(g))].sum()) for g in groups], dtype=np.float64
    )
    return rank_sums, counts, block_ranks, int(pooled.size)


def rank_sum_of_squares(counts: np.ndarray, block_ranks: np.ndarray, n: int) -> float:
    """Total sum of squares of the (tie-averaged) ranks about their mean ``(N + 1) / 2``.

    Equals ``(N**3 - N) / 12 * (1 - sum(t**3 - t) / (N**3 - N))``, the tie-corrected
    variance term of Kruskal-Wallis, Mann-Whitney and Dunn, but is computed as a sum of
    non-negative terms, so there is no cancellation for heavy ties and it is exactly 0
    when (and only when) all values are tied.
    """
    dev = block_ranks - (n + 1) / 2.0
    return float(np.sum(counts * dev * dev))


def check_frame(data: Any, columns: dict[str, Any]) -> pd.DataFrame:
    """Check ``data`` is a DataFrame holding every named column."""
    if not isinstance(data, pd.DataFrame):
        raise UserError(f"data must be a pandas DataFrame, got {type(data).__name__}")
    for role, col in columns.items():
        if col is None:
            raise UserError(f"{role} must name a column of data, got None")
        if col not in data.columns:
            raise UserError(f"{role}={col!r} is not a column of data")
    return data


def py_scalar(v: Any) -> Any:
    """NumPy scalar -> the equivalent Python scalar (clean reprs in messages and tables)."""
    return v.item() if isinstance(v, np.generic) else v


def levels_in_order(labels: pd.Series, order: Sequence[Any] | None, between: str) -> list[Any]:
    """Condition levels to analyse, in output order.

    ``order=None``: the categories of a categorical column (those that occur), otherwise
    the sorted distinct labels (order of first appearance if they cannot be sorted).
    An explicit ``order`` must be free of duplicates; its levels are used as given.
    """
    present = [py_scalar(v) for v in pd.unique(labels.dropna())]
    if order is None:
        if isinstance(labels.dtype, pd.CategoricalDtype):
            seen = set(present)
            return [py_scalar(c) for c in labels.cat.categories if py_scalar(c) in seen]
        try:
            return sorted(present)
        except TypeError:
            return present
    if isinstance(order, (str, bytes)):
        raise UserError(f"order must be a sequence of {between!r} levels, not a string")
    order = [py_scalar(v) for v in order]
    if len(set(order)) != len(order):
        raise UserError(f"order contains duplicate levels: {order!r}")
    return order


def split_groups(
    data: pd.DataFrame, dv: str, between: str, order: Sequence[Any] | None
) -> tuple[list[Any], list[np.ndarray]]:
    """Split a tidy frame into NaN-free float arrays, one per condition level.

    Rows whose ``dv`` is NaN or whose ``between`` label is missing are dropped. With an
    explicit ``order``, rows of levels not in ``order`` are ignored. Every analysed level
    must keep at least one observation, and at least two levels are required.
    """
    check_frame(data, {"dv": dv, "between": between})
    if dv == between:
        raise UserError("dv and between must be different columns")
    y = as_float_1d(data[dv], f"column {dv!r}")
    labels = data[between]
    keep = ~np.isnan(y) & labels.notna().to_numpy()
    levels = levels_in_order(labels[keep], order, between)
    lab = labels.to_numpy()
    groups = []
    for lev in levels:
        g = y[keep & (lab == lev)]
        if g.size == 0:
            raise UserError(f"condition {lev!r} of {between!r} has no non-NaN observations of {dv!r}")
        groups.append(g)
    if len(groups) < 2:
        raise UserError(f"need at least two conditions of {between!r} with data, got {len(groups)}")
    return levels, groups
