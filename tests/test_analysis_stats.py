"""Behaviour, validation and numerical robustness of analysis.stats / analysis.multicomp.

Reference values from R live in test_analysis_r_reference.py; here the checks are exact
identities, independent re-implementations (exact rational arithmetic, scipy.stats as a
secondary implementation) and edge cases.
"""

import math
from fractions import Fraction

import numpy as np
import pandas as pd
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from scipy import stats as sps

import analysis
from analysis import (
    adjust_pvalues,
    dunn,
    format_p,
    holm,
    kruskal,
    mann_whitney,
    pairwise_kruskal,
    pairwise_matrix,
    summary_table,
)

# Small integer values make ties frequent; floats exercise the tie-free path.
tied_values = st.lists(st.integers(-3, 3).map(float), min_size=1, max_size=12)
float_values = st.lists(
    st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False), min_size=1, max_size=12
)
groups_strategy = st.lists(st.one_of(tied_values, float_values), min_size=2, max_size=5)


def exact_kruskal(groups):
    """H from the textbook formula in exact rational arithmetic (R's kruskal.test formula)."""
    pooled = sorted(v for g in groups for v in g)
    n = len(pooled)
    rank = {}
    i = 0
    ties = 0
    while i < n:
        j = i
        while j < n and pooled[j] == pooled[i]:
            j += 1
        rank[pooled[i]] = Fraction(i + 1 + j, 2)
        t = j - i
        ties += t**3 - t
        i = j
    stat = sum(sum(rank[v] for v in g) ** 2 / len(g) for g in groups)
    denom = 1 - Fraction(ties, n**3 - n)
    return (Fraction(12, n * (n + 1)) * stat - 3 * (n + 1)) / denom


# --- kruskal -------------------------------------------------------------------------------------


def test_kruskal_result_fields_and_types():
    res = kruskal([1.0, 2.0, 3.0], [4.0, 5.0, 6.0])
    assert isinstance(res, analysis.KruskalResult)
    assert isinstance(res.H, float) and isinstance(res.p, float) and isinstance(res.df, int)
    # No ties: H = 12/(N(N+1)) * sum(R^2/n) - 3(N+1) = 12/42 * (36 + 225)/3 - 21 = 27/7
    assert res.H == pytest.approx(27 / 7, rel=1e-14)
    assert res.p == pytest.approx(math.erfc(math.sqrt(27 / 14)), rel=1e-12)  # chi2(1).sf(H) = erfc(sqrt(H/2))
    assert (res.df, res.N, res.degenerate) == (1, 6, False)


def test_kruskal_p_is_chi2_upper_tail():
    res = kruskal([1, 5, 7, 8], [2, 3, 4], [6, 9, 10, 11, 12])
    assert res.p == pytest.approx(sps.chi2.sf(res.H, res.df), rel=1e-14)


@given(groups_strategy)
def test_kruskal_equals_exact_rational_formula(groups):
    res = kruskal(*groups)
    pooled = [v for g in groups for v in g]
    assume(len(set(pooled)) > 1)
    exact = exact_kruskal(groups)
    assert res.H == pytest.approx(float(exact), rel=1e-9, abs=1e-12)
    assert 0.0 <= res.p <= 1.0
    assert res.df == len(groups) - 1 and not res.degenerate


@given(groups_strategy)
def test_kruskal_matches_scipy_secondary_check(groups):
    assume(len({v for g in groups for v in g}) > 1)
    res = kruskal(*groups)
    ref = sps.kruskal(*groups)
    assert res.H == pytest.approx(ref.statistic, rel=1e-7, abs=1e-9)
    assert res.p == pytest.approx(ref.pvalue, rel=1e-7, abs=1e-12)


@given(groups_strategy, st.randoms(use_true_random=False))
def test_kruskal_invariant_to_group_order_and_monotone_transform(groups, rnd):
    res = kruskal(*groups)
    shuffled = list(groups)
    rnd.shuffle(shuffled)
    # Scaling by -4 is exact in float64 and reverses the ranks; H only depends on the
    # squared deviations of the mean ranks, so it is unchanged.
    transformed = [-4.0 * np.asarray(g) for g in shuffled]
    res2 = kruskal(*transformed)
    assert res2.degenerate == res.degenerate
    assert res2.H == pytest.approx(res.H, rel=1e-12, abs=1e-12)
    assert res2.p == pytest.approx(res.p, rel=1e-12, abs=1e-300)


