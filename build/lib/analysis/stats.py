"""Rank-based tests for between-condition comparisons of perceptual study data.

Kruskal-Wallis omnibus test, the two-sample Mann-Whitney test, Dunn's post-hoc test and
pairwise Kruskal-Wallis tests with multiplicity adjustment, plus the per-condition summary
table used in the papers' results sections. All tests are the asymptotic, tie-corrected
versions that R's ``kruskal.test`` and ``wilcox.test(exact = FALSE, correct = FALSE)``
compute, and every p-value is two-sided.

NaN policy (all functions): NaN observations are dropped before anything is computed;
a group left without observations is an error.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations
from typing import Any

import numpy as np
import pandas as pd
from scipy import special

from data_schema.errors import UserError

from ._validation import (
    as_float_1d,
    check_frame,
    check_group,
    group_rank_sums,
    levels_in_order,
    py_scalar,
    rank_sum_of_squares,
    split_groups,
)
from .effect_size import _mean_var, d_with_reason, effect_size_label
from .multicomp import adjust_pvalues, holm

__all__ = [
    "KruskalResult",
    "MannWhitneyResult",
    "kruskal",
    "mann_whitney",
    "dunn",
    "pairwise_kruskal",
    "pairwise_matrix",
    "format_p",
    "format_p_cell",
    "summary_table",
    "holm",
    "adjust_pvalues",
]


@dataclass(frozen=True)
class KruskalResult:
    """Result of :func:`kruskal`.

    Attributes
    ----------
    H : float
        Tie-corrected Kruskal-Wallis statistic (R's "Kruskal-Wallis chi-squared").
    df : int
        Degrees of freedom, number of groups minus one.
    p : float
        Upper-tail chi-square p-value, in [0, 1].
    N : int
        Number of observations used (after dropping NaN).
    degenerate : bool
        True when every observation is tied (the statistic is 0/0); then ``H = 0.0`` and
        ``p = 1.0`` by definition.
    """

    H: float
    df: int
    p: float
    N: int
    degenerate: bool


@dataclass(frozen=True)
class MannWhitneyResult:
    """Result of :func:`mann_whitney`.

    Attributes
    ----------
    U : float
        Mann-Whitney U of ``x``: number of pairs with x > y plus half the ties (R's ``W``).
    z : float
        Tie-corrected standard score of U, positive when ``x`` tends to be larger.
    p : float
        Two-sided asymptotic p-value, in [0, 1].
    n_x, n_y : int
        Sample sizes used (after dropping NaN).
    degenerate : bool
        True when every observation is tied; then ``z = 0.0`` and ``p = 1.0``.
    """

    U: float
    z: float
    p: float
    n_x: int
    n_y: int
    degenerate: bool


#: ``note`` of a pair whose observations are all tied (its p-value is NaN and it is not counted by Holm).
NOT_TESTABLE = "not testable (all observations tied)"
#: ``note`` of a paired summary row whose condition shares no subject with the reference.
NO_COMMON_SUBJECT = "not testable (no subject with data in both)"


def _all_tied(x: np.ndarray, y: np.ndarray) -> bool:
    """True if the NaN-free samples ``x`` and ``y`` hold one single value between them."""
    lo = min(x.min(), y.min())
    return bool(lo == max(x.max(), y.max()))


def _chi2_sf(x: float, df: int) -> float:
    # Same routine as scipy.stats.chi2.sf (cephes chdtrc), without importing scipy.stats.
    return float(min(1.0, max(0.0, special.chdtrc(df, x))))


def _two_sided_normal_p(z: float | np.ndarray) -> float | np.ndarray:
    # 2 * P(Z > |z|) = 2 * Phi(-|z|), computed in the tail so tiny p-values do not underflow early.
    return np.minimum(1.0, 2.0 * special.ndtr(-np.abs(z)))


def _rank_groups(groups: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Rank the pooled groups; return sizes, rank sums, total rank SS and N."""
    sizes = np.array([g.size for g in groups], dtype=np.int64)
    rank_sums, counts, block_ranks, n = group_rank_sums(groups)
    ss_total = rank_sum_of_squares(counts, block_ranks, n)
    return sizes, rank_sums, ss_total, n


def _kruskal_groups(groups: Sequence[np.ndarray]) -> KruskalResult:
    sizes, rank_sums, ss_total, n = _rank_groups(groups)
    df = len(groups) - 1
    if ss_total == 0.0:
        return KruskalResult(H=0.0, df=df, p=1.0, N=n, degenerate=True)
    dev = rank_sums / sizes - (n + 1) / 2.0
    h = (n - 1) * float(np.sum(sizes * dev * dev)) / ss_total
    return KruskalResult(H=h, df=df, p=_chi2_sf(h, df), N=n, degenerate=False)


def kruskal(*groups: Any) -> KruskalResult:
    """Kruskal-Wallis H test of equal distributions across independent groups.

    Parameters
    ----------
    *groups : array_like
        Two or more 1-D samples. NaN observations are dropped (as R's formula interface
        does with ``na.action = na.omit``).

    Returns
    -------
    KruskalResult
        ``H`` (tie-corrected), ``df = k - 1``, ``p``, ``N`` and ``degenerate``.

    Raises
    ------
    ValueError
        If fewer than two groups are given, if a group is empty (or all NaN) -- the
        message names the group by its 0-based position -- or if a group is not 1-D
        numeric data.

    Notes
    -----
    With pooled average ranks, group rank means :math:`\\bar R_i`, group sizes
    :math:`n_i` and :math:`N = \\sum n_i`,

    .. math::

        H = \\frac{\\frac{12}{N(N+1)} \\sum_i n_i \\big(\\bar R_i - \\tfrac{N+1}{2}\\big)^2}
                  {1 - \\sum_b (t_b^3 - t_b) / (N^3 - N)}

    where :math:`t_b` are the sizes of the blocks of tied values. It is computed in the
    equivalent form :math:`H = (N-1)\\,SS_{between}/SS_{total}` of the ranks, which has
    no cancellation and uses float64 ranks, so :math:`N = 10^7` is fine. The p-value is
    the chi-square upper tail with ``k - 1`` degrees of freedom (``chi2.sf``, not
    ``1 - cdf``), so small p-values do not underflow before ~1e-300. The result equals
    R's ``kruskal.test``.

    **Degenerate data.** If every observation (across all groups) has the same value,
    the tie correction is 0 and H is 0/0. Instead of NaN this function returns
    ``H = 0.0``, ``p = 1.0`` and ``degenerate = True``: no evidence of any difference.
    R returns NaN in this case.

    References
    ----------
    Kruskal, W. H. & Wallis, W. A. (1952). Use of ranks in one-criterion variance
    analysis. *Journal of the American Statistical Association*, 47(260), 583-621.
    Hollander, M. & Wolfe, D. A. (1973). *Nonparametric Statistical Methods*, 115-120.

    Examples
    --------
    >>> r = kruskal([2.9, 3.0, 2.5, 2.6, 3.2], [3.8, 2.7, 4.0, 2.4], [2.8, 3.4, 3.7, 2.2, 2.0])
    >>> round(r.H, 5), r.df, round(r.p, 2)
    (0.77143, 2, 0.68)
    """
    if len(groups) < 2:
        raise UserError(f"kruskal needs at least two groups, got {len(groups)}")
    arrays = [check_group(as_float_1d(g, f"groups[{i}]"), f"groups[{i}]") for i, g in enumerate(groups)]
    return _kruskal_groups(arrays)


def _mann_whitney_arrays(x: np.ndarray, y: np.ndarray) -> MannWhitneyResult:
    sizes, rank_sums, ss_total, n = _rank_groups([x, y])
    nx, ny = int(sizes[0]), int(sizes[1])
    u = float(rank_sums[0] - nx * (nx + 1) / 2.0)
    if ss_total == 0.0:
        return MannWhitneyResult(U=u, z=0.0, p=1.0, n_x=nx, n_y=ny, degenerate=True)
    # U - nx*ny/2 == R_x - nx*(N+1)/2 (exact in float64); Var(U) = nx*ny*SS_total/(N(N-1)).
    centred = float(rank_sums[0] - nx * (n + 1) / 2.0)
    z = centred / np.sqrt(nx * ny * ss_total / (n * (n - 1.0)))
    p = float(_two_sided_normal_p(z))
    return MannWhitneyResult(U=u, z=float(z), p=p, n_x=nx, n_y=ny, degenerate=False)


def mann_whitney(x: Any, y: Any) -> MannWhitneyResult:
    """Two-sided Mann-Whitney U (Wilcoxon rank-sum) test, asymptotic and tie-corrected.

    Parameters
    ----------
    x, y : array_like
        Independent 1-D samples. NaN observations are dropped.

    Returns
    -------
    MannWhitneyResult
        ``U`` (for ``x``), ``z``, two-sided ``p``, ``n_x``, ``n_y``, ``degenerate``.

    Raises
    ------
    ValueError
        If a sample is empty (or all NaN) or not 1-D numeric data.

    Notes
    -----
    With :math:`R_x` the sum of the pooled average ranks of ``x``,

    .. math::

        U = R_x - \\frac{n_x(n_x+1)}{2}, \\qquad
        z = \\frac{U - n_x n_y / 2}
                 {\\sqrt{\\frac{n_x n_y}{12}\\Big((N + 1) - \\frac{\\sum_b (t_b^3 - t_b)}{N(N-1)}\\Big)}},
        \\qquad p = 2\\,\\Phi(-|z|).

    No continuity correction is applied, so :math:`z^2` equals the Kruskal-Wallis H of
    the two groups and ``p`` equals its p-value. Equals R's
    ``wilcox.test(x, y, exact = FALSE, correct = FALSE)`` (``U`` is R's ``W``).
    If all observations are tied, ``z = 0.0``, ``p = 1.0`` and ``degenerate = True``.

    References
    ----------
    Mann, H. B. & Whitney, D. R. (1947). On a test of whether one of two random variables
    is stochastically larger than the other. *Annals of Mathematical Statistics*, 18, 50-60.
    Hollander, M. & Wolfe, D. A. (1973). *Nonparametric Statistical Methods*, 67-75.
    """
    xa = check_group(as_float_1d(x, "x"), "x")
    ya = check_group(as_float_1d(y, "y"), "y")
    return _mann_whitney_arrays(xa, ya)


def dunn(
    data: pd.DataFrame,
    dv: str,
    between: str,
    p_adjust: str = "holm",
    order: Sequence[Any] | None = None,
) -> pd.DataFrame:
    """Dunn's (1964) post-hoc test after a Kruskal-Wallis omnibus test.

    Parameters
    ----------
    data : DataFrame
        Tidy (long) data, one observation per row.
    dv : str
        Column of the dependent variable (numeric). NaN rows are dropped.
    between : str
        Column of the condition labels. Rows with a missing label are dropped.
    p_adjust : {"holm", "bonferroni", "fdr_bh", "none"}
        Adjustment across all pairs, as :func:`adjust_pvalues`.
    order : sequence, optional
        Conditions to compare, in this order; pairs are ``(order[i], order[j])``, i < j.
        Rows of other conditions are ignored (ranks are computed over the listed
        conditions only). Default: categorical order, else sorted labels.

    Returns
    -------
    DataFrame
        One row per pair, columns ``A``, ``B``, ``z``, ``p_unc``, ``p_adj``, ``note``. ``z > 0``
        means A has the higher mean rank. A pair whose observations are all tied is not
        testable: ``z``, ``p_unc`` and ``p_adj`` are NaN and ``note`` says so (``""``
        otherwise).

    Raises
    ------
    ValueError
        Missing columns, non-numeric ``dv``, fewer than two conditions, a condition in
        ``order`` without data, or an unknown ``p_adjust``.

    Notes
    -----
    Ranks are pooled over all compared conditions (average ranks for ties). For
    conditions i and j,

    .. math::

        z_{ij} = \\frac{\\bar R_i - \\bar R_j}
                      {\\sqrt{\\Big(\\frac{N(N+1)}{12} - \\frac{\\sum_b (t_b^3 - t_b)}{12(N-1)}\\Big)
                              \\Big(\\frac{1}{n_i} + \\frac{1}{n_j}\\Big)}},
        \\qquad p_{ij} = 2\\,\\Phi(-|z_{ij}|)

    i.e. tie-corrected and **two-sided**. ``p_adj`` adjusts these across the testable
    pairs. Matches the ``Z``, ``P.unadj`` and ``P.adj`` columns of R's
    ``FSA::dunnTest(dv ~ between, method = "holm")`` whenever no pair is all tied.

    **Untestable pairs.** If the two groups of a pair hold one and the same value (all
    their observations tied; in particular when every observation is tied and the
    statistic is 0/0), the pair gives no information about a difference. Its ``z`` and p
    are NaN ("not testable"), and, as R's ``p.adjust`` does with ``NA``, it is left out of
    the number of tests the adjustment counts.

    References
    ----------
    Dunn, O. J. (1964). Multiple comparisons using rank sums. *Technometrics*, 6(3),
    241-252.
    """
    levels, groups = split_groups(data, dv, between, order)
    sizes, rank_sums, ss_total, n = _rank_groups(groups)
    mean_ranks = rank_sums / sizes
    pairs = list(combinations(range(len(levels)), 2))
    ia = np.array([i for i, _ in pairs])
    ib = np.array([j for _, j in pairs])
    tied = np.array([_all_tied(groups[i], groups[j]) for i, j in pairs], dtype=bool)
    if ss_total == 0.0:
        z = np.full(len(pairs), np.nan)
    else:
        s2 = ss_total / (n - 1.0)  # == N(N+1)/12 - sum(t^3 - t) / (12(N-1))
        z = (mean_ranks[ia] - mean_ranks[ib]) / np.sqrt(s2 * (1.0 / sizes[ia] + 1.0 / sizes[ib]))
        z[tied] = np.nan
    p_unc = np.where(tied, np.nan, _two_sided_normal_p(z))
    return pd.DataFrame(
        {
            "A": [levels[i] for i in ia],
            "B": [levels[j] for j in ib],
            "z": z.astype(np.float64),
            "p_unc": p_unc.astype(np.float64),
            "p_adj": adjust_pvalues(p_unc, p_adjust),
            "note": np.where(tied, NOT_TESTABLE, "").astype(object),
        }
    )


def pairwise_kruskal(
    data: pd.DataFrame,
    dv: str,
    between: str,
    order: Sequence[Any] | None = None,
    p_adjust: str = "holm",
) -> pd.DataFrame:
    """Kruskal-Wallis test on every pair of conditions, adjusted across the pairs.

    The layout of the pairwise tables of the VaFR paper (Tables 2-3); see
    :func:`pairwise_matrix` for the matrix view.

    Parameters
    ----------
    data : DataFrame
        Tidy (long) data, one observation per row.
    dv : str
        Column of the dependent variable (numeric). NaN rows are dropped.
    between : str
        Column of the condition labels. Rows with a missing label are dropped.
    order : sequence, optional
        Conditions to compare, in this order; pairs are ``(order[i], order[j])``, i < j.
        Rows of other conditions are ignored. Default: categorical order, else sorted.
    p_adjust : {"holm", "bonferroni", "fdr_bh", "none"}
        Adjustment across all pairs (default Holm).

    Returns
    -------
    DataFrame
        One row per pair, columns ``A``, ``B``, ``H``, ``df``, ``p_unc``, ``p_adj``,
        ``n_A``, ``n_B``, ``note`` (``""``, or ``"not testable (all observations tied)"``).

    Raises
    ------
    ValueError
        As :func:`dunn`.

    Notes
    -----
    Each pair is ranked on its own (unlike :func:`dunn`, which ranks all conditions
    together): ``H`` and ``p_unc`` are :func:`kruskal` of the two samples (df = 1,
    equal to a two-sided, tie-corrected Mann-Whitney test without continuity
    correction), i.e. R's ``kruskal.test`` on the pair's subset.

    **Untestable pairs.** A pair whose observations are all tied has H = 0/0; R's
    ``kruskal.test`` returns NaN for it. So does this function (``H``, ``p_unc`` and
    ``p_adj`` NaN, ``note`` "not testable ..."), and the adjustment leaves the pair out of
    its count of tests, as R's ``p.adjust`` leaves out ``NA``. Example (R 4.2.2): for
    a = b = [1, 1, 1] and c = [2, 3, 4], a-c and b-c get Holm p = 0.073808 (two tests), a-b
    NaN. (The omnibus :func:`kruskal` keeps its documented ``degenerate`` flag instead.)

    References
    ----------
    Kruskal, W. H. & Wallis, W. A. (1952). *JASA*, 47(260), 583-621.
    Holm, S. (1979). *Scandinavian Journal of Statistics*, 6, 65-70.
    """
    levels, groups = split_groups(data, dv, between, order)
    rows = []
    for i, j in combinations(range(len(levels)), 2):
        res = _kruskal_groups([groups[i], groups[j]])
        h, p, note = (np.nan, np.nan, NOT_TESTABLE) if res.degenerate else (res.H, res.p, "")
        rows.append((levels[i], levels[j], h, res.df, p, groups[i].size, groups[j].size, note))
    out = pd.DataFrame(rows, columns=["A", "B", "H", "df", "p_unc", "n_A", "n_B", "note"])
    out.insert(5, "p_adj", adjust_pvalues(out["p_unc"].to_numpy(), p_adjust))
    dtypes = {"H": np.float64, "df": np.int64, "p_unc": np.float64, "n_A": np.int64, "n_B": np.int64}
    return out.astype(dtypes)


def format_p(p: float, decimals: int = 3) -> str:
    """Format a p-value for a table: ``decimals`` places, ``'<0.001'`` below ``10**-decimals``.

    Examples
    --------
    >>> format_p(0.0123), format_p(0.0004), format_p(1.0)
    ('0.012', '<0.001', '1.000')
    """
    if not isinstance(decimals, (int, np.integer)) or decimals < 1:
        raise UserError(f"decimals must be a positive integer, got {decimals!r}")
    p = float(p)
    if np.isnan(p) or p < 0.0 or p > 1.0:
        raise UserError(f"p must be a number in [0, 1], got {p!r} (see format_p_cell for untestable pairs)")
    threshold = 10.0 ** -int(decimals)
    if p < threshold:
        return f"<{threshold:.{decimals}f}"
    return f"{p:.{decimals}f}"


def format_p_cell(p: float, decimals: int = 3) -> str:
    """:func:`format_p` for a table cell: a NaN p (an untestable pair) prints as ``'not testable'``."""
    return "not testable" if np.isnan(float(p)) else format_p(p, decimals)


def pairwise_matrix(
    result: pd.DataFrame,
    order: Sequence[Any] | None = None,
    column: str = "p_adj",
    decimals: int = 3,
) -> pd.DataFrame:
    """Upper-triangular matrix of pairwise p-values, formatted for a paper table.

    Parameters
    ----------
    result : DataFrame
        Output of :func:`pairwise_kruskal` or :func:`dunn` (columns ``A``, ``B`` and
        ``column``).
    order : sequence, optional
        Row/column order. Default: levels in order of first appearance in ``A``/``B``.
    column : str
        Which p-value column to show (default ``"p_adj"``).
    decimals : int
        Decimal places (default 3); smaller values print as ``'<0.001'``.

    Returns
    -------
    DataFrame of str
        Index and columns ``order``; cell (r, c) for r before c holds the formatted
        p-value of the pair (in either orientation in ``result``); cells on and below the
        diagonal hold ``'/'``; a NaN p-value (an untestable pair) prints ``'not testable'``.

    Raises
    ------
    ValueError
        Missing columns, a pair of ``order`` absent from ``result``, or a pair listed twice.
    """
    check_frame(result, {"A column": "A", "B column": "B", "column": column})
    lookup: dict[frozenset, float] = {}
    for a, b, p in zip(result["A"], result["B"], result[column]):
        a, b = py_scalar(a), py_scalar(b)
        key = frozenset((a, b))
        if key in lookup:
            raise UserError(f"pair ({a!r}, {b!r}) appears more than once in result")
        lookup[key] = p
    if order is None:
        order = list(pd.unique(pd.concat([result["A"], result["B"]], ignore_index=True)))
    order = levels_in_order(pd.Series(list(order), dtype=object), order, "A/B")
    cells = [["/"] * len(order) for _ in order]
    for r, c in combinations(range(len(order)), 2):
        key = frozenset((order[r], order[c]))
        if key not in lookup:
            raise UserError(f"pair ({order[r]!r}, {order[c]!r}) is missing from result")
        cells[r][c] = format_p_cell(lookup[key], decimals)
    return pd.DataFrame(cells, index=pd.Index(order), columns=pd.Index(order), dtype=object)


def summary_table(
    data: pd.DataFrame,
    dv: str,
    between: str,
    reference: Any,
    order: Sequence[Any] | None = None,
    paired: bool = False,
    subject: str | None = None,
) -> pd.DataFrame:
    """Each condition against a reference: mean ± SD, p-value, Cohen's d and its label.

    The layout of the lightcuts paper's Tables 5-6 (avg ± std, p, Cohen's d, label).

    Parameters
    ----------
    data : DataFrame
        Tidy (long) data, one observation per row.
    dv : str
        Column of the dependent variable. NaN rows are dropped.
    between : str
        Column of the condition labels.
    reference : scalar
        The reference condition (e.g. full-resolution rendering); must occur in the data.
    order : sequence, optional
        Conditions to report, in this order (the reference is skipped if listed).
        Default: categorical order, else sorted labels.
    paired : bool
        If True, observations are matched by ``subject``: each row uses only the subjects
        with data in both the condition and the reference, and ``d`` is the paired
        :math:`d_z` (see :func:`~analysis.effect_size.cohens_d`).
    subject : str, optional
        Subject column, required when ``paired=True`` (one row per subject and condition).

    Returns
    -------
    DataFrame
        One row per non-reference condition, columns ``condition``, ``n``, ``mean``,
        ``std``, ``n_ref``, ``mean_ref``, ``std_ref``, ``p``, ``d``, ``label``, ``note``.
        ``std`` uses ddof = 1 (NaN for a single observation). ``p`` is always the
        two-sided, tie-corrected Mann-Whitney test (= Kruskal-Wallis on the two groups),
        as in the papers, also when ``paired=True``. ``d`` is Cohen's d of condition
        minus reference and ``label`` its Sawilowsky (2009) label.

    Raises
    ------
    ValueError
        Bad columns, unknown reference, a condition without data, or duplicate
        (subject, condition) rows when paired.

    Notes
    -----
    Degenerate rows never abort the table:

    * **undefined d** (zero pooled SD, one observation per group, fewer than two pairs):
      ``d`` is NaN and ``label`` gives the reason, e.g. ``"undefined (zero SD)"`` (see
      :func:`~analysis.effect_size.d_with_reason`); two identical constant groups are
      undefined as in R and pingouin, not d = 0;
    * **all observations of the row tied** (R's ``wilcox.test`` gives NaN): ``p`` is NaN
      and ``note`` is ``"not testable (all observations tied)"``; ``note`` is ``""``
      otherwise.

    References
    ----------
    Cohen, J. (1988). *Statistical Power Analysis for the Behavioral Sciences* (2nd ed.).
    Sawilowsky, S. S. (2009). New effect size rules of thumb. *Journal of Modern Applied
    Statistical Methods*, 8(2), 597-599.
    """
    if paired and subject is None:
        raise UserError("paired=True needs subject= naming the subject column")
    cols = {"dv": dv, "between": between}
    if paired:
        cols["subject"] = subject
    check_frame(data, cols)
    y = as_float_1d(data[dv], f"column {dv!r}")
    labels = data[between]
    keep = ~np.isnan(y) & labels.notna().to_numpy()
    if paired:
        keep &= data[subject].notna().to_numpy()
    present = set(pd.unique(labels[keep]))
    if reference not in present:
        raise UserError(f"reference {reference!r} has no non-NaN observations in column {between!r}")
    levels = [lev for lev in levels_in_order(labels[keep], order, between) if lev != reference]
    if not levels:
        raise UserError(f"no condition other than the reference {reference!r} to compare")
    lab = labels.to_numpy()

    if paired:
        sub = pd.DataFrame({"s": data[subject].to_numpy()[keep], "c": lab[keep], "y": y[keep]})
        dup = sub.duplicated(["s", "c"])
        if dup.any():
            s, c = (py_scalar(v) for v in sub.loc[dup.idxmax(), ["s", "c"]])
            raise UserError(f"subject {s!r} has more than one row for condition {c!r}; aggregate first")
        wide = sub.pivot(index="s", columns="c", values="y")

    rows = []
    for lev in levels:
        if paired:
            if lev not in wide.columns:
                raise UserError(f"condition {lev!r} of {between!r} has no non-NaN observations of {dv!r}")
            both = wide[[lev, reference]].dropna()
            x, r = both[lev].to_numpy(np.float64), both[reference].to_numpy(np.float64)
            if x.size == 0:  # no subject with data in both: nothing to compare, but no reason to abort
                rows.append((lev, 0, np.nan, np.nan, 0, np.nan, np.nan, np.nan, np.nan,
                             d_with_reason(x, r, paired=True)[1], NO_COMMON_SUBJECT))
                continue
        else:
            x = y[keep & (lab == lev)]
            r = y[keep & (lab == reference)]
            if x.size == 0:
                raise UserError(f"condition {lev!r} of {between!r} has no non-NaN observations of {dv!r}")
        d, reason = d_with_reason(x, r, paired=paired)
        mx, vx = _mean_var(x)
        mr, vr = _mean_var(r)
        tied = _all_tied(x, r)
        rows.append(
            (
                lev,
                x.size,
                mx,
                float(np.sqrt(vx)) if x.size > 1 else np.nan,
                r.size,
                mr,
                float(np.sqrt(vr)) if r.size > 1 else np.nan,
                np.nan if tied else _mann_whitney_arrays(x, r).p,
                np.nan if reason else d,
                reason or effect_size_label(d),
                NOT_TESTABLE if tied else "",
            )
        )
    return pd.DataFrame(
        rows,
        columns=["condition", "n", "mean", "std", "n_ref", "mean_ref", "std_ref", "p", "d", "label", "note"],
    ).astype({"n": np.int64, "n_ref": np.int64})
