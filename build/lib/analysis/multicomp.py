"""Multiple-comparison adjustment of p-values (R's ``p.adjust`` semantics)."""

from __future__ import annotations

from typing import Any

import numpy as np

from data_schema.errors import UserError

__all__ = ["holm", "adjust_pvalues"]

_METHODS = {
    "holm": "holm",
    "bonferroni": "bonferroni",
    "bonf": "bonferroni",
    "fdr_bh": "fdr_bh",
    "bh": "fdr_bh",
    "none": "none",
}


def _as_pvalues(pvalues: Any) -> np.ndarray:
    if isinstance(pvalues, (str, bytes)) or pvalues is None:
        raise UserError(f"pvalues must be array-like numbers, got {type(pvalues).__name__}")
    try:
        p = np.array(pvalues, dtype=np.float64)
    except (TypeError, ValueError):
        raise UserError("pvalues must contain only numbers (or NaN)") from None
    finite = p[~np.isnan(p)]
    if finite.size and (finite.min() < 0.0 or finite.max() > 1.0):
        raise UserError(
            f"pvalues must lie in [0, 1] (NaN allowed), got min={finite.min()!r}, max={finite.max()!r}"
        )
    return p


def _holm_sorted_free(q: np.ndarray) -> np.ndarray:
    n = q.size
    o = np.argsort(q, kind="stable")
    adj = np.empty(n)
    adj[o] = np.minimum(1.0, np.maximum.accumulate((n - np.arange(n)) * q[o]))
    return adj


def _bh_sorted_free(q: np.ndarray) -> np.ndarray:
    n = q.size
    o = np.argsort(-q, kind="stable")  # decreasing
    i = np.arange(n, 0, -1, dtype=np.float64)
    adj = np.empty(n)
    adj[o] = np.minimum(1.0, np.minimum.accumulate((n / i) * q[o]))
    return adj


def adjust_pvalues(pvalues: Any, method: str = "holm") -> np.ndarray:
    """Adjust p-values for multiple comparisons, exactly as R's ``p.adjust``.

    Parameters
    ----------
    pvalues : array_like
        p-values in [0, 1]; NaN marks a missing test. Any shape; the output has the same
        shape.
    method : {"holm", "bonferroni", "fdr_bh", "none"}
        ``"bonf"`` and ``"bh"`` are accepted aliases (case-insensitive).

    Returns
    -------
    ndarray of float64
        Adjusted p-values, each capped at 1, NaN where the input was NaN.

    Notes
    -----
    NaN semantics follow R: NaN entries stay NaN and are *not* counted, i.e. ``n`` is the
    number of non-NaN p-values. With the non-NaN p-values sorted ascending,
    :math:`p_{(1)} \\le \\dots \\le p_{(n)}`:

    * Holm (1979): :math:`\\tilde p_{(i)} = \\min\\{1, \\max_{j \\le i} (n - j + 1) p_{(j)}\\}`
    * Bonferroni: :math:`\\tilde p_i = \\min(1, n p_i)`
    * Benjamini & Hochberg (1995):
      :math:`\\tilde p_{(i)} = \\min\\{1, \\min_{j \\ge i} n p_{(j)} / j\\}`

    References
    ----------
    Holm, S. (1979). A simple sequentially rejective multiple test procedure.
    *Scandinavian Journal of Statistics*, 6, 65-70.
    R Core Team. ``p.adjust`` in package stats.
    """
    key = _METHODS.get(str(method).lower()) if isinstance(method, str) else None
    if key is None:
        raise UserError(f"unknown p-value adjustment method {method!r}; use one of {sorted(_METHODS)}")
    p = _as_pvalues(pvalues)
    flat = p.ravel()
    out = np.full(flat.shape, np.nan)
    ok = ~np.isnan(flat)
    q = flat[ok]
    if q.size:
        if key == "holm":
            out[ok] = _holm_sorted_free(q)
        elif key == "bonferroni":
            out[ok] = np.minimum(1.0, q.size * q)
        elif key == "fdr_bh":
            out[ok] = _bh_sorted_free(q)
        else:
            out[ok] = q
    return out.reshape(p.shape)


def holm(pvalues: Any) -> np.ndarray:
    """Holm (1979) step-down adjusted p-values, identical to R's ``p.adjust(p, "holm")``.

    Parameters
    ----------
    pvalues : array_like
        p-values in [0, 1]; NaN marks a missing test. Any shape.

    Returns
    -------
    ndarray of float64
        Adjusted p-values (same shape), monotone in the order of the raw p-values and
        capped at 1. NaNs stay NaN and are excluded from the number of tests ``n``.

    Raises
    ------
    ValueError
        If a p-value lies outside [0, 1] (including +-inf) or is not a number.

    Notes
    -----
    With the ``n`` non-NaN p-values sorted ascending,

    .. math:: \\tilde p_{(i)} = \\min\\Big\\{1,\\ \\max_{j \\le i}\\,(n - j + 1)\\,p_{(j)}\\Big\\}.

    A p-value of exactly 0 stays 0; tiny p-values (e.g. 1e-300) are multiplied, never
    rounded to 0.

    References
    ----------
    Holm, S. (1979). A simple sequentially rejective multiple test procedure.
    *Scandinavian Journal of Statistics*, 6, 65-70.

    Examples
    --------
    >>> holm([0.01, float("nan"), 0.04, 0.03])
    array([0.03,  nan, 0.06, 0.06])
    """
    return adjust_pvalues(pvalues, "holm")
