"""Cohen's d, Hedges' g, Sawilowsky labels and the bootstrap CI (analysis.effect_size).

R reference values for d, g and d_z are in test_analysis_r_reference.py; here the checks
are the defining formulas, invariances and edge cases.
"""

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from analysis import SAWILOWSKY_BINS, BootstrapCI, bootstrap_ci_d, cohens_d, effect_size_label, hedges_g
from analysis.effect_size import _quantile_linear, d_with_reason

sample = st.lists(st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False), min_size=2, max_size=15)


def pooled_d(x, y):
    x, y = np.asarray(x, float), np.asarray(y, float)
    n1, n2 = x.size, y.size
    sp = math.sqrt(((n1 - 1) * x.var(ddof=1) + (n2 - 1) * y.var(ddof=1)) / (n1 + n2 - 2))
    return (x.mean() - y.mean()) / sp


# --- cohens_d ------------------------------------------------------------------------------------


def test_cohens_d_textbook_example():
    # means 2 and 4, both SDs 1 (ddof = 1): d = -2
    assert cohens_d([1.0, 2.0, 3.0], [3.0, 4.0, 5.0]) == pytest.approx(-2.0, rel=1e-15)
    # unequal n: s1^2 = 1, s2^2 = 2.5 -> sp = sqrt((2*1 + 4*2.5)/6) = sqrt(2)
    assert cohens_d([1.0, 2.0, 3.0], [1.0, 2.0, 3.0, 4.0, 5.0]) == pytest.approx(-1 / math.sqrt(2), rel=1e-15)


@given(sample, sample)
def test_cohens_d_matches_formula_and_is_antisymmetric(x, y):
    assume(np.var(x) > 1e-6 or np.var(y) > 1e-6)
    d = cohens_d(x, y)
    assert d == pytest.approx(pooled_d(x, y), rel=1e-9, abs=1e-12)
    assert cohens_d(y, x) == pytest.approx(-d, rel=1e-12, abs=1e-15)


@given(sample, sample, st.floats(0.01, 100), st.floats(-100, 100))
def test_cohens_d_affine_invariant(x, y, scale, shift):
    assume(np.ptp(x) > 1e-3 and np.ptp(y) > 1e-3)
    d = cohens_d(x, y)
    d2 = cohens_d(np.asarray(x) * scale + shift, np.asarray(y) * scale + shift)
    assert d2 == pytest.approx(d, rel=1e-7, abs=1e-9)


def test_cohens_d_paired_is_dz():
    x = [5.0, 6.0, 7.0, 6.5]
    y = [4.0, 5.5, 6.0, 5.0]
    diff = np.subtract(x, y)
    assert cohens_d(x, y, paired=True) == pytest.approx(diff.mean() / diff.std(ddof=1), rel=1e-15)
    assert cohens_d(x, y, paired=True) != pytest.approx(cohens_d(x, y))


def test_cohens_d_nan_policy():
    with_nan = cohens_d([1.0, np.nan, 2.0, 3.0], [3.0, 4.0, 5.0, np.nan])
    assert with_nan == cohens_d([1.0, 2.0, 3.0], [3.0, 4.0, 5.0])
    # paired: the whole pair is dropped when either member is NaN
    assert cohens_d([1.0, 2.0, np.nan, 4.0, 9.0], [0.5, np.nan, 2.0, 3.0, 7.0], paired=True) == cohens_d(
        [1.0, 4.0, 9.0], [0.5, 3.0, 7.0], paired=True
    )


