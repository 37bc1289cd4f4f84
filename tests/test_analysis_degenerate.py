"""Degenerate data as R treats it: untestable pairs (p = NaN, left out of Holm), undefined effect sizes (n/a with the
reason), and reports that never abort on them (issue 12, items 1-2).

Constants: printed by R 4.2.2 (Debian r-base-core, "R version 4.2.2 Patched (2022-11-10 r83330)") with
``Rscript tests/reference/untestable_pairs.R`` (kruskal.test per pair + p.adjust(holm); Dunn's z by hand with NA for
an all-tied pair, then p.adjust(holm); wilcox.test; Cohen's d by its formula). R is not needed to run these tests.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from analysis import dunn, kruskal, pairwise_kruskal, pairwise_matrix, summary_table
from analysis.io import validate_log
from analysis.plan import AnalysisPlan
from analysis.report import write_report
from analysis.study import analyze_log
from analysis.synthetic import seed003_yes_no_log
from analysis.tables import to_csv
from studyapp.cli import main

nan = float("nan")
RTOL = 1e-12

# --- constants from tests/reference/untestable_pairs.R ------------------------------------------------------------
ABC_PKW_P = [nan, 0.036903953613718128, 0.036903953613718128]
ABC_PKW_HOLM = [nan, 0.073807907227436256, 0.073807907227436256]
ABC_DUNN_Z = [nan, -2.3911601909582574, -2.3911601909582574]
ABC_DUNN_P = [nan, 0.016795223112260012, 0.016795223112260012]
ABC_DUNN_HOLM = [nan, 0.033590446224520024, 0.033590446224520024]
FIVE_PKW_P = [nan, 0.1762963744405118, 0.0081509715935026931, 0.045500263896358549, 0.23672357063785718,
              0.014305878435429647, 0.073638270120302884, 0.073638270120302857, 0.39907519654823803,
              0.22067136191984696]
FIVE_PKW_HOLM = [nan, 0.7051854977620472, 0.073358744341524243, 0.31850184727450986, 0.7051854977620472,
                 0.11444702748343717, 0.44182962072181714, 0.44182962072181714, 0.7051854977620472,
                 0.7051854977620472]
FIVE_DUNN_Z = [nan, 1.1699952516522831, 2.7748873851023217, 2.026491220476089, 1.074709263010234,
               2.5690465157330258, 1.8499249234015478, 1.7549928774784245, 0.86409875978771478,
               -1.0132456102380443]
FIVE_DUNN_P = [nan, 0.24200287971107684, 0.0055220825466006235, 0.042714471512531361, 0.28250491527470917,
               0.010197876776240244, 0.064324371113975848, 0.079260526067594761, 0.38753364025454645,
               0.31094285965471219]
FIVE_DUNN_HOLM = [nan, 0.96801151884430736, 0.049698742919405611, 0.29900130058771951, 0.96801151884430736,
                  0.08158301420992195, 0.38594622668385509, 0.3963026303379738, 0.96801151884430736,
                  0.96801151884430736]
TIED_WILCOX_P = nan  # wilcox.test(c(4,4,4), c(4,4,4), exact=FALSE, correct=FALSE)$p.value
D_SAME_CONST, D_DIFF_CONST, D_ONE_EACH = nan, -np.inf, nan  # R's formula: 0/0, -1/0, NA

ABC = {"a": [1, 1, 1], "b": [1, 1, 1], "c": [2, 3, 4]}
FIVE = {"A": [1, 1, 1, 1], "B": [1, 1, 1], "C": [0, 1, 1, 0, 1], "D": [0, 0, 0, 0], "E": [0, 1, 0, 0, 0, 1]}


def _frame(groups: dict) -> pd.DataFrame:
    return pd.DataFrame({"g": [k for k, v in groups.items() for _ in v],
                         "y": [float(x) for v in groups.values() for x in v]})


def _close(got, want):
    np.testing.assert_allclose(np.asarray(got, dtype=float), np.asarray(want, dtype=float), rtol=RTOL, atol=0)


# --- item 1: untestable pairs --------------------------------------------------------------------------------------
@pytest.mark.parametrize("groups, p, holm", [(ABC, ABC_PKW_P, ABC_PKW_HOLM), (FIVE, FIVE_PKW_P, FIVE_PKW_HOLM)])
def test_pairwise_kruskal_matches_r_with_an_all_tied_pair(groups, p, holm):
    out = pairwise_kruskal(_frame(groups), "y", "g")
    _close(out.p_unc, p)
    _close(out.p_adj, holm)  # the NaN pair is left out of Holm's count, as p.adjust leaves out NA
    assert out.note.iloc[0] == "not testable (all observations tied)" and (out.note.iloc[1:] == "").all()


def test_the_issue_example_is_no_longer_counted():
    out = pairwise_kruskal(_frame(ABC), "y", "g")
    assert out.p_adj.iloc[1] == pytest.approx(0.073808, abs=5e-7)  # R; counting the tied pair gave 0.110712
    assert 3 * out.p_unc.iloc[1] == pytest.approx(0.110712, abs=5e-7)


@pytest.mark.parametrize("groups, z, p, holm", [(ABC, ABC_DUNN_Z, ABC_DUNN_P, ABC_DUNN_HOLM),
                                                 (FIVE, FIVE_DUNN_Z, FIVE_DUNN_P, FIVE_DUNN_HOLM)])
def test_dunn_matches_r_with_an_all_tied_pair(groups, z, p, holm):
    out = dunn(_frame(groups), "y", "g")
    _close(out.z, z)
    _close(out.p_unc, p)
    _close(out.p_adj, holm)
    assert out.note.iloc[0].startswith("not testable")


def test_omnibus_keeps_its_degenerate_flag():
    res = kruskal([2.0, 2.0], [2.0])
    assert (res.H, res.p, res.degenerate) == (0.0, 1.0, True)  # documented; the pairs report NaN instead


def test_matrix_and_report_show_not_testable(tmp_path):
    m = pairwise_matrix(pairwise_kruskal(_frame(ABC), "y", "g"))
    assert m.loc["a", "b"] == "not testable" and m.loc["a", "c"] == "0.074"
    log = validate_log(pd.DataFrame({"participant": [f"P{i}" for i in range(9)], "scene": "s", "family": "yes_no",
                                     "condition": ["a"] * 3 + ["b"] * 3 + ["c"] * 3,
                                     "response": [1, 1, 1, 1, 1, 1, 0, 1, 0]}))
    res = analyze_log(log, AnalysisPlan(unit="trial", reference="a", n_boot=0, per_scene=False))
    write_report(res, tmp_path, figures=False)
    md = (tmp_path / "tables" / "yes_no_pairwise_matrix.md").read_text()
    assert "| a | / | not testable |" in md
    assert "not testable" in (tmp_path / "tables" / "yes_no_dunn_matrix.md").read_text()
    summary = (tmp_path / "tables" / "yes_no_summary_table.md").read_text()
    assert "| b | 1.00 ± 0.00 | not testable | n/a | undefined (zero SD) |" in summary
    report = (tmp_path / "report.md").read_text()
    assert "left out of the Holm count" in report and "shown as n/a with the reason" in report
    rows = json.loads((tmp_path / "analysis.json").read_text())["tables"]["yes_no_pairwise"]
    assert rows[0]["p_adj"] is None and rows[0]["note"].startswith("not testable")


# --- item 2: undefined effect sizes never abort ---------------------------------------------------------------------
def test_identical_constant_groups_are_undefined_as_in_r():
    row = summary_table(_frame({"r": [4, 4, 4], "x": [4, 4, 4]}), "y", "g", "r").iloc[0]
    assert np.isnan(TIED_WILCOX_P) and np.isnan(row.p)
    assert np.isnan(D_SAME_CONST) and np.isnan(row.d) and row.label == "undefined (zero SD)"
    from analysis import cohens_d

    assert cohens_d([1.0, 1.0], [2.0, 2.0]) == D_DIFF_CONST and np.isnan(cohens_d([1.0], [2.0])) == np.isnan(
        D_ONE_EACH)


def _yes_no_log(values: dict[str, list[int]], participants=None) -> pd.DataFrame:
    rows = [((participants or (lambda i: f"P{i}"))(i), "s", "yes_no", c, v) for c, vs in values.items()
            for i, v in enumerate(vs)]
    return pd.DataFrame(rows, columns=["participant", "scene", "family", "condition", "response"])


def test_constant_condition_against_constant_reference_is_reported():
    log = validate_log(_yes_no_log({"A": [1] * 6, "B": [0] * 6, "C": [1, 0, 1, 0, 1, 1], "D": [1] * 6}))
    s = analyze_log(log, AnalysisPlan(unit="trial", reference="A", n_boot=0)).tables["yes_no_summary"]
    s = s[s.scene == "(all)"].set_index("condition")
    assert np.isnan(s.loc["B", "d"]) and s.loc["B", "label"] == "undefined (zero SD)" and 0 < s.loc["B", "p"] < 1
    assert np.isnan(s.loc["D", "d"]) and np.isnan(s.loc["D", "p"]) and s.loc["D", "note"].startswith("not test")
    assert np.isfinite(s.loc["C", "d"]) and s.loc["C", "label"] in ("medium", "large", "very large", "huge")


def test_constant_data_everywhere():
    log = validate_log(_yes_no_log({"A": [1] * 8, "B": [1] * 8, "C": [1] * 8}))
    res = analyze_log(log, AnalysisPlan(unit="trial", reference="A", n_boot=0))
    s = res.tables["yes_no_summary"]
    assert s["p"].isna().all() and s["d"].isna().all() and (s["label"] == "undefined (zero SD)").all()
    assert res.tables["yes_no_omnibus"]["p"].iloc[0] == 1.0  # the omnibus test's documented degenerate result
    assert res.tables["yes_no_pairwise"]["p_adj"].isna().all()


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("log", [
    # a constant condition against a constant reference (every table row still computed)
    lambda: _yes_no_log({"EC": [1] * 5, "CC1": [1] * 5, "CC2": [0, 1, 0, 1, 1]}),
    # a one-participant log: every participant-level group has one value (n1 + n2 - 2 = 0)
    lambda: seed003_yes_no_log(6, n_participants=1),
])
def test_cli_analyze_exits_0_on_degenerate_logs(tmp_path, capsys, log):
    p = tmp_path / "log.csv"
    p.write_text(to_csv(log()))
    code, out, err = _run(capsys, "analyze", str(p), "--out", str(tmp_path / "o"), "--json", "--no-figures",
                          "--reference", "EC", "--test", "summary_table", "pairwise_kruskal", "kruskal_dunn", "gee")
    assert code == 0, err
    rows = [r for r in json.loads(out)["tables"]["yes_no_summary"] if r["scene"] == "(all)"]
    assert any(r["d"] is None and r["label"].startswith("undefined") for r in rows)
    md = (tmp_path / "o" / "tables" / "yes_no_summary_table.md").read_text()
    assert "| n/a | undefined (" in md


def test_one_participant_2afc_log_is_analysed(capsys, tmp_path):
    from analysis.synthetic import seed001_2afc_log

    p = tmp_path / "log.csv"
    p.write_text(to_csv(seed001_2afc_log(seed=1, n_participants=1, reps=1)))
    code, out, err = _run(capsys, "analyze", str(p), "--out", str(tmp_path / "o"), "--json", "--no-figures",
                          "--n-boot", "20", "--reference", "GT", "--test", "summary_table", "thurstone", "gee")
    assert code == 0, err
    data = json.loads(out)
    assert all(r["label"].startswith("undefined (n1 + n2 - 2") for r in data["tables"]["2afc_summary"]
               if r["scene"] == "(all)")
    assert all(r["note"] == "not estimable (fewer than 2 participants)" for r in data["tables"]["2afc_gee"])
