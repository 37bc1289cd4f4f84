"""The whole study analysis: seed tables reproduced, layouts, units of analysis, degenerate logs, the CLI."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pandas as pd
import pytest

from analysis import cohens_d, kruskal, pairwise_kruskal
from analysis.io import LogError, read_log, validate_log
from analysis.plan import AnalysisPlan, plan_from_mapping
from analysis.report import report_json, write_report
from analysis.study import analyze_log
from analysis.synthetic import (
    SEED001_MODES,
    binary_d_range,
    pooled_d_range,
    seed001_2afc_log,
    seed003_comparison,
    seed003_yes_no_log,
    synthetic_2afc_log,
)
from analysis.tables import to_csv
from studyapp.cli import main


# --- seed 003 Tables 5-6 --------------------------------------------------------------------------------------
def test_seed003_tables_reproduced_within_tolerance_and_labels_exact():
    cmp = seed003_comparison()
    assert len(cmp) == 7
    assert (cmp["abs_d_error"] <= 0.05).all(), cmp[["table", "condition", "d", "seed_d"]]
    assert (cmp["label"] == cmp["seed_label"]).all()
    # means and SDs print as the seed's (2 decimals); Table 5's EC SD only as a population SD (see docs)
    assert np.allclose(cmp["mean"].round(2), cmp["seed_mean"])
    assert (cmp["p_text"] == cmp["seed_p"]).all()


def test_seed003_numbers_that_zero_one_data_cannot_reach():
    cmp = seed003_comparison().set_index(["table", "condition"])
    # every printed d is reachable from the rounded means/SDs alone ...
    assert cmp["seed_d_reachable"].all()
    # ... but not from 0/1 scores of 320 trials per condition: Table 5 CC2 (1.62) and Table 6 CC3 (0.80)
    unreachable = sorted(cmp.index[~cmp["seed_d_reachable_binary"]])
    assert unreachable == [(5, "CC2"), (6, "CC3")]
    lo, hi = cmp.loc[(5, "CC2"), ["binary_d_min", "binary_d_max"]]
    assert hi < 1.615 and lo > 1.60
    lo, hi = cmp.loc[(6, "CC3"), ["binary_d_min", "binary_d_max"]]
    assert lo > 0.805


def test_pooled_d_range_brackets_direct_computation():
    lo, hi = pooled_d_range(0.96, 0.19, 0.79, 0.40)
    d0 = (0.96 - 0.79) / np.sqrt((0.19**2 + 0.40**2) / 2)
    assert lo < d0 < hi
    assert lo == pytest.approx(0.16 / np.sqrt((0.195**2 + 0.405**2) / 2))
    # 0/1 data: Table 5 EC (0.79 +- 0.40) exists with 320 trials only as a population SD
    assert np.isnan(binary_d_range(0.96, 0.19, 0.79, 0.40, 320, 320, ddof=1)[0])
    assert np.isfinite(binary_d_range(0.96, 0.19, 0.79, 0.40, 320, 320, ddof=0)[0])


def test_seed003_log_has_the_seed_trial_counts():
    for table, n_cond, per_participant in ((5, 5, 50), (6, 4, 40)):
        log = seed003_yes_no_log(table)
        assert log["participant"].nunique() == 32
        assert log.groupby("participant").size().eq(per_participant).all()
        assert log.groupby("condition").size().eq(320).all()
        assert log["condition"].nunique() == n_cond


# --- seed 001 Tables 2-3 ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def seed001():
    log = seed001_2afc_log(seed=0)
    plan = AnalysisPlan(conditions=SEED001_MODES, reference="GT", n_boot=100)
    return log, analyze_log(validate_log(log), plan)


def test_seed001_log_size_and_design(seed001):
    log, _ = seed001
    assert len(log) == 4500
    per = log.groupby(["participant", "block", "scene"]).size()
    assert per.eq(30).all() and len(per) == 25 * 2 * 3
    pairs = log.apply(lambda r: frozenset((r.condition_a, r.condition_b)), axis=1)
    assert pairs.value_counts().eq(450).all() and pairs.nunique() == 10
    assert (log["condition_a"] == log["chosen"]).mean() == pytest.approx(0.5, abs=0.05)  # position balanced


def test_seed001_pairwise_matches_direct_computation(seed001):
    log, res = seed001
    units = res.tables["2afc_units"]
    assert units.groupby("condition").size().eq(25).all()  # one value per participant and condition
    # votes per participant, recomputed by hand
    votes = log.groupby(["participant", "chosen"]).size().unstack(fill_value=0)
    u = units.set_index(["participant", "condition"])["value"]
    for p in ("P01", "P13", "P25"):
        for c in SEED001_MODES:
            assert u[(p, c)] == votes.loc[p, c]
    tidy = pd.DataFrame({"participant": votes.index.repeat(5),
                         "condition": np.tile(votes.columns, len(votes)), "v": votes.to_numpy().ravel()})
    direct = pairwise_kruskal(tidy, "v", "condition", order=list(SEED001_MODES))
    pw = res.tables["2afc_pairwise"].query("block == '(all)' and scene == '(all)'").reset_index(drop=True)
    assert np.allclose(pw["p_adj"], direct["p_adj"], rtol=1e-12)
    # the simulated observers prefer VaFR: significant against the other three, not among them
    sig = {frozenset((a, b)): p < 0.05 for a, b, p in zip(pw["A"], pw["B"], pw["p_adj"])}
    for v in ("VaFR_Rep", "VaFR_Dup"):
        for o in ("LaFR(2.2)", "LaFR(1.8)", "GT"):
            assert sig[frozenset((v, o))]
    assert not sig[frozenset(("LaFR(2.2)", "GT"))]


def test_seed001_table_layout(tmp_path, seed001):
    _, res = seed001
    write_report(res, tmp_path, figures=False)
    md = (tmp_path / "tables" / "2afc_pairwise_matrix.md").read_text().splitlines()
    assert md[2] == "| P values | VaFR_Rep | VaFR_Dup | LaFR(2.2) | LaFR(1.8) | GT |"
    rows = [r.strip("| ").split(" | ") for r in md[4:]]
    assert [r[0] for r in rows] == list(SEED001_MODES[:-1])  # GT's all-'/' row is left out, as in the seed
    for i, r in enumerate(rows):
        assert all(c == "/" for c in r[1:i + 2])  # on and below the diagonal
        assert all(c != "/" for c in r[i + 2:])
    tex = (tmp_path / "tables" / "2afc_pairwise_matrix.tex").read_text()
    assert "\\toprule" in tex and "\\bottomrule" in tex and "VaFR\\_Rep" in tex


def test_jod_scale_recovers_simulated_order(seed001):
    _, res = seed001
    sc = res.tables["2afc_scale"].set_index("condition")
    assert sc.loc["GT", "jod"] == 0.0
    assert sc.loc["VaFR_Rep", "jod"] == pytest.approx(0.75, abs=0.15)
    assert (sc["jod_ci_low"] <= sc["jod"]).all() and (sc["jod"] <= sc["jod_ci_high"]).all()
    assert sc.loc["VaFR_Rep", "jod_ci_low"] > sc.loc["LaFR(2.2)", "jod_ci_high"]


# --- units of analysis, paired designs -------------------------------------------------------------------------
def test_unit_of_analysis_changes_the_sample():
    log = validate_log(seed003_yes_no_log(6))
    by_trial = analyze_log(log, AnalysisPlan(unit="trial", reference="EC", n_boot=0, per_scene=False))
    by_part = analyze_log(log, AnalysisPlan(unit="participant", reference="EC", n_boot=0, per_scene=False))
    assert by_trial.tables["yes_no_summary"]["n"].eq(320).all()
    assert by_part.tables["yes_no_summary"]["n"].eq(32).all()
    # participant means: the same grand mean, a smaller SD
    t, p = by_trial.tables["yes_no_summary"], by_part.tables["yes_no_summary"]
    assert np.allclose(t["mean"], p["mean"])
    assert (p["std"] < t["std"]).all()


def test_paired_plan_uses_dz():
    log = validate_log(seed003_yes_no_log(6))
    res = analyze_log(log, AnalysisPlan(unit="participant", paired=True, reference="EC", n_boot=0,
                                        per_scene=False))
    units = res.tables["yes_no_units"]
    wide = units.pivot(index="participant", columns="condition", values="value")
    row = res.tables["yes_no_summary"].set_index("condition").loc["CC3"]
    assert row["d"] == pytest.approx(cohens_d(wide["CC3"], wide["EC"], paired=True), rel=1e-12)
    with pytest.raises(ValueError, match="paired=true needs unit=participant"):
        AnalysisPlan(unit="trial", paired=True)


# --- degenerate logs ---------------------------------------------------------------------------------------------
def _yes_no(values: dict[str, list[int]]) -> pd.DataFrame:
    rows = [(f"P{i}", "s", "yes_no", c, v) for c, vs in values.items() for i, v in enumerate(vs)]
    return pd.DataFrame(rows, columns=["participant", "scene", "family", "condition", "response"])


def test_constant_but_different_groups_give_undefined_d_not_a_label():
    log = validate_log(_yes_no({"A": [1] * 6, "B": [0] * 6, "C": [1, 0, 1, 0, 1, 1]}))
    s = analyze_log(log, AnalysisPlan(unit="trial", reference="A", n_boot=0)).tables["yes_no_summary"]
    b = s.set_index("condition").loc["B"]
    assert np.isnan(b["d"]) and b["label"] == "undefined (zero SD)"
    assert 0.0 <= b["p"] <= 1.0
    assert s.set_index("condition").loc["C", "label"] in ("medium", "large", "very large", "huge")


def test_preference_family_votes_and_plackett_luce():
    rng = np.random.default_rng(1)
    modes = ["A", "B", "C", "D"]
    strength = np.array([2.0, 1.0, 0.0, 0.0])
    rows = []
    for p in range(12):
        for s in ("x", "y"):
            order = list(np.argsort(-(strength + rng.gumbel(size=4))))
            second = modes[order[1]] if p % 5 else ""  # some participants pick only one
            rows.append((f"P{p}", s, "preference", "|".join(modes), modes[order[0]], second))
    log = pd.DataFrame(rows, columns=["participant", "scene", "family", "conditions", "chosen", "chosen_2"])
    res = analyze_log(validate_log(log), AnalysisPlan(reference="D", n_boot=50))
    votes = res.tables["preference_votes"].query("block == '' and scene == 'x'").set_index("condition")
    first_x = log[log.scene == "x"]["chosen"].value_counts()
    assert votes.loc["A", "first"] == first_x.get("A", 0)
    assert votes["shown"].eq(12).all()
    sc = res.tables["preference_scale"].set_index("condition")
    assert sc.loc["A", "score"] > sc.loc["B", "score"] > sc.loc["D", "score"] == 0.0


def test_report_is_byte_identical(tmp_path):
    log = validate_log(seed001_2afc_log(seed=3, n_participants=6))
    plan = AnalysisPlan(conditions=SEED001_MODES, reference="GT", n_boot=50)

    def digest(d):
        paths = write_report(analyze_log(log, plan), d)
        return {p.relative_to(d).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() for p in paths}

    a, b = digest(tmp_path / "a"), digest(tmp_path / "b")
    assert a == b and any(k.endswith(".png") for k in a)
    data = json.loads((tmp_path / "a" / "analysis.json").read_text())
    assert data == json.loads(json.dumps(report_json(analyze_log(log, plan))))


def test_large_synthetic_log_is_aggregated_not_looped():
    log = synthetic_2afc_log(200_000, seed=0)
    res = analyze_log(validate_log(log), AnalysisPlan(n_boot=20, per_scene=False))
    votes = res.tables["2afc_votes"].groupby("condition")["votes"].sum()
    assert votes.sum() == 200_000
    assert votes.to_dict() == log["chosen"].value_counts().to_dict()
    # omnibus test over participant totals equals a direct call
    units = res.tables["2afc_units"]
    direct = kruskal(*[units.loc[units.condition == c, "value"] for c in res.conditions["2afc"]])
    assert res.tables["2afc_omnibus"]["H"].iloc[0] == pytest.approx(direct.H, rel=1e-12)


# --- plans and bad input -----------------------------------------------------------------------------------------
def test_plan_from_mapping_aliases_and_errors():
    plan = plan_from_mapping({"unit_of_analysis": "trial", "reference_condition": "EC", "test": "summary_table",
                              "dependent_variable": "response"})
    assert (plan.unit, plan.reference, plan.tests, plan.dv) == ("trial", "EC", ("summary_table",), "response")
    with pytest.raises(ValueError, match="unknown field 'colour'"):
        plan_from_mapping({"colour": 1})
    with pytest.raises(ValueError, match="unit='day' is invalid"):
        plan_from_mapping({"unit": "day"})


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture()
def csv_log(tmp_path):
    p = tmp_path / "log.csv"
    p.write_text(to_csv(seed003_yes_no_log(6)))
    return p


def test_cli_analyze_writes_tables_and_json(tmp_path, csv_log, capsys):
    code, out, err = _run(capsys, "analyze", str(csv_log), "--out", str(tmp_path / "o"), "--unit", "trial",
                          "--reference", "EC", "--conditions", "EC,CC2,CC3,CC4", "--json", "--no-figures")
    assert code == 0, err
    data = json.loads(out)
    rows = [r for r in data["tables"]["yes_no_summary"] if r["scene"] == "(all)"]
    assert [r["condition"] for r in rows] == ["CC2", "CC3", "CC4"]
    assert [r["label"] for r in rows] == ["very large", "large", "large"]
    md = (tmp_path / "o" / "tables" / "yes_no_summary_table.md").read_text()
    assert "| EC | 0.86 ± 0.35 | / | / | / |" in md
    assert "| CC2 | 0.18 ± 0.39 | <0.001 | -1.85 | very large |" in md


@pytest.mark.parametrize("mutate, message", [
    (lambda df: df.drop(columns=["participant"]), "missing required column(s) participant"),
    (lambda df: df.assign(response="often"), "line 2: column response of a yes_no trial must be 0 or 1, found 'often'"),
    (lambda df: df[df.condition == "EC"], "fewer than two conditions"),
    (lambda df: df.assign(family="rating"), "unknown trial family 'rating'"),
])
def test_cli_bad_logs_exit_2_with_one_line(tmp_path, capsys, mutate, message):
    p = tmp_path / "bad.csv"
    p.write_text(to_csv(mutate(seed003_yes_no_log(6))))
    code, _out, err = _run(capsys, "analyze", str(p), "--out", str(tmp_path / "o"), "--no-figures")
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("studyapp: error: ") and message in err, err
    assert not (tmp_path / "o" / "report.md").exists()


def test_cli_unknown_condition_in_plan(tmp_path, csv_log, capsys):
    plan = tmp_path / "plan.yaml"
    plan.write_text("name: x\nanalysis:\n  conditions: [EC, CC2, CC3, CC9]\n  reference: EC\n")
    code, _, err = _run(capsys, "analyze", str(csv_log), "--out", str(tmp_path / "o"), "--plan", str(plan))
    assert code == 2 and "condition 'CC9'" in err and err.count("\n") == 1
    code, _, err = _run(capsys, "analyze", str(csv_log), "--out", str(tmp_path / "o"), "--reference", "ZZ")
    assert code == 2 and "reference condition 'ZZ'" in err


def test_read_log_errors(tmp_path):
    with pytest.raises(LogError, match="no such file"):
        read_log(tmp_path / "nope.csv")
    (tmp_path / "x.xlsx").write_text("a")
    with pytest.raises(LogError, match="unknown log format"):
        read_log(tmp_path / "x.xlsx")
    (tmp_path / "e.csv").write_text("participant,family,scene\n")
    with pytest.raises(LogError, match="no trials"):
        read_log(tmp_path / "e.csv")


def test_practice_and_catch_trials_are_excluded(tmp_path):
    log = seed003_yes_no_log(6)
    extra = log.head(10).assign(practice=1, response=0)
    both = pd.concat([log.assign(practice=0), extra], ignore_index=True)
    p = tmp_path / "l.csv"
    p.write_text(to_csv(both))
    assert len(read_log(p)) == len(log)


# --- a study database from the runner, analysed with its protocol's plan ----------------------------------------
@pytest.mark.parametrize("name", ["seed001_2afc", "seed001_pilot", "seed003_task1"])
def test_analyze_a_simulated_study_database(tmp_path, capsys, name):
    from pathlib import Path

    from data_schema.store import read_analysis_plan

    proto = Path(__file__).resolve().parents[1] / "protocols" / f"{name}.yaml"
    db = tmp_path / "study.db"
    for pid in ("P1", "P2", "P3"):
        assert main(["run", str(proto), "--participant", pid, "--simulate", "--db", str(db), "--quiet",
                     "--stimuli", str(tmp_path / "none")]) == 0
    capsys.readouterr()
    code, out, err = _run(capsys, "analyze", str(db), "--out", str(tmp_path / "o"), "--json", "--n-boot", "20")
    assert code == 0, err
    data = json.loads(out)
    plan = plan_from_mapping(read_analysis_plan(db))
    assert data["plan"]["unit"] == plan.unit and data["plan"]["reference"] == plan.reference
    fam = data["families"][0]
    assert data["n_participants"][fam] == 3
    assert (tmp_path / "o" / "report.md").exists()
    if fam == "yes_no":
        rows = data["tables"]["yes_no_summary"]
        assert all(r["condition"] != plan.reference for r in rows)
    else:
        votes = data["tables"][f"{fam}_votes"]
        log = read_log(db)
        picks = log["chosen"].astype(str).ne("").sum() + (
            log["chosen_2"].astype(str).ne("").sum() if fam == "preference" else 0)
        assert sum(v["votes"] for v in votes) == picks


def test_plan_accepts_the_protocol_schema_vocabulary():
    plan = plan_from_mapping({"dv": "chosen", "unit": "participant", "reference": "VaFR_Rep",
                              "test": "pairwise_kruskal", "by": [], "alpha": 0.01, "family": "2afc",
                              "protocol": "seed001_2afc"})
    assert (plan.dv, plan.tests, plan.per_scene, plan.alpha) == ("chosen", ("pairwise_kruskal",), False, 0.01)
    assert plan_from_mapping({"dv": "response", "unit": "trial", "test": "summary_table"}).tests == ("summary_table",)
    with pytest.raises(ValueError, match="by must be a list"):
        plan_from_mapping({"by": ["headset"]})