def test_cohens_d_zero_pooled_sd_follows_r():
    # R: (mean(x) - mean(y)) / sqrt(((n1-1)*var(x) + (n2-1)*var(y)) / (n1+n2-2)) is 0/0 = NaN for two identical
    # constant groups (pingouin's compute_effsize too) and +-Inf for constant but different groups.
    assert np.isnan(cohens_d([2.0, 2.0], [2.0, 2.0, 2.0]))
    assert np.isnan(cohens_d([0.1] * 7, [0.1] * 3))  # no rounding noise from the mean of 0.1s
    assert cohens_d([1.0, 1.0], [2.0, 2.0]) == -np.inf
    assert cohens_d([3.0, 4.0, 5.0], [1.0, 2.0, 3.0], paired=True) == np.inf  # constant differences
    assert np.isnan(cohens_d([3.0, 4.0], [3.0, 4.0], paired=True))
    assert d_with_reason([2.0, 2.0], [2.0, 2.0, 2.0])[1] == "undefined (zero SD)"
    assert d_with_reason([1.0, 1.0], [2.0, 2.0])[1] == "undefined (zero SD)"
    assert d_with_reason([1.0, 2.0], [2.0, 4.0]) == (cohens_d([1.0, 2.0], [2.0, 4.0]), None)
    assert np.isnan(hedges_g([2.0, 2.0], [2.0, 2.0]))


def test_cohens_d_size_one_groups():
    # n1 = 1 contributes nothing to the pooled SS: sp = sd(y)
    assert cohens_d([10.0], [1.0, 2.0, 3.0]) == pytest.approx(8.0, rel=1e-15)
    # n1 + n2 - 2 = 0: no SD at all (R: NA)
    assert d_with_reason([1.0], [2.0])[1] == "undefined (n1 + n2 - 2 = 0: no SD)"
    assert np.isnan(cohens_d([1.0, np.nan], [np.nan, 2.0]))
    assert d_with_reason([1.0, np.nan], [2.0, 3.0], paired=True)[1] == "undefined (fewer than 2 complete pairs)"
    with pytest.raises(ValueError, match="both samples need observations"):
        cohens_d([], [1.0, 2.0, 3.0])


@pytest.mark.parametrize(
    "x, y, kwargs, message",
    [
        ([1.0, 2.0], [1.0, 2.0, 3.0], dict(paired=True), "equal length"),
        ([1.0, np.inf], [1.0, 2.0], {}, "must be finite"),
        ([1.0, np.inf], [1.0, 2.0], dict(paired=True), "must be finite"),
        ("ab", [1.0, 2.0], {}, "x must be a 1-D"),
        ([[1.0, 2.0]], [1.0, 2.0], {}, "x must be 1-D"),
    ],
)
def test_cohens_d_invalid(x, y, kwargs, message):
    with pytest.raises(ValueError, match=message):
        cohens_d(x, y, **kwargs)


# --- hedges_g ------------------------------------------------------------------------------------


@given(sample, sample)
def test_hedges_g_is_corrected_d(x, y):
    assume(np.ptp(x) > 1e-6 or np.ptp(y) > 1e-6)
    d = cohens_d(x, y)
    n = len(x) + len(y)
    g = hedges_g(x, y)
    assert g == pytest.approx(d * (1 - 3 / (4 * n - 9)), rel=1e-14, abs=1e-300)
    assert abs(g) <= abs(d)


def test_hedges_g_values_and_errors():
    # n1 = n2 = 3: J = 1 - 3/(4*6 - 9) = 0.8
    assert hedges_g([1.0, 2.0, 3.0], [3.0, 4.0, 5.0]) == pytest.approx(-1.6, rel=1e-15)
    assert hedges_g([1.0, 1.0], [2.0, 2.0]) == -np.inf  # zero pooled SD, different means: as cohens_d


# --- effect_size_label ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "d, label", [(0.15, "very small"), (0.53, "medium"), (0.92, "large"), (1.62, "very large")]
)
def test_labels_of_seed_tables(d, label):
    # Values and labels as printed in the VaFR / lightcuts tables.
    assert effect_size_label(d) == label
    assert effect_size_label(-d) == label


