"""Thurstone (JOD), Bradley-Terry and Plackett-Luce scaling (analysis.scaling)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy import special

from analysis.scaling import JOD_SIGMA, bradley_terry, plackett_luce, thurstone_jod

TRUE = np.array([0.0, 0.5, 1.0, 2.0])
N_PAIRS = 6  # 4 conditions -> 6 unordered pairs


def _pairwise_sample(true, n, link, seed, observers=0):
    rng = np.random.default_rng(seed)
    k = len(true)
    a = rng.integers(0, k, n)
    b = (a + rng.integers(1, k, n)) % k
    d = true[a] - true[b]
    p = special.ndtr(d / JOD_SIGMA) if link == "probit" else special.expit(d)
    # selection: 1 = condition_1 chosen, 2 = condition_2 chosen (pwcmp export layout)
    df = pd.DataFrame({"condition_1": a, "condition_2": b, "selection": np.where(rng.random(n) < p, 1, 2)})
    if observers:
        df["observer"] = rng.integers(0, observers, n)
    return df


def _tiny(n_a=75, n=100):
    return pd.DataFrame(
        {"condition_1": ["a"] * n, "condition_2": ["b"] * n, "selection": [1] * n_a + [2] * (n - n_a)}
    )


def _pl_sample(true, n, seed, p_second=0.7, as_string=True):
    rng = np.random.default_rng(seed)
    k = len(true)
    rows = []
    for _ in range(n):
        m = int(rng.integers(2, k + 1))
        opts = [int(o) for o in rng.choice(k, m, replace=False)]
        g = true[opts] + rng.gumbel(size=m)
        order = [opts[i] for i in np.argsort(-g)]
        second = f"c{order[1]}" if rng.random() < p_second else np.nan
        labels = [f"c{o}" for o in opts]
        rows.append(
            {"options": "|".join(labels) if as_string else labels, "first": f"c{order[0]}", "second": second}
        )
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------- constants


def test_jod_sigma_is_75_percent():
    assert JOD_SIGMA == pytest.approx(1.4826, abs=1e-4)
    assert special.ndtr(1.0 / JOD_SIGMA) == pytest.approx(0.75, abs=1e-12)


# ----------------------------------------------------------------------------- exact tiny cases


def test_thurstone_75_of_100_is_one_jod():
    out = thurstone_jod(_tiny(), reference="b")
    assert list(out.columns) == ["condition", "jod", "n_comparisons"]
    assert out["condition"].tolist() == ["a", "b"]
    assert out["jod"].iloc[0] == pytest.approx(1.0, abs=1e-3)  # prior shrinks by ~4e-4
    assert out["jod"].iloc[1] == 0.0
    assert out["n_comparisons"].tolist() == [100, 100]
    # default reference: first in sorted order
    default = thurstone_jod(_tiny())
    assert default["jod"].tolist() == pytest.approx([0.0, -out["jod"].iloc[0]], abs=1e-9)


def test_bradley_terry_75_of_100_is_ln3():
    out = bradley_terry(_tiny(), reference="b")
    assert list(out.columns) == ["condition", "score", "n_comparisons"]
    assert out["score"].iloc[0] == pytest.approx(np.log(3.0), abs=1e-3)


def test_no_prior_gives_exact_mle():
    assert thurstone_jod(_tiny(), reference="b", prior_sd=np.inf)["jod"].iloc[0] == pytest.approx(
        1.0, abs=1e-7
    )
    assert bradley_terry(_tiny(), reference="b", prior_sd=np.inf)["score"].iloc[0] == pytest.approx(
        np.log(3.0), abs=1e-7
    )


def test_prior_shrinks_towards_zero():
    weak = thurstone_jod(_tiny(), reference="b")["jod"].iloc[0]
    strong = thurstone_jod(_tiny(), reference="b", prior_sd=0.5)["jod"].iloc[0]
    assert 0.0 < strong < weak < 1.0


def test_selection_float_and_swapped_columns_agree():
    df = _tiny()
    as_float = df.assign(selection=df["selection"].astype(float))
    swapped = pd.DataFrame(
        {"condition_1": df["condition_2"], "condition_2": df["condition_1"], "selection": 3 - df["selection"]}
    )
    ref = thurstone_jod(df)
    pd.testing.assert_frame_equal(thurstone_jod(as_float), ref)
    np.testing.assert_allclose(thurstone_jod(swapped)["jod"], ref["jod"], atol=1e-9)


def test_reference_only_shifts_scores():
    df = _pairwise_sample(TRUE, 600, "probit", seed=3)
    r0 = thurstone_jod(df, reference=0)["jod"].to_numpy()
    r2 = thurstone_jod(df, reference=2)["jod"].to_numpy()
    np.testing.assert_allclose(r2, r0 - r0[2], atol=1e-7)


# ----------------------------------------------------------------------------- recovery


def test_thurstone_recovers_known_scale():
    n = 3000
    out = thurstone_jod(_pairwise_sample(TRUE, n, "probit", seed=11))
    # worst-case SE of a direct pair difference: sigma * sqrt(p(1-p)) / phi(0) / sqrt(n_pair) at p = 0.5
    tol = 4 * JOD_SIGMA * np.sqrt(np.pi / 2) / np.sqrt(n / N_PAIRS)
    np.testing.assert_allclose(out["jod"], TRUE, atol=tol)
    assert out["n_comparisons"].sum() == 2 * n


def test_bradley_terry_recovers_known_scale():
    n = 3000
    true = TRUE * np.log(3.0)  # the same scale in logits
    out = bradley_terry(_pairwise_sample(true, n, "logit", seed=12))
    p_min = special.expit(true.max() - true.min())
    tol = 4 / np.sqrt(n / N_PAIRS * p_min * (1 - p_min))
    np.testing.assert_allclose(out["score"], true, atol=tol)


def test_plackett_luce_recovers_known_scale():
    n = 2000
    true = TRUE * np.log(3.0)
    out = plackett_luce(_pl_sample(true, n, seed=13))
    assert out["condition"].tolist() == ["c0", "c1", "c2", "c3"]
    tol = 4 / np.sqrt(n / N_PAIRS * 0.09)
    np.testing.assert_allclose(out["score"], true, atol=tol)
    assert out["score"].is_monotonic_increasing


# ----------------------------------------------------------------------------- unanimous data


def test_unanimous_pairs_stay_finite():
    df = _tiny(n_a=20, n=20)
    jod = thurstone_jod(df)["jod"].to_numpy()
    bt = bradley_terry(df)["score"].to_numpy()
    assert np.all(np.isfinite(jod)) and np.all(np.isfinite(bt))
    assert 2.0 < -jod[1] < 10.0 and 2.0 < -bt[1] < 15.0
    # a complete, unanimous order of three conditions stays finite and ordered
    chain = pd.DataFrame(
        {"condition_1": ["a", "b", "a"] * 10, "condition_2": ["b", "c", "c"] * 10, "selection": [1] * 30}
    )
    out = thurstone_jod(chain, n_boot=20)
    assert np.all(np.isfinite(out[["jod", "ci_low", "ci_high"]].to_numpy()))
    assert out["jod"].iloc[0] > out["jod"].iloc[1] > out["jod"].iloc[2]


def test_unanimous_plackett_luce_stays_finite():
    df = pd.DataFrame({"options": ["x|y|z"] * 10, "first": ["x"] * 10, "second": ["y"] * 10})
    out = plackett_luce(df, reference="z")
    assert np.all(np.isfinite(out["score"]))
    assert out["score"].iloc[0] > out["score"].iloc[1] > 0.0


# ----------------------------------------------------------------------------- bootstrap


def test_bootstrap_ci_contains_estimate_and_is_reproducible():
    df = _pairwise_sample(TRUE, 800, "probit", seed=21)
    a = thurstone_jod(df, n_boot=150, seed=5)
    b = thurstone_jod(df, n_boot=150, seed=5)
    c = thurstone_jod(df, n_boot=150, seed=6)
    assert list(a.columns) == ["condition", "jod", "ci_low", "ci_high", "n_comparisons"]
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    assert a.to_numpy().tobytes() == b.to_numpy().tobytes()
    assert not np.array_equal(a["ci_low"], c["ci_low"])
    assert np.all(a["ci_low"] <= a["jod"]) and np.all(a["jod"] <= a["ci_high"])
    assert a["ci_low"].iloc[0] == a["ci_high"].iloc[0] == 0.0  # the reference is fixed
    assert np.all(a["ci_high"].iloc[1:] - a["ci_low"].iloc[1:] > 0.05)
    assert not a.isna().any().any()
    # without n_boot the point estimate is unchanged
    np.testing.assert_array_equal(thurstone_jod(df)["jod"], a["jod"])


def test_bootstrap_resamples_observers_when_present():
    df = _pairwise_sample(TRUE, 800, "probit", seed=22, observers=8)
    by_obs = bradley_terry(df, n_boot=100, seed=1)
    by_row = bradley_terry(df, n_boot=100, seed=1, observer=None)
    assert not np.array_equal(by_obs["ci_low"], by_row["ci_low"])
    pd.testing.assert_frame_equal(by_obs, bradley_terry(df, n_boot=100, seed=1), check_exact=True)
    assert np.all(by_obs["ci_low"] <= by_obs["score"]) and np.all(by_obs["score"] <= by_obs["ci_high"])


def test_plackett_luce_bootstrap():
    df = _pl_sample(TRUE, 300, seed=23)
    a = plackett_luce(df, n_boot=50, seed=2)
    pd.testing.assert_frame_equal(a, plackett_luce(df, n_boot=50, seed=2), check_exact=True)
    assert list(a.columns) == ["condition", "score", "ci_low", "ci_high", "n_first", "n_second", "n_offered"]
    assert np.all(a["ci_low"] <= a["score"]) and np.all(a["score"] <= a["ci_high"])


# ----------------------------------------------------------------------------- Plackett-Luce specifics


def test_plackett_luce_two_options_is_bradley_terry():
    pw = _pairwise_sample(TRUE, 500, "logit", seed=31)
    winner = np.where(pw["selection"] == 1, pw["condition_1"], pw["condition_2"])  # 2: condition_2 chosen
    pl_df = pd.DataFrame(
        {"options": [(a, b) for a, b in zip(pw["condition_1"], pw["condition_2"])], "first": winner}
    )
    pl = plackett_luce(pl_df, ranking_cols=("first",))
    bt = bradley_terry(pw)
    np.testing.assert_allclose(pl["score"], bt["score"], atol=1e-6)
    assert pl["n_second"].sum() == 0
    # a second choice out of two options carries no information
    pl_df["second"] = [a if a != w else b for a, b, w in zip(pw["condition_1"], pw["condition_2"], winner)]
    np.testing.assert_allclose(plackett_luce(pl_df)["score"], bt["score"], atol=1e-6)


def test_plackett_luce_first_choice_is_multinomial_logit():
    counts = {"a": 10, "b": 30, "c": 60}
    firsts = [c for c, k in counts.items() for _ in range(k)]
    df = pd.DataFrame({"options": [["a", "b", "c"]] * 100, "first": firsts, "second": [None] * 100})
    exact = plackett_luce(df, prior_sd=np.inf)
    np.testing.assert_allclose(exact["score"], [0.0, np.log(3.0), np.log(6.0)], atol=1e-6)
    regular = plackett_luce(df)
    np.testing.assert_allclose(regular["score"], exact["score"], atol=0.05)
    assert regular["n_first"].tolist() == [10, 30, 60]
    assert regular["n_second"].tolist() == [0, 0, 0]
    assert regular["n_offered"].tolist() == [100, 100, 100]


def test_plackett_luce_top_two_counts_and_option_formats():
    as_str = _pl_sample(TRUE, 200, seed=41)
    as_list = _pl_sample(TRUE, 200, seed=41, as_string=False)
    a, b = plackett_luce(as_str), plackett_luce(as_list)
    pd.testing.assert_frame_equal(a, b)
    assert a["n_first"].sum() == 200
    assert a["n_second"].sum() == as_str["second"].notna().sum()


def test_plackett_luce_second_choice_informs():
    # x always first; second choice y over z in every trial -> y above z
    df = pd.DataFrame({"options": ["x|y|z"] * 20, "first": ["x"] * 20, "second": ["y"] * 15 + ["z"] * 5})
    out = plackett_luce(df, reference="z")  # weak prior: x stays finite, y - z shrinks by ~0.012
    assert out.loc[out["condition"] == "y", "score"].item() == pytest.approx(np.log(3.0), abs=0.02)
    # without a prior x's score is +inf: refused, not returned as a large unconverged number
    with pytest.raises(ValueError, match="maximum-likelihood scale does not exist"):
        plackett_luce(df, prior="none", reference="z")


# ----------------------------------------------------------------------------- invariance (hypothesis)


_BASE_PW = _pairwise_sample(TRUE, 120, "probit", seed=51)
_BASE_PL = _pl_sample(TRUE, 80, seed=52)


@given(st.randoms(use_true_random=False))
def test_scores_invariant_to_row_order(rnd):
    perm = list(range(len(_BASE_PW)))
    rnd.shuffle(perm)
    shuffled = _BASE_PW.iloc[perm]
    np.testing.assert_allclose(thurstone_jod(shuffled)["jod"], thurstone_jod(_BASE_PW)["jod"], atol=1e-9)
    np.testing.assert_allclose(bradley_terry(shuffled)["score"], bradley_terry(_BASE_PW)["score"], atol=1e-9)
    perm_pl = list(range(len(_BASE_PL)))
    rnd.shuffle(perm_pl)
    np.testing.assert_allclose(
        plackett_luce(_BASE_PL.iloc[perm_pl])["score"], plackett_luce(_BASE_PL)["score"], atol=1e-9
    )


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("func", [thurstone_jod, bradley_terry])
def test_pairwise_bad_input(func):
    df = _tiny()
    with pytest.raises(ValueError, match="missing column"):
        func(df.drop(columns="selection"))
    with pytest.raises(ValueError, match="DataFrame"):
        func(df.to_dict())
    with pytest.raises(ValueError, match=r"must hold 1 \(condition_1 chosen\) or 2.*row 0 has 0 \(a 0/1"):
        func(df.assign(selection=[0] + [1] * 99))
    with pytest.raises(ValueError, match="row 0 has True"):
        func(df.assign(selection=[True] * 100))
    with pytest.raises(ValueError, match="row 3 has 3"):
        func(df.assign(selection=[1, 2, 1, 3] + [1] * 96))
    with pytest.raises(ValueError, match="must hold 1"):
        func(df.assign(selection=["a"] * 100))
    with pytest.raises(ValueError, match="prior='pwcmp' is invalid here" if func is bradley_terry else "prior="):
        func(df, prior="pwcmp" if func is bradley_terry else "strong")
    with pytest.raises(ValueError, match="itself"):
        func(df.assign(condition_2="a"))
    with pytest.raises(ValueError, match="at least two conditions"):
        func(df.iloc[:0])
    with pytest.raises(ValueError, match="reference"):
        func(df, reference="zzz")
    with pytest.raises(ValueError, match="disconnected"):
        func(pd.concat([df, df.replace({"a": "c", "b": "d"})], ignore_index=True))
    with pytest.raises(ValueError, match="ci"):
        func(df, n_boot=10, ci=1.5)
    with pytest.raises(ValueError, match="n_boot"):
        func(df, n_boot=-1)
    with pytest.raises(ValueError, match="prior_sd"):
        func(df, prior_sd=0.0)


def test_pairwise_nan_rows_are_dropped():
    df = _tiny()
    with_nan = pd.concat(
        [df, pd.DataFrame({"condition_1": ["a"], "condition_2": ["b"], "selection": [np.nan]})]
    )
    pd.testing.assert_frame_equal(thurstone_jod(with_nan), thurstone_jod(df))


def test_plackett_luce_bad_input():
    ok = pd.DataFrame({"options": ["x|y|z", "x|y"], "first": ["x", "y"], "second": ["y", np.nan]})
    plackett_luce(ok)  # sanity
    with pytest.raises(ValueError, match="missing column"):
        plackett_luce(ok.drop(columns="options"))
    with pytest.raises(ValueError, match="not among"):
        plackett_luce(ok.assign(first=["w", "y"]))
    with pytest.raises(ValueError, match="twice"):
        plackett_luce(ok.assign(second=["x", np.nan]))
    with pytest.raises(ValueError, match="after a missing"):
        plackett_luce(
            ok.assign(second=[np.nan, np.nan], third=["y", np.nan]), ranking_cols=("first", "second", "third")
        )
    with pytest.raises(ValueError, match="at least two"):
        plackett_luce(ok.assign(options=["x", "x|y"], second=[np.nan, np.nan]))
    with pytest.raises(ValueError, match="disconnected"):
        plackett_luce(pd.DataFrame({"options": ["x|y", "u|v"], "first": ["x", "u"], "second": [np.nan] * 2}))
    with pytest.raises(ValueError, match="at least two conditions"):
        plackett_luce(ok.iloc[:0])
