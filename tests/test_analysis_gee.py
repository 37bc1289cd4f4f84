"""Logistic GEE of repeated binary answers against R's geepack::geeglm (issue 12, item 5).

Constants: ``python tests/reference/gee_geepack.py`` writes the inputs below (:func:`gee_inputs`) and prints
geepack's coefficients, robust SEs and working correlation (R 4.2.2, geepack 1.3.9 from Debian r-cran-geepack;
``geeglm(y ~ condition, id = participant, family = binomial, corstr = "exchangeable")``, data sorted by participant,
``geese.control(epsilon = 1e-12)``). R is not needed to run these tests.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from analysis.gee import GEE_COLUMNS, logistic_gee
from analysis.io import validate_log
from analysis.plan import AnalysisPlan
from analysis.study import analyze_log
from analysis.synthetic import SEED001_MODES, seed001_2afc_log, seed003_yes_no_log

TOL = 1e-6  # the bar; measured: below 1e-9 (see test_matches_geepack)

def gee_inputs() -> dict[str, tuple[pd.DataFrame, str, bool]]:
    """name -> (participant/condition/y frame, reference, intercept): what the study feeds the GEE."""
    yn = seed003_yes_no_log(5, seed=0)
    yes_no = pd.DataFrame({"participant": yn["participant"], "condition": yn["condition"],
                           "y": yn["response"].astype(float)})
    log = seed001_2afc_log(seed=0)
    with_gt = log[(log.condition_a == "GT") | (log.condition_b == "GT")]
    other = np.where(with_gt.condition_a == "GT", with_gt.condition_b, with_gt.condition_a)
    tafc = pd.DataFrame({"participant": with_gt["participant"].to_numpy(), "condition": other,
                         "y": (with_gt["chosen"].to_numpy() == other).astype(float)})
    keep_yn = np.random.default_rng(1).random(len(yes_no)) < 0.6
    keep_2afc = np.random.default_rng(2).random(len(tafc)) < 0.6
    return {"seed001_2afc": (tafc, "GT", False), "seed001_2afc_unbalanced": (tafc[keep_2afc], "GT", False),
            "seed003_table5": (yes_no, "EC", True), "seed003_table5_unbalanced": (yes_no[keep_yn], "EC", True)}


# Printed by tests/reference/gee_geepack.py: GEEPACK_VERSION = "1.3.9", R 4.2.2 Patched (2022-11-10 r83330).
GEEPACK = {
    "seed001_2afc_unbalanced.csv": dict(
        terms=["conditionLaFR(1.8)", "conditionLaFR(2.2)", "conditionVaFR_Dup", "conditionVaFR_Rep"],
        coef=[-0.17130195466821024, -0.023231851768467357, 0.7328395064057055, 0.82889215070286659],
        se=[0.090796261967018316, 0.12291559734387797, 0.12886855507568945, 0.11145436948580675],
        alpha=[-0.001381712838934956]),
    "seed001_2afc.csv": dict(
        terms=["conditionLaFR(1.8)", "conditionLaFR(2.2)", "conditionVaFR_Dup", "conditionVaFR_Rep"],
        coef=[-0.080042707673536162, 0.017778246021284094, 0.62392680366875963, 0.97777581552483617],
        se=[0.085284401815014579, 0.10808807205083736, 0.11025936412899577, 0.080554933989706853],
        alpha=[0.005279939972832352]),
    "seed003_table5_unbalanced.csv": dict(
        terms=["(Intercept)", "conditionCC1", "conditionCC2", "conditionCC3", "conditionCC4"],
        coef=[1.2615099055523298, 1.85430433602583, -2.6628922882845543, -1.6988615185790636, 0.36418999543131714],
        se=[0.17878068903832767, 0.4063449197714778, 0.23137040669500247, 0.22699334402243604, 0.29736920970878189],
        alpha=[0.0093830789176992686]),
    "seed003_table5.csv": dict(
        terms=["(Intercept)", "conditionCC1", "conditionCC2", "conditionCC3", "conditionCC4"],
        coef=[1.3476795249921114, 1.8975136081934632, -2.9646362698402391, -1.8319255109533903, 0.38692153039599464],
        se=[0.14010897882035953, 0.33638496525754713, 0.19796446559262906, 0.15253835629870854, 0.23225287111012957],
        alpha=[-0.0010673557534103505]),
}


#: (answers, answers = 1) of each input: the constants belong to these inputs (regenerate them if this changes).
GEE_INPUT_SIZES = {"seed001_2afc": (1800, 1063), "seed001_2afc_unbalanced": (1064, 618),
                   "seed003_table5": (1600, 1009), "seed003_table5_unbalanced": (956, 600)}


@pytest.fixture(scope="module")
def inputs():
    data = gee_inputs()
    sizes = {name: (len(f), int(f["y"].sum())) for name, (f, _, _) in data.items()}
    assert sizes == GEE_INPUT_SIZES
    return data


@pytest.mark.parametrize("name", sorted(GEE_INPUT_SIZES))
def test_matches_geepack(inputs, name):
    frame, reference, intercept = inputs[name]
    out = logistic_gee(frame, "y", "condition", "participant", reference, intercept=intercept)
    ref = GEEPACK[f"{name}.csv"]
    terms = [t.removeprefix("condition") for t in ref["terms"] if t != "(Intercept)"]
    start = 1 if intercept else 0
    got = out.set_index("condition").loc[terms]
    np.testing.assert_allclose(got["log_or"], ref["coef"][start:], rtol=0, atol=TOL)
    np.testing.assert_allclose(got["se"], ref["se"][start:], rtol=0, atol=TOL)
    np.testing.assert_allclose(got["working_corr"], ref["alpha"][0], rtol=0, atol=TOL)
    # measured agreement (the report's figure): far inside the bar
    assert np.max(np.abs(got["log_or"] - ref["coef"][start:])) < 1e-9
    assert np.max(np.abs(got["se"] - ref["se"][start:])) < 1e-9


def test_odds_ratios_intervals_and_p_follow_from_the_coefficients(inputs):
    frame, reference, intercept = inputs["seed003_table5"]
    out = logistic_gee(frame, "y", "condition", "participant", reference, intercept=intercept)
    assert list(out.columns) == list(GEE_COLUMNS) and list(out.condition) == ["CC1", "CC2", "CC3", "CC4"]
    np.testing.assert_allclose(out.odds_ratio, np.exp(out.log_or), rtol=1e-15)
    np.testing.assert_allclose(np.log(out.ci_high) - out.log_or, 1.959963984540054 * out.se, rtol=1e-12)
    from scipy import stats

    np.testing.assert_allclose(out.p, 2 * stats.norm.sf(np.abs(out.log_or / out.se)), rtol=1e-12)
    assert (out.n == 320).all() and (out.n_participants == 32).all() and (out.note == "").all()


def test_study_reports_the_gee_beside_the_seed_tables(inputs, tmp_path):
    from analysis.report import write_report

    plan = AnalysisPlan(unit="trial", tests=("summary_table", "gee"), reference="EC", n_boot=0, per_scene=False)
    res = analyze_log(validate_log(seed003_yes_no_log(5, seed=0)), plan)
    assert {"yes_no_summary", "yes_no_gee"} <= set(res.tables)
    ref = GEEPACK["seed003_table5.csv"]
    np.testing.assert_allclose(res.tables["yes_no_gee"]["log_or"], ref["coef"][1:], atol=TOL, rtol=0)
    log = validate_log(seed001_2afc_log(seed=0))
    res2 = analyze_log(log, AnalysisPlan(conditions=SEED001_MODES, reference="GT", tests=("gee",), n_boot=0))
    got = res2.tables["2afc_gee"].set_index("condition").loc[["LaFR(1.8)", "LaFR(2.2)", "VaFR_Dup", "VaFR_Rep"]]
    np.testing.assert_allclose(got["se"], GEEPACK["seed001_2afc.csv"]["se"], atol=TOL, rtol=0)
    write_report(res, tmp_path, figures=False)
    md = (tmp_path / "tables" / "yes_no_gee.md").read_text()
    assert "| CC2 | 320 | 0.17 | 0.05 [" in md and "odds ratio [95% CI]" in md
    data = json.loads((tmp_path / "analysis.json").read_text())
    assert [r["condition"] for r in data["tables"]["yes_no_gee"]] == ["CC1", "CC2", "CC3", "CC4"]
    assert "logistic GEE" in (tmp_path / "report.md").read_text()


def test_separation_and_too_few_participants_are_reported_not_fatal():
    rng = np.random.default_rng(3)
    rows = [(f"P{p}", c, float(rng.random() < rate) if rate < 1 else 1.0) for p in range(8)
            for c, rate in (("R", 0.6), ("all_yes", 1.0), ("mixed", 0.3)) for _ in range(4)]
    df = pd.DataFrame(rows, columns=["participant", "condition", "y"])
    out = logistic_gee(df, "y", "condition", "participant", "R").set_index("condition")
    assert np.isnan(out.loc["all_yes", "odds_ratio"])
    assert out.loc["all_yes", "note"] == "not estimable (every answer 1: infinite log odds)"
    assert np.isfinite(out.loc["mixed", "odds_ratio"]) and out.loc["mixed", "note"] == ""
    ref_const = logistic_gee(df.assign(y=np.where(df.condition == "R", 0.0, df.y)), "y", "condition",
                             "participant", "R")
    assert ref_const["note"].str.startswith("not estimable (reference 'R': every answer 0").all()
    alone = pd.DataFrame({"participant": "P1", "condition": ["R"] * 4 + ["mixed"] * 4, "y": [1, 0, 1, 0, 0, 1, 1, 0]})
    one = logistic_gee(alone, "y", "condition", "participant", "R").set_index("condition")
    assert one.loc["mixed", "note"] == "not estimable (fewer than 2 participants)"
    with pytest.raises(ValueError, match="0/1 answers"):
        logistic_gee(df.assign(y=df.y * 2), "y", "condition", "participant", "R")
    # identical answer patterns in every cluster: the exchangeable fit breaks down; reported, never numbers
    same = pd.DataFrame([(f"P{p}", c, y) for p in range(6) for c, ys in (("R", [1, 0, 1]), ("x", [0, 1, 0]))
                         for y in ys], columns=["participant", "condition", "y"])
    bad = logistic_gee(same, "y", "condition", "participant", "R").iloc[0]  # and no warning printed
    assert np.isnan(bad.odds_ratio) and bad.note == "not estimable (GEE did not converge in 200 iterations)"


def test_statsmodels_is_imported_only_when_the_gee_runs():
    import subprocess
    import sys

    code = ("import sys, analysis, analysis.gee, analysis.study; print('statsmodels' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"