@pytest.mark.parametrize(
    "d, label",
    [
        (0.0, "very small"), (0.005, "very small"), (0.01, "very small"), (0.1999999, "very small"),
        (0.2, "small"), (0.4999, "small"), (0.5, "medium"), (0.7999, "medium"), (0.8, "large"),
        (1.1999, "large"), (1.2, "very large"), (1.9999, "very large"), (2.0, "huge"), (37.0, "huge"),
        (-2.0, "huge"), (np.inf, "huge"), (-np.inf, "huge"), (np.float32(0.6), "medium"), (1, "large"),
    ],
)
def test_label_bin_edges(d, label):
    assert effect_size_label(d) == label


def test_labels_vectorised():
    d = np.array([[0.1, -0.3], [0.6, 2.5]])
    out = effect_size_label(d)
    assert out.shape == (2, 2) and out.dtype == object
    assert out.tolist() == [["very small", "small"], ["medium", "huge"]]
    s = pd.Series([0.9, -1.3], index=["fov", "low"], name="d")
    ls = effect_size_label(s)
    assert isinstance(ls, pd.Series) and list(ls.index) == ["fov", "low"] and ls.name == "d"
    assert ls.tolist() == ["large", "very large"]
    assert effect_size_label([]).shape == (0,)
    assert isinstance(effect_size_label(np.float64(0.3)), str)


@pytest.mark.parametrize("bad", [np.nan, float("nan"), [0.5, np.nan], pd.Series([0.1, None])])
def test_no_label_for_nan(bad):
    with pytest.raises(ValueError, match="NaN"):
        effect_size_label(bad)


@pytest.mark.parametrize("bad", ["0.5", None, True, ["a"]])
def test_label_rejects_non_numbers(bad):
    with pytest.raises(ValueError, match="must be a number|must be numeric"):
        effect_size_label(bad)


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_label_never_for_nan_and_monotone(d):
    names = [label for _, label in SAWILOWSKY_BINS]
    if math.isnan(d):
        with pytest.raises(ValueError):
            effect_size_label(d)
        return
    label = effect_size_label(d)
    assert label in names
    lower = effect_size_label(abs(d) / 2)
    assert names.index(lower) <= names.index(label)
    edge = max(e for e, _ in SAWILOWSKY_BINS if e <= abs(d))
    assert dict((lab, e) for e, lab in SAWILOWSKY_BINS)[label] == edge


# --- bootstrap_ci_d ------------------------------------------------------------------------------


def test_bootstrap_reproducible_and_seed_dependent():
    rng = np.random.default_rng(1)
    x, y = rng.normal(0.5, 1, 30), rng.normal(0, 1, 25)
    a = bootstrap_ci_d(x, y, n_boot=500, seed=3)
    b = bootstrap_ci_d(x, y, n_boot=500, seed=3)
    c = bootstrap_ci_d(x, y, n_boot=500, seed=4)
    assert isinstance(a, BootstrapCI)
    assert a == b
    assert (a.low, a.high) != (c.low, c.high)
    assert a.d == pytest.approx(cohens_d(x, y), rel=1e-14)
    assert a.low < a.d < a.high
    assert (a.ci, a.n_boot) == (0.95, 500)


def test_bootstrap_matches_explicit_resampling_loop():
    # Same draws as the implementation (x then y per chunk; one chunk here): percentile CI by hand.
    x = np.array([1.0, 2.5, 3.0, 4.5, 2.0, 3.3])
    y = np.array([0.5, 1.0, 2.0, 1.5, 0.7])
    n_boot = 300
    rng = np.random.default_rng(11)
    ix = rng.integers(0, x.size, size=(n_boot, x.size))
    iy = rng.integers(0, y.size, size=(n_boot, y.size))
    boots = []
    for r in range(n_boot):
        bx, by = x[ix[r]], y[iy[r]]
        try:
            boots.append(cohens_d(bx, by))
        except ValueError:  # zero pooled SD with different means
            boots.append(math.copysign(math.inf, bx.mean() - by.mean()))
    lo, hi = np.quantile(np.array(boots), [0.05, 0.95]) if np.isfinite(boots).all() else (None, None)
    res = bootstrap_ci_d(x, y, n_boot=n_boot, ci=0.90, seed=11)
    assert lo is not None
    assert res.low == pytest.approx(lo, rel=1e-12) and res.high == pytest.approx(hi, rel=1e-12)