@given(groups_strategy)
def test_kruskal_p_always_in_unit_interval_and_h_nonnegative(groups):
    res = kruskal(*groups)
    assert 0.0 <= res.p <= 1.0
    assert res.H >= 0.0 and math.isfinite(res.H)


def test_kruskal_constant_data_is_degenerate_not_significant():
    res = kruskal([3.0, 3.0, 3.0], [3.0, 3.0], [3.0])
    assert res.H == 0.0 and res.p == 1.0 and res.degenerate is True
    assert res.df == 2 and res.N == 6


def test_kruskal_constant_within_but_not_across_groups():
    # ranks 1.5, 1.5, 3.5, 3.5: SS_total = 4, SS_between = 4, H = (N - 1) * 4 / 4 = 3
    res = kruskal([1.0, 1.0], [2.0, 2.0])
    assert res.H == pytest.approx(3.0, rel=1e-15)
    assert res.p == pytest.approx(sps.chi2.sf(3.0, 1), rel=1e-14)
    assert res.degenerate is False


def test_kruskal_groups_of_size_one():
    res = kruskal([1.0], [2.0], [3.0])
    # H = (N - 1) * SS_between / SS_total = 2 * 2 / 2 = 2; chi2(2).sf(2) = exp(-1)
    assert res.H == pytest.approx(2.0, rel=1e-15)
    assert res.p == pytest.approx(math.exp(-1.0), rel=1e-14)
    assert kruskal([5.0], [5.0]).degenerate


def test_kruskal_nan_observations_are_dropped():
    with_nan = kruskal([1.0, np.nan, 2.0, 7.0], [3.0, 4.0, np.nan], pd.Series([5.0, 6.0, None]))
    without = kruskal([1.0, 2.0, 7.0], [3.0, 4.0], [5.0, 6.0])
    assert with_nan == without
    assert with_nan.N == 7


def test_kruskal_accepts_pandas_nullable_and_integer_input():
    a = pd.Series([1, 2, None, 4], dtype="Int64")
    res = kruskal(a, np.array([5, 6, 7], dtype=np.int32))
    assert res == kruskal([1.0, 2.0, 4.0], [5.0, 6.0, 7.0])


@pytest.mark.parametrize(
    "groups, message",
    [
        (([1.0, 2.0], []), r"groups\[1\] is empty"),
        (([], [1.0]), r"groups\[0\] is empty"),
        (([1.0, 2.0], [np.nan, np.nan]), r"groups\[1\] is empty"),
        (([1.0, 2.0],), "at least two groups"),
        ((), "at least two groups"),
        (([[1.0, 2.0]], [1.0]), r"groups\[0\] must be 1-D"),
        ((["a", "b"], [1.0]), r"groups\[0\] must be numeric"),
        (("abc", [1.0]), r"groups\[0\] must be a 1-D array-like"),
        (([1 + 2j], [1.0]), r"groups\[0\] must be numeric"),
        ((pd.Series([True, False]), [1.0]), r"groups\[0\] must be numeric"),
    ],
)
def test_kruskal_invalid_input(groups, message):
    with pytest.raises(ValueError, match=message):
        kruskal(*groups)


def test_kruskal_tiny_p_does_not_underflow_early():
    # Two completely separated groups of n = 800: H = 3n^2/(2n + 1) ~ 1199, p ~ 1e-262.
    n = 800
    res = kruskal(np.arange(n), np.arange(n) + n)
    assert res.H == pytest.approx(3 * n**2 / (2 * n + 1), rel=1e-12)
    assert 0.0 < res.p < 1e-250
    assert math.log(res.p) == pytest.approx(sps.chi2.logsf(res.H, 1), rel=1e-10)


