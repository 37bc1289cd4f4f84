"""Psychometric fits of threshold data (analysis/thresholds.py): values on known-truth data, not-estimable rows,
agreement with psignifit's own fit, the group table, the Pareto table, byte-stable figures."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from analysis.thresholds import (
    FIT_COLUMNS,
    POOLED,
    FitSettings,
    detection,
    fit_one,
    fit_thresholds,
    group_table,
    pareto,
    psychometric,
)
from data_schema.intensity import Axis

VAFR = Axis("log", "lower", (0.1, 1.0))
LAFR = Axis("log", "higher", (0.5, 5.0))


def _trials(truth: dict, participants: int, n: int, seed: int = 0, scenes=("temple",)) -> pd.DataFrame:
    """Trials at levels spread over each axis' domain, answered by a logistic psychometric function whose level
    at 75 % correct is ``truth[condition]`` (2AFC, lapse 0.02, width 0.5 log10 units)."""
    rng = np.random.default_rng(seed)
    axes = {"VaFR": VAFR, "LaFR": LAFR}
    rows = []
    for p in range(participants):
        for cond, t in truth.items():
            ax = axes[cond]
            ladder = np.geomspace(*ax.bounds, 9)
            for s in scenes:
                lv = rng.choice(ladder, n)
                pc = psychometric(ax.to_intensity(lv), float(ax.to_intensity(t)), 0.5, 0.5, 0.02, 0.75)
                for level, q in zip(lv, pc):
                    rows.append({"participant": f"P{p:02d}", "condition": cond, "scene": s, "level": float(level),
                                 "correct": int(rng.random() < q), "varied": "x"})
    return pd.DataFrame(rows)


def test_pooled_fit_recovers_the_threshold_at_the_criterion_and_its_interval_covers_it():
    truth = {"VaFR": 0.35, "LaFR": 1.6}
    df = _trials(truth, participants=4, n=80)
    fits = fit_thresholds(df, criterion=0.75, experiment_type="2AFC", axes={"VaFR": VAFR, "LaFR": LAFR})
    assert list(fits.columns) == list(FIT_COLUMNS)
    pooled = fits[fits["participant"] == POOLED].set_index("condition")
    for cond, t in truth.items():
        r = pooled.loc[cond]
        assert r["estimable"] and r["reason"] == ""
        assert abs(math.log10(r["threshold"]) - math.log10(t)) < 0.08
        assert r["ci_low"] < t < r["ci_high"]  # level units: a "lower" axis keeps low < high
        assert r["n_trials"] == 320 and r["guess"] == 0.5
    # per participant: every fit estimable, the interval ordered and wider than the pooled one
    per = fits[fits["participant"] != POOLED]
    assert len(per) == 8 and per["estimable"].all()
    assert (per["ci_low"] < per["threshold"]).all() and (per["threshold"] < per["ci_high"]).all()
    width = np.log10(per["ci_high"] / per["ci_low"])
    assert width.min() > np.log10(pooled["ci_high"] / pooled["ci_low"]).max()


def test_degenerate_data_give_a_stated_not_estimable_row_never_a_number():
    base = {"participant": "P01", "condition": "LaFR", "scene": "temple", "varied": "delta"}
    rows = []
    rows += [{**base, "level": lv, "correct": 1} for lv in np.geomspace(0.5, 5, 30)]  # ceiling
    rows += [{**base, "scene": "street", "level": 2.0, "correct": k % 2} for k in range(30)]  # one level
    rows += [{**base, "scene": "hall", "level": lv, "correct": k % 2} for k, lv in enumerate(np.geomspace(1, 4, 9))]
    rows += [{**base, "scene": "attic", "level": lv, "correct": 0} for lv in np.geomspace(0.5, 5, 12)]  # floor
    fits = fit_thresholds(pd.DataFrame(rows), criterion=0.75, experiment_type="2AFC", axes={"LaFR": LAFR},
                          pooled=False).set_index("scene")
    assert not fits["estimable"].any()
    assert fits["threshold"].isna().all() and fits["ci_low"].isna().all() and fits["width"].isna().all()
    assert fits.loc["temple", "reason"] == "not estimable: at ceiling (every trial correct)"
    assert fits.loc["street", "reason"] == "not estimable: one level only"
    assert fits.loc["hall", "reason"] == "not estimable: 9 trials, fewer than 10"
    assert fits.loc["attic", "reason"] == "not estimable: at floor (no trial correct)"


def test_the_lean_grid_agrees_with_psignifits_own_fit_at_its_defaults():
    """psignifit.psignifit (public API, default grids, MAP) against this module's posterior median on the lean
    grid: the thresholds at 75 % agree within 0.03 log10 units, the posterior mean widths within 10 %."""
    import warnings

    import psignifit

    rng = np.random.default_rng(3)
    x = rng.choice(np.linspace(-1.0, 0.0, 9), 200)
    correct = (rng.random(x.size) < psychometric(x, -0.5, 0.4, 0.5, 0.0, 0.75)).astype(float)
    ours = fit_one(x, correct, criterion=0.75, experiment_type="2AFC", x_range=(-1.0, 0.0),
                   settings=FitSettings(), pooled=False)
    xs, idx = np.unique(x, return_inverse=True)
    data = np.column_stack([xs, np.bincount(idx, weights=correct), np.bincount(idx)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = psignifit.psignifit(data, experiment_type="2AFC", sigmoid="logistic", stimulus_range=(-1.0, 0.0),
                                  fixed_parameters={"eta": 0.0})
    assert abs(ours["x_threshold"] - float(ref.threshold(0.75, return_ci=False))) < 0.03
    assert abs(ours["x_threshold"] - (-0.5)) < 0.1
    # the posterior means (ours are means; psignifit's point estimate is the MAP)
    assert ours["width"] == pytest.approx(ref.get_parameter_estimate("mean")["width"], rel=0.1)


def test_group_table_mean_sd_and_bootstrap_interval_by_hand():
    xs = [0.1, 0.2, 0.4, 0.3]
    fits = pd.DataFrame([{"participant": f"P{i}", "condition": "LaFR", "scene": "temple", "varied": "delta",
                          "estimable": True, "x_threshold": x, "axis": "log10", "stronger": "higher"}
                         for i, x in enumerate(xs)]
                        + [{"participant": "P9", "condition": "LaFR", "scene": "temple", "varied": "delta",
                            "estimable": False, "x_threshold": np.nan, "axis": "log10", "stronger": "higher"},
                           {"participant": "P0", "condition": "VaFR", "scene": "temple", "varied": "acuity_scale",
                            "estimable": True, "x_threshold": 0.3, "axis": "log10", "stronger": "lower"}])
    g = group_table(fits, n_boot=500, seed=1).set_index("condition")
    r = g.loc["LaFR"]
    assert r["n_participants"] == 4 and r["n_not_estimable"] == 1
    assert r["mean_x"] == pytest.approx(0.25) and r["sd_x"] == pytest.approx(np.std(xs, ddof=1))
    assert 0.1 <= r["ci_low_x"] < 0.25 < r["ci_high_x"] <= 0.4
    assert r["threshold"] == pytest.approx(10 ** 0.25)  # the geometric mean level
    v = g.loc["VaFR"]  # one participant: no SD, no interval; a "lower" axis maps x = 0.3 to level 10^-0.3
    assert v["threshold"] == pytest.approx(10 ** -0.3) and math.isnan(v["sd_x"]) and math.isnan(v["ci_low"])
    again = group_table(fits, n_boot=500, seed=1)
    pd.testing.assert_frame_equal(g.reset_index(), again)


def test_pareto_carries_the_threshold_interval_into_the_cost():
    fits = pd.DataFrame([{"participant": POOLED, "condition": "VaFR", "scene": "temple", "estimable": True,
                          "criterion": 0.75, "x_threshold": 0.5, "x_ci_low": 0.4, "x_ci_high": 0.6, "width": 0.5,
                          "guess": 0.5, "lapse": 0.0}])
    group = pd.DataFrame([{"condition": "VaFR", "scene": "temple", "varied": "acuity_scale",
                           "threshold": 10 ** -0.5, "ci_low": 10 ** -0.6, "ci_high": 10 ** -0.4}])
    table, curves = pareto(fits, group, {"VaFR": VAFR}, cost=lambda c, s, lv: 1000.0 * lv,
                           gt_cost=lambda s: 2000.0)
    r = table.iloc[0]
    assert r["cost"] == pytest.approx(1000 * 10 ** -0.5)
    assert (r["cost_ci_low"], r["cost_ci_high"]) == pytest.approx((1000 * 10 ** -0.6, 1000 * 10 ** -0.4))
    assert r["relative_cost"] == pytest.approx(10 ** -0.5 / 2) and r["speedup"] == pytest.approx(2 / 10 ** -0.5)
    assert r["p_detect"] == pytest.approx(0.5)  # 75 % correct in 2AFC: half the trials detected
    # a lower acuity scale is stronger foveation: detection falls as the level (and the cost) grows
    assert len(curves) == 41 and curves.sort_values("level")["p_detect"].is_monotonic_decreasing
    i = int(np.argmin(abs(curves["level"] - 10 ** -0.5)))
    assert curves["p_detect"].iloc[i] == pytest.approx(0.5, abs=0.05)
    assert detection(0.5, 0.5) == 0.0 and detection(1.0, 0.5) == 1.0


def test_pareto_carries_the_threshold_interval_into_the_time_when_given():
    fits = pd.DataFrame([{"participant": POOLED, "condition": "LaFR", "scene": "temple", "estimable": True,
                          "criterion": 0.75, "x_threshold": 0.3, "x_ci_low": 0.2, "x_ci_high": 0.4, "width": 0.5,
                          "guess": 0.5, "lapse": 0.0}])
    group = pd.DataFrame([{"condition": "LaFR", "scene": "temple", "varied": "delta",
                           "threshold": 2.0, "ci_low": 1.5, "ci_high": 3.0}])
    kw = dict(cost=lambda c, s, lv: 1000.0 / lv, gt_cost=lambda s: 2000.0)
    table, _ = pareto(fits, group, {"LaFR": LAFR}, **kw)
    assert "time_ms" not in table.columns
    table, _ = pareto(fits, group, {"LaFR": LAFR}, **kw, time=lambda c, s, lv: 60.0 / lv, gt_time=lambda s: 90.0)
    r = table.iloc[0]
    # a stronger delta is faster: the interval's upper end gives the lower time, listed first
    assert (r["time_ms"], r["time_ms_ci_low"], r["time_ms_ci_high"]) == pytest.approx((30.0, 20.0, 40.0))
    assert r["gt_time_ms"] == 90.0 and r["time_speedup"] == pytest.approx(3.0) and r["speedup"] == pytest.approx(4.0)


def test_figures_are_byte_identical_run_to_run(tmp_path):
    from analysis.figures import pareto_figure, psychometric_figure

    df = _trials({"LaFR": 1.6}, participants=1, n=40, scenes=("temple", "street"))
    fits = fit_thresholds(df, criterion=0.75, experiment_type="2AFC", axes={"LaFR": LAFR}, pooled=False)
    a = psychometric_figure(df, fits, tmp_path / "a.png", "P00")
    b = psychometric_figure(df, fits, tmp_path / "b.png", "P00")
    assert a.read_bytes() == b.read_bytes() and a.stat().st_size > 10_000
    curves = pd.DataFrame({"condition": "LaFR", "scene": "temple", "level": [1.0, 2.0],
                           "relative_cost": [0.5, 0.25], "p_detect": [0.2, 0.8]})
    table = pd.DataFrame([{"condition": "LaFR", "scene": "temple", "relative_cost": 0.3, "p_detect": 0.5,
                           "relative_cost_ci_low": 0.25, "relative_cost_ci_high": 0.4}])
    c = pareto_figure(curves, table, tmp_path / "c.png", "Pareto", "rays relative to GT")
    d = pareto_figure(curves, table, tmp_path / "d.png", "Pareto", "rays relative to GT")
    assert c.read_bytes() == d.read_bytes()


def test_yes_no_fit_estimates_the_false_alarm_rate_and_the_50_percent_level():
    """yes/no: "not the ground truth" is correct; the guess rate (false alarms) is fitted, the threshold is
    where half the answers say "not the ground truth"."""
    rng = np.random.default_rng(5)
    ax = Axis("log", "higher", (0.5, 5.0))
    lv = rng.choice(np.geomspace(0.5, 5.0, 9), 600)
    pc = psychometric(ax.to_intensity(lv), np.log10(2.0), 0.6, 0.1, 0.02, 0.5)
    df = pd.DataFrame({"participant": "P01", "condition": "FSL", "scene": "cornell", "level": lv,
                       "correct": (rng.random(lv.size) < pc).astype(int)})
    r = fit_thresholds(df, criterion=0.5, experiment_type="yes/no", axes={"FSL": ax}, pooled=False).iloc[0]
    assert r["estimable"] and abs(math.log10(r["threshold"] / 2.0)) < 0.08
    assert r["guess"] == pytest.approx(0.1, abs=0.06) and r["ci_low"] < 2.0 < r["ci_high"]


def test_the_simulated_observer_answers_each_family_from_the_drawn_outcome():
    """An adaptive trial's outcome becomes the family's answer: 2AFC the original's side when correct, yes/no
    "no" (not the ground truth) when detected."""
    from types import SimpleNamespace

    from studyapp.runner.observer import DeclaredFunction, SimulatedObserver

    spec = {"scale": "log", "stronger": "higher"}
    sure = DeclaredFunction("LaFR", spec, -5.0, 5.0, 0.0, 0.5)  # far above threshold: always correct
    rng = np.random.default_rng(0)
    for order, expect in ((("GT", "LaFR(2)"), "A"), (("LaFR(2)", "GT"), "B")):
        trial = SimpleNamespace(family="2afc", level=2.0, stimuli=[SimpleNamespace(condition=c) for c in order])
        assert SimulatedObserver._psychometric_answer(None, trial, sure, rng)[0] == [expect]
    trial = SimpleNamespace(family="yes_no", level=2.0, stimuli=[SimpleNamespace(condition="LaFR(2)")])
    assert SimulatedObserver._psychometric_answer(None, trial, sure, rng)[0] == ["no"]
    never = DeclaredFunction("LaFR", spec, 5.0, 5.0, 0.0, 0.0)  # yes/no, no false alarms, far below threshold
    assert SimulatedObserver._psychometric_answer(None, trial, never, rng)[0] == ["yes"]