def test_bootstrap_close_to_normal_theory_for_large_samples():
    rng = np.random.default_rng(2024)
    n = 400
    x, y = rng.normal(0.5, 1, n), rng.normal(0.0, 1, n)
    res = bootstrap_ci_d(x, y, n_boot=2000, seed=0)
    d = res.d
    se = math.sqrt(2 / n + d**2 / (4 * n))  # Hedges & Olkin (1985) large-sample SE
    assert res.low == pytest.approx(d - 1.96 * se, abs=0.03)
    assert res.high == pytest.approx(d + 1.96 * se, abs=0.03)


def test_bootstrap_paired():
    x = np.array([5.0, 6.0, 7.0, 6.5, 5.5, 6.2, 7.1, 5.9])
    y = x - np.array([0.5, 0.4, 1.0, 0.2, 0.8, 0.3, 0.9, 0.6])
    res = bootstrap_ci_d(x, y, n_boot=400, seed=5, paired=True)
    assert res.d == pytest.approx(cohens_d(x, y, paired=True), rel=1e-14)
    assert 0 < res.low < res.d < res.high


def test_bootstrap_degenerate_resamples_give_no_nan():
    # Tiny, tied samples: some resamples have zero pooled SD with different means (d* = +inf).
    res = bootstrap_ci_d([0.0, 0.0, 1.0], [1.0, 1.0, 2.0], n_boot=200, seed=0)
    assert not math.isnan(res.low) and not math.isnan(res.high)
    assert res.low <= res.d <= res.high
    assert res.low == -math.inf  # more than 2.5 % of resamples are all-0 vs all-1: d* = -inf


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(n_boot=0), "n_boot must be a positive integer"),
        (dict(n_boot=2.5), "n_boot must be a positive integer"),
        (dict(ci=1.0), "ci must be a number strictly between 0 and 1"),
        (dict(ci=0.0), "ci must be a number strictly between 0 and 1"),
        (dict(seed="a"), "seed must be an integer"),
    ],
)
def test_bootstrap_invalid_arguments(kwargs, message):
    with pytest.raises(ValueError, match=message):
        bootstrap_ci_d([1.0, 2.0, 3.0], [2.0, 3.0, 5.0], **kwargs)


def test_bootstrap_refuses_an_undefined_d():
    with pytest.raises(ValueError, match=r"undefined \(zero SD\): no bootstrap interval"):
        bootstrap_ci_d([1.0, 1.0], [2.0, 2.0])
    with pytest.raises(ValueError, match="fewer than 2 complete pairs"):
        bootstrap_ci_d([1.0], [2.0], paired=True)


@given(st.lists(st.floats(-1e6, 1e6), min_size=1, max_size=40), st.floats(0, 1))
def test_quantile_linear_matches_numpy_on_finite_data(values, q):
    s = np.sort(np.array(values))
    assert _quantile_linear(s, q) == pytest.approx(np.quantile(s, q), rel=1e-12, abs=1e-9)


def test_quantile_linear_with_infinities():
    s = np.array([-np.inf, -np.inf, 0.0, 1.0, np.inf])
    assert _quantile_linear(s, 0.0) == -np.inf
    assert _quantile_linear(s, 0.3) == -np.inf  # between -inf and 0
    assert _quantile_linear(s, 0.5) == 0.0
    assert _quantile_linear(s, 0.9) == np.inf
    assert _quantile_linear(s, 0.7) == pytest.approx(0.8, rel=1e-15)