def test_kruskal_heavy_ties_no_cancellation():
    # N - 1 tied values and one distinct value: the tie correction 1 - sum(t^3 - t)/(N^3 - N)
    # is ~3/N; the sum-of-squares form is exact here.
    n = 100_001
    a = np.zeros(n - 1)
    groups = [a[: n // 2], np.append(a[n // 2 :], 1.0)]
    res = kruskal(*groups)
    exact = exact_kruskal([[0.0] * (n // 2), [0.0] * (n - 1 - n // 2) + [1.0]])
    assert res.H == pytest.approx(float(exact), rel=1e-12)


def test_kruskal_ten_million_observations_exact():
    rng = np.random.default_rng(12345)
    n = 10_000_000
    x = rng.standard_normal(n)
    x[n // 2 :] += 0.001  # a tiny shift
    res = kruskal(x[: n // 2], x[n // 2 :])  # speed is measured in benchmarks/, never asserted here
    assert res.N == n and not res.degenerate
    # Independent exact check: no ties (continuous data), so the ranks are 1..N and
    # H = 12/(N(N+1)) * sum(R_i^2 / n_i) - 3(N+1), evaluated in exact rational arithmetic
    # from the int64 rank sums (which are exact below 2^63).
    assert np.unique(x).size == n
    ranks = np.empty(n, dtype=np.int64)
    ranks[np.argsort(x)] = np.arange(1, n + 1)
    r1, r2 = int(ranks[: n // 2].sum()), int(ranks[n // 2 :].sum())
    sum_sq = Fraction(r1 * r1, n // 2) + Fraction(r2 * r2, n - n // 2)
    exact = Fraction(12, n * (n + 1)) * sum_sq - 3 * (n + 1)
    assert res.H == pytest.approx(float(exact), rel=1e-9)
    assert 0.0 <= res.p <= 1.0


def test_kruskal_ten_million_tied_integers():
    rng = np.random.default_rng(7)
    x = rng.integers(0, 50, size=10_000_000).astype(np.float64)
    groups = [x[:3_000_000], x[3_000_000:7_000_000], x[7_000_000:]]
    res = kruskal(*groups)
    # Independent O(N) computation from the contingency table of value x group.
    counts = np.stack([np.bincount(g.astype(np.int64), minlength=50) for g in groups])
    t = counts.sum(axis=0)
    n = int(t.sum())
    start = np.concatenate(([0], np.cumsum(t)[:-1]))
    mid_rank = start + (t + 1) / 2.0
    rank_sums = counts @ mid_rank
    sizes = counts.sum(axis=1)
    h_num = 12.0 / (n * (n + 1.0)) * np.sum(rank_sums**2 / sizes) - 3.0 * (n + 1)
    h = h_num / (1.0 - np.sum(t.astype(float) ** 3 - t) / (float(n) ** 3 - n))
    assert res.H == pytest.approx(h, rel=1e-6, abs=1e-6)  # the reference formula itself cancels
    assert 0.0 <= res.p <= 1.0 and res.N == 10_000_000


# --- mann_whitney --------------------------------------------------------------------------------


@given(st.one_of(tied_values, float_values), st.one_of(tied_values, float_values))
def test_mann_whitney_is_kruskal_with_two_groups(x, y):
    mw = mann_whitney(x, y)
    kw = kruskal(x, y)
    assert mw.degenerate == kw.degenerate
    assert mw.z**2 == pytest.approx(kw.H, rel=1e-10, abs=1e-12)
    assert mw.p == pytest.approx(kw.p, rel=1e-10, abs=1e-300)
    assert 0.0 <= mw.p <= 1.0


@given(st.one_of(tied_values, float_values), st.one_of(tied_values, float_values))
def test_mann_whitney_matches_scipy_asymptotic_without_correction(x, y):
    assume(len(set(x) | set(y)) > 1)
    mw = mann_whitney(x, y)
    ref = sps.mannwhitneyu(x, y, method="asymptotic", use_continuity=False)
    assert mw.U == pytest.approx(ref.statistic, rel=1e-12)
    assert mw.p == pytest.approx(ref.pvalue, rel=1e-8, abs=1e-14)


@given(st.one_of(tied_values, float_values), st.one_of(tied_values, float_values))
def test_mann_whitney_symmetry(x, y):
    a, b = mann_whitney(x, y), mann_whitney(y, x)
    assert a.U + b.U == pytest.approx(len(x) * len(y), rel=1e-15)
    assert a.z == pytest.approx(-b.z, rel=1e-12, abs=1e-15)
    assert a.p == pytest.approx(b.p, rel=1e-12)


def test_mann_whitney_known_values():
    # x all above y: U = n_x n_y, z = (U - n_x n_y/2) / sqrt(n_x n_y (N + 1)/12)
    res = mann_whitney([4.0, 5.0, 6.0], [1.0, 2.0])
    assert res.U == 6.0
    assert res.z == pytest.approx(3.0 / math.sqrt(6 * 6 / 12), rel=1e-14)
    assert res.p == pytest.approx(math.erfc(res.z / math.sqrt(2)), rel=1e-13)
    assert (res.n_x, res.n_y, res.degenerate) == (3, 2, False)


def test_mann_whitney_all_tied_is_degenerate():
    res = mann_whitney([2.0, 2.0, 2.0], [2.0, np.nan])
    assert (res.U, res.z, res.p, res.degenerate) == (1.5, 0.0, 1.0, True)
    assert res.n_y == 1


@pytest.mark.parametrize(
    "x, y, message",
    [([], [1.0], "x is empty"), ([1.0], [np.nan], "y is empty"), ([1.0], None, "y must be a 1-D")],
)
def test_mann_whitney_invalid(x, y, message):
    with pytest.raises(ValueError, match=message):
        mann_whitney(x, y)


# --- holm / adjust_pvalues -----------------------------------------------------------------------


def naive_holm(p):
    """Definition-level Holm: sort, multiply by (n - rank + 1), running max, cap, NaN skipped."""
    p = list(p)
    idx = [i for i, v in enumerate(p) if not math.isnan(v)]
    n = len(idx)
    order = sorted(idx, key=lambda i: p[i])
    out = [math.nan] * len(p)
    running = 0.0
    for k, i in enumerate(order):
        running = max(running, (n - k) * p[i])
        out[i] = min(1.0, running)
    return out


pvalue = st.one_of(
    st.floats(0.0, 1.0),
    st.sampled_from([0.0, 1.0, 1e-300, 5e-324, 0.05, math.nan]),
)


@given(st.lists(pvalue, max_size=30))
def test_holm_matches_definition(p):
    out = holm(p)
    np.testing.assert_allclose(out, naive_holm(p), rtol=1e-15, atol=0)


@given(st.lists(pvalue, min_size=1, max_size=30))
def test_holm_properties(p):
    arr = np.array(p)
    out = holm(arr)
    ok = ~np.isnan(arr)
    assert np.array_equal(np.isnan(out), ~ok)  # NaN stays NaN and only NaN
    assert np.all((out[ok] >= 0.0) & (out[ok] <= 1.0))
    assert np.all(out[ok] >= arr[ok])  # never smaller than the raw p
    order = np.argsort(arr[ok], kind="stable")
    assert np.all(np.diff(out[ok][order]) >= 0.0)  # monotone in the raw order
    assert np.all(out[ok][arr[ok] > 0] > 0.0)  # a positive p never becomes 0


def test_holm_nan_not_counted():
    assert holm([0.01, np.nan]).tolist()[0] == 0.01
    out = holm([0.01, np.nan, 0.04, 0.03])
    np.testing.assert_allclose(out, [0.03, np.nan, 0.06, 0.06], rtol=1e-15)
    assert np.isnan(holm([np.nan, np.nan])).all()
    assert holm([]).shape == (0,)


def test_holm_exact_zero_and_one():
    np.testing.assert_array_equal(holm([0.0, 1.0]), [0.0, 1.0])
    np.testing.assert_array_equal(holm([1.0, 1.0, 1.0]), [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(holm([0.0, 0.0, 0.5]), [0.0, 0.0, 0.5])


def test_holm_tiny_pvalues_stay_positive_and_monotone():
    out = holm([1e-300, 2e-300, 5e-301])
    # sorted: 5e-301 * 3 = 1.5e-300, 1e-300 * 2 = 2e-300, 2e-300 * 1 -> running max 2e-300
    np.testing.assert_allclose(out, [2e-300, 2e-300, 1.5e-300], rtol=1e-14)
    sub = holm([5e-324, 1e-320, 0.5])
    assert np.all(sub > 0.0) and sub[0] <= sub[1] <= sub[2]


def test_holm_preserves_shape_and_accepts_series():
    p = np.array([[0.01, 0.02], [0.03, 0.04]])
    out = holm(p)
    assert out.shape == (2, 2)
    np.testing.assert_allclose(out.ravel(), holm(p.ravel()), rtol=0)
    s = holm(pd.Series([0.2, 0.01], index=["a", "b"]))
    assert isinstance(s, np.ndarray)
    np.testing.assert_allclose(s, [0.2, 0.02], rtol=1e-15)


@pytest.mark.parametrize("bad", [[-0.1], [1.1], [np.inf], [-np.inf], [0.5, 2.0, np.nan]])
def test_holm_rejects_out_of_range(bad):
    with pytest.raises(ValueError, match=r"must lie in \[0, 1\]"):
        holm(bad)


def test_holm_rejects_non_numbers():
    with pytest.raises(ValueError, match="only numbers"):
        holm(["a", 0.1])
    with pytest.raises(ValueError, match="array-like"):
        holm("0.1")


def test_adjust_pvalues_methods():
    p = [0.01, 0.02, 0.03]
    np.testing.assert_allclose(adjust_pvalues(p, "bonferroni"), [0.03, 0.06, 0.09], rtol=1e-15)
    np.testing.assert_allclose(adjust_pvalues(p, "fdr_bh"), [0.03, 0.03, 0.03], rtol=1e-15)
    np.testing.assert_allclose(adjust_pvalues(p, "none"), p, rtol=0)
    np.testing.assert_allclose(adjust_pvalues(p, "HOLM"), holm(p), rtol=0)
    with pytest.raises(ValueError, match="unknown p-value adjustment method"):
        adjust_pvalues(p, "sidak")


# --- dunn ----------------------------------------------------------------------------------------


def frame(groups, labels=None):
    labels = labels or [f"g{i}" for i in range(len(groups))]
    return pd.DataFrame(
        {"y": [v for g in groups for v in g], "cond": [lab for lab, g in zip(labels, groups) for _ in g]}
    )


@given(st.one_of(tied_values, float_values), st.one_of(tied_values, float_values))
def test_dunn_with_two_groups_is_kruskal(x, y):
    out = dunn(frame([x, y]), "y", "cond")
    kw = kruskal(x, y)
    assert len(out) == 1
    if kw.degenerate:  # all observations tied: not testable, as R's NA
        assert np.isnan(out.z.iloc[0]) and np.isnan(out.p_adj.iloc[0]) and out.note.iloc[0].startswith("not")
        return
    assert out.z.iloc[0] ** 2 == pytest.approx(kw.H, rel=1e-10, abs=1e-12)
    assert out.p_unc.iloc[0] == pytest.approx(kw.p, rel=1e-10, abs=1e-300)
    assert out.p_adj.iloc[0] == out.p_unc.iloc[0]


@given(groups_strategy)
def test_dunn_properties(groups):
    out = dunn(frame(groups), "y", "cond")
    k = len(groups)
    assert len(out) == k * (k - 1) // 2
    assert list(out.columns) == ["A", "B", "z", "p_unc", "p_adj", "note"]
    tied = out.note != ""
    ok = out[~tied]
    assert ((ok.p_unc >= 0) & (ok.p_unc <= 1) & (ok.p_adj >= ok.p_unc) & (ok.p_adj <= 1)).all()
    np.testing.assert_allclose(out.p_adj, holm(out.p_unc), rtol=0)  # NaN (untestable) left out of the count
    assert np.isfinite(ok.z).all() and out[tied][["z", "p_unc", "p_adj"]].isna().all().all()
    for row in out.itertuples():  # untestable exactly when the pair's observations are all one value
        pair = np.concatenate([groups[int(row.A[1:])], groups[int(row.B[1:])]])
        assert (row.note != "") == (pair.min() == pair.max())


def test_dunn_formula_by_hand():
    # ranks: g0 -> 1, 2, 3.5; g1 -> 3.5, 5; g2 -> 6, 7   (one tie of size 2), N = 7
    df = frame([[1.0, 2.0, 3.0], [3.0, 4.0], [5.0, 6.0]])
    out = dunn(df, "y", "cond", p_adjust="none")
    s2 = 7 * 8 / 12 - (2**3 - 2) / (12 * 6)
    z01 = (6.5 / 3 - 8.5 / 2) / math.sqrt(s2 * (1 / 3 + 1 / 2))
    assert out.z.iloc[0] == pytest.approx(z01, rel=1e-14)
    assert out.p_unc.iloc[0] == pytest.approx(math.erfc(abs(z01) / math.sqrt(2)), rel=1e-13)
    assert out.z.iloc[0] < 0  # g0 has the lower mean rank
    assert list(out.A) == ["g0", "g0", "g1"] and list(out.B) == ["g1", "g2", "g2"]


def test_dunn_constant_data_is_not_testable():
    out = dunn(frame([[2.0, 2.0], [2.0], [2.0, 2.0, 2.0]]), "y", "cond")
    assert out[["z", "p_unc", "p_adj"]].isna().all().all()
    assert (out.note == "not testable (all observations tied)").all()


def test_dunn_order_subset_and_nan_rows():
    df = frame([[1.0, 2.0, np.nan], [3.0, 4.0], [5.0, 6.0], [9.0]], ["a", "b", "c", "d"])
    df.loc[len(df)] = [100.0, None]  # missing label: dropped
    out = dunn(df, "y", "cond", order=["c", "a"])
    assert list(zip(out.A, out.B)) == [("c", "a")]
    expected = dunn(frame([[5.0, 6.0], [1.0, 2.0]], ["c", "a"]), "y", "cond", order=["c", "a"])
    pd.testing.assert_frame_equal(out, expected)
    assert out.z.iloc[0] > 0


def test_dunn_categorical_order():
    df = frame([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]], ["low", "mid", "high"])
    df["cond"] = pd.Categorical(df["cond"], categories=["high", "mid", "low", "unused"])
    out = dunn(df, "y", "cond")
    assert list(zip(out.A, out.B)) == [("high", "mid"), ("high", "low"), ("mid", "low")]


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(dv="nope", between="cond"), "dv='nope' is not a column"),
        (dict(dv="y", between="nope"), "between='nope' is not a column"),
        (dict(dv="y", between="cond", order=["g0", "zz"]), "condition 'zz' of 'cond' has no non-NaN"),
        (dict(dv="y", between="cond", order=["g0"]), "at least two conditions"),
        (dict(dv="y", between="cond", order=["g0", "g0"]), "duplicate levels"),
        (dict(dv="y", between="cond", p_adjust="tukey"), "unknown p-value adjustment"),
        (dict(dv="cond", between="y"), "column 'cond' must be numeric"),
        (dict(dv="y", between="y"), "different columns"),
    ],
)
def test_dunn_invalid(kwargs, message):
    df = frame([[1.0, 2.0], [3.0, 4.0]])
    with pytest.raises(ValueError, match=message):
        dunn(df, **kwargs)


def test_dunn_rejects_non_dataframe_and_single_condition():
    with pytest.raises(ValueError, match="must be a pandas DataFrame"):
        dunn({"y": [1.0]}, "y", "cond")
    with pytest.raises(ValueError, match="at least two conditions"):
        dunn(frame([[1.0, 2.0], [np.nan]]).dropna(), "y", "cond")


# --- pairwise_kruskal / pairwise_matrix ----------------------------------------------------------


@given(groups_strategy)
def test_pairwise_kruskal_is_kruskal_per_pair(groups):
    out = pairwise_kruskal(frame(groups), "y", "cond")
    assert list(out.columns) == ["A", "B", "H", "df", "p_unc", "p_adj", "n_A", "n_B", "note"]
    for row in out.itertuples():
        i, j = int(row.A[1:]), int(row.B[1:])
        res = kruskal(groups[i], groups[j])
        if res.degenerate:  # R: kruskal.test gives NaN; the pair is left out of the Holm count
            assert np.isnan(row.H) and np.isnan(row.p_unc) and row.note == "not testable (all observations tied)"
        else:
            assert (row.H, row.p_unc, row.df, row.note) == (res.H, res.p, 1, "")
        assert (row.n_A, row.n_B) == (len(groups[i]), len(groups[j]))
    np.testing.assert_allclose(out.p_adj, holm(out.p_unc), rtol=0)
    assert ((out.p_adj.dropna() >= 0) & (out.p_adj.dropna() <= 1)).all()


def test_pairwise_kruskal_degenerate_pair_and_dtypes():
    out = pairwise_kruskal(frame([[1.0, 1.0], [1.0], [2.0, 3.0]], ["a", "b", "c"]), "y", "cond")
    first = out.iloc[0]
    assert (first.A, first.B, first.note) == ("a", "b", "not testable (all observations tied)")
    assert np.isnan(first.H) and np.isnan(first.p_unc) and np.isnan(first.p_adj)
    # Holm counts the two testable pairs only
    np.testing.assert_allclose(out.p_adj.iloc[1:], holm(out.p_unc.iloc[1:].to_numpy()), rtol=0)
    assert out.dtypes["df"] == np.int64 and out.dtypes["n_A"] == np.int64
    assert out.dtypes["H"] == np.float64


def test_pairwise_kruskal_order_and_p_adjust():
    df = frame([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.5]], ["fov", "full", "low"])
    out = pairwise_kruskal(df, "y", "cond", order=["full", "fov", "low"], p_adjust="bonferroni")
    assert list(zip(out.A, out.B)) == [("full", "fov"), ("full", "low"), ("fov", "low")]
    np.testing.assert_allclose(out.p_adj, np.minimum(1, 3 * out.p_unc), rtol=1e-15)


def test_pairwise_matrix_layout():
    result = pd.DataFrame(
        {"A": ["a", "a", "c"], "B": ["b", "c", "b"], "p_adj": [0.0004, 0.04567, 1.0]}
    )  # ("c", "b") is stored reversed
    m = pairwise_matrix(result, order=["a", "b", "c"])
    expected = pd.DataFrame(
        [["/", "<0.001", "0.046"], ["/", "/", "1.000"], ["/", "/", "/"]],
        index=["a", "b", "c"],
        columns=["a", "b", "c"],
        dtype=object,
    )
    pd.testing.assert_frame_equal(m, expected)
    default = pairwise_matrix(result)  # order of first appearance: a, c, b
    assert list(default.index) == ["a", "c", "b"]
    assert default.loc["a", "c"] == "0.046" and default.loc["c", "b"] == "1.000"
    assert default.loc["c", "a"] == "/"


def test_pairwise_matrix_from_pairwise_kruskal_and_errors():
    df = frame([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [1.5, 2.5, 3.5]], ["x", "y", "z"])
    res = pairwise_kruskal(df, "y", "cond")
    m = pairwise_matrix(res, ["x", "y", "z"], column="p_unc", decimals=2)
    assert m.loc["x", "y"] == format_p(res.p_unc.iloc[0], 2)
    with pytest.raises(ValueError, match=r"pair \('x', 'w'\) is missing"):
        pairwise_matrix(res, ["x", "w"])
    with pytest.raises(ValueError, match="appears more than once"):
        pairwise_matrix(pd.concat([res, res]), ["x", "y"])
    with pytest.raises(ValueError, match="column='p' is not a column"):
        pairwise_matrix(res, ["x", "y"], column="p")


@pytest.mark.parametrize(
    "p, text",
    [(0.0, "<0.001"), (0.0005, "<0.001"), (0.000999, "<0.001"), (0.001, "0.001"), (0.0123, "0.012"),
     (0.05, "0.050"), (0.9996, "1.000"), (1.0, "1.000")],
)
def test_format_p(p, text):
    assert format_p(p) == text


@pytest.mark.parametrize("bad", [np.nan, -0.01, 1.5])
def test_format_p_rejects_non_p(bad):
    with pytest.raises(ValueError, match="p must be a number in"):
        format_p(bad)


# --- summary_table -------------------------------------------------------------------------------


def study_frame():
    return pd.DataFrame(
        {
            "subject": [1, 2, 3, 4] * 3,
            "cond": ["full"] * 4 + ["fov"] * 4 + ["low"] * 4,
            "score": [5.0, 6.0, 7.0, 6.5, 4.0, 5.5, 6.0, 5.0, 2.0, 3.0, np.nan, 2.5],
        }
    )


def test_summary_table_independent():
    df = study_frame()
    out = summary_table(df, "score", "cond", reference="full", order=["full", "fov", "low"])
    assert list(out.columns) == [
        "condition", "n", "mean", "std", "n_ref", "mean_ref", "std_ref", "p", "d", "label", "note"
    ]
    assert list(out.condition) == ["fov", "low"]
    ref = np.array([5.0, 6.0, 7.0, 6.5])
    for row, vals in zip(out.itertuples(), [np.array([4.0, 5.5, 6.0, 5.0]), np.array([2.0, 3.0, 2.5])]):
        assert row.n == vals.size and row.n_ref == 4
        assert row.mean == pytest.approx(vals.mean(), rel=1e-15)
        assert row.std == pytest.approx(vals.std(ddof=1), rel=1e-14)
        assert row.mean_ref == pytest.approx(ref.mean(), rel=1e-15)
        assert row.std_ref == pytest.approx(ref.std(ddof=1), rel=1e-14)
        assert row.p == pytest.approx(mann_whitney(vals, ref).p, rel=1e-15)
        assert row.d == pytest.approx(analysis.cohens_d(vals, ref), rel=1e-14)
        assert row.label == analysis.effect_size_label(row.d)
    assert out.d.iloc[1] < -2 and out.label.iloc[1] == "huge"


def test_summary_table_paired_uses_complete_subjects_and_dz():
    df = study_frame()
    out = summary_table(df, "score", "cond", reference="full", paired=True, subject="subject")
    assert list(out.condition) == ["fov", "low"]  # sorted labels, reference skipped
    low = out.iloc[1]
    assert low.n == 3 and low.n_ref == 3  # subject 3 has no 'low' score
    diff = np.array([2.0, 3.0, 2.5]) - np.array([5.0, 6.0, 6.5])
    assert low.d == pytest.approx(diff.mean() / diff.std(ddof=1), rel=1e-14)
    assert low.mean_ref == pytest.approx(np.mean([5.0, 6.0, 6.5]), rel=1e-15)


def test_summary_table_single_observation_has_nan_std_but_a_label():
    df = pd.DataFrame({"c": ["r", "r", "r", "x"], "v": [1.0, 2.0, 3.0, 10.0]})
    out = summary_table(df, "v", "c", reference="r")
    assert out.n.iloc[0] == 1 and np.isnan(out["std"].iloc[0])
    assert out.label.iloc[0] == "huge" and np.isfinite(out.d.iloc[0])


def test_summary_table_errors():
    df = study_frame()
    with pytest.raises(ValueError, match="reference 'none' has no non-NaN"):
        summary_table(df, "score", "cond", reference="none")
    with pytest.raises(ValueError, match="needs subject="):
        summary_table(df, "score", "cond", reference="full", paired=True)
    dup = pd.concat([df, df.iloc[[0]]])
    with pytest.raises(ValueError, match="subject 1 has more than one row for condition 'full'"):
        summary_table(dup, "score", "cond", reference="full", paired=True, subject="subject")
    with pytest.raises(ValueError, match="no condition other than the reference"):
        summary_table(df[df.cond == "full"], "score", "cond", reference="full")
    with pytest.raises(ValueError, match="condition 'zz' of 'cond' has no non-NaN"):
        summary_table(df, "score", "cond", reference="full", order=["fov", "zz"])


def test_summary_table_all_equal_gives_undefined_effect_and_untestable_p():
    # R: wilcox.test(c(4,4,4), c(4,4,4), exact=FALSE, correct=FALSE)$p.value is NaN; the pooled-SD d is 0/0.
    df = pd.DataFrame({"c": ["r"] * 3 + ["x"] * 3, "v": [4.0] * 6})
    row = summary_table(df, "v", "c", reference="r").iloc[0]
    assert np.isnan(row.p) and np.isnan(row.d) and row["std"] == 0.0
    assert (row.label, row.note) == ("undefined (zero SD)", "not testable (all observations tied)")


def test_summary_table_undefined_rows_never_abort():
    # constant but different groups (R: d = -Inf), one observation per group (R: NA), a normal row
    df = pd.DataFrame({"c": ["r", "r", "x", "x", "y", "z", "z", "z"],
                       "v": [1.0, 1.0, 2.0, 2.0, 5.0, 0.0, 1.0, 3.0]})
    out = summary_table(df, "v", "c", reference="r").set_index("condition")
    assert np.isnan(out.loc["x", "d"]) and out.loc["x", "label"] == "undefined (zero SD)"
    assert out.loc["x", "note"] == "" and 0.0 < out.loc["x", "p"] < 1.0  # the ranks still differ: testable
    assert out.loc["z", "label"] in ("very small", "small", "medium", "large", "very large", "huge")
    one = summary_table(df[df.c.isin(["r", "y"])].iloc[[0, 2]], "v", "c", reference="r").iloc[0]
    assert np.isnan(one.d) and one.label == "undefined (n1 + n2 - 2 = 0: no SD)"


def test_public_api_exports():
    for name in [
        "kruskal", "mann_whitney", "holm", "adjust_pvalues", "dunn", "pairwise_kruskal", "pairwise_matrix",
        "format_p", "summary_table", "cohens_d", "hedges_g", "effect_size_label", "bootstrap_ci_d",
    ]:
        assert callable(getattr(analysis, name)) and name in analysis.__all__
    assert analysis.stats.kruskal is analysis.kruskal and analysis.stats.holm is analysis.holm


def test_docstring_examples_run():
    import doctest

    import analysis.effect_size
    import analysis.multicomp
    import analysis.stats

    for module in (analysis.stats, analysis.effect_size, analysis.multicomp):
        result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
        assert result.failed == 0 and result.attempted >= 1, module.__name__


def test_import_is_light():
    import subprocess
    import sys

    code = "import sys, analysis; print('scipy.stats' in sys.modules, 'statsmodels' in sys.modules)"
    root = __import__("pathlib").Path(__file__).resolve().parent.parent
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=root)
    assert out.stdout.split() == ["False", "False"]
