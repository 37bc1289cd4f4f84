"""One analysis vocabulary (analysis/vocabulary.py) for the plan, the CLI and the protocol schema (architecture
issue, item A): the shipped schema is the generated one, no schema value stands for another, every test name
produces its own tables, and the shipped protocols stay valid."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from analysis import vocabulary as V
from analysis.io import validate_log
from analysis.plan import AnalysisPlan, plan_from_mapping
from analysis.study import analyze_log
from analysis.synthetic import seed001_2afc_log, seed003_yes_no_log
from data_schema.protocol_schema import ProtocolError, load_schema, load_yaml, validate_document

ROOT = Path(__file__).resolve().parents[1]


def test_shipped_schema_is_the_generated_one():
    text = V.schema_path().read_text(encoding="utf-8")
    assert V.generated_schema_text(text) == text, "run: python -m analysis.vocabulary --write-schema"
    block = load_schema()["$defs"]["analysis"]["properties"]
    assert block["dv"]["enum"] == list(V.DVS)
    assert block["unit"]["enum"] == list(V.UNITS)
    assert block["test"]["items"]["enum"] == list(V.TESTS)
    assert block["prior"]["enum"] == list(V.PRIORS)


def test_generator_rewrites_only_the_analysis_block(tmp_path):
    text = V.schema_path().read_text(encoding="utf-8")
    stale = text.replace('"gee"]}}', '"thurstone"]}}').replace('"enum": ["none", "weak", "pwcmp"]', '"enum": []')
    assert stale != text
    p = tmp_path / "schema.json"
    p.write_text(stale, encoding="utf-8")
    assert V.write_schema(p) is True and p.read_text(encoding="utf-8") == text
    assert V.write_schema(p) is False
    assert V.main(["--check"]) == 0


def _cli_choices() -> dict[str, list[str]]:
    from studyapp.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    analyze = sub.choices["analyze"]
    return {a.dest: list(a.choices) for a in analyze._actions if a.choices}


def test_cli_choices_are_the_vocabulary():
    assert _cli_choices() == {"unit": list(V.UNITS), "test": list(V.TESTS), "prior": list(V.PRIORS)}


def test_plan_validates_against_the_vocabulary_without_aliases():
    for name in V.TESTS:
        assert plan_from_mapping({"test": name}).tests == (name,)
    assert plan_from_mapping({"test": ["gee", "summary_table"]}).tests == ("gee", "summary_table")
    for bad, hint in (("kruskal_holm", "renamed: use pairwise_kruskal, kruskal_dunn"),
                      ("mann_whitney", "renamed: use summary_table"), ("wilcoxon", "allowed summary_table")):
        with pytest.raises(ValueError, match=hint):
            plan_from_mapping({"test": bad})
    for field, bad in (("dv", "score"), ("dv", "preference"), ("unit", "session"), ("prior", "gaussian")):
        with pytest.raises(ValueError, match=f"{field}={bad!r} is invalid"):
            plan_from_mapping({field: bad})
    with pytest.raises(ValueError, match="lists a test twice"):
        AnalysisPlan(tests=("gee", "gee"))


# which tables each test name adds (beyond the votes table and the omnibus test, always there)
EXPECTED = {
    "summary_table": {"2afc": {"2afc_summary"}, "yes_no": {"yes_no_summary"}},
    "pairwise_kruskal": {"2afc": {"2afc_pairwise"}, "yes_no": {"yes_no_pairwise"}},
    "kruskal_dunn": {"2afc": {"2afc_dunn"}, "yes_no": {"yes_no_dunn"}},
    "thurstone": {"2afc": {"2afc_scale"}, "yes_no": set()},
    "bradley_terry": {"2afc": {"2afc_scale"}, "yes_no": set()},
    "plackett_luce": {"2afc": set(), "yes_no": set()},
    "gee": {"2afc": {"2afc_gee"}, "yes_no": {"yes_no_gee"}},
}


@pytest.fixture(scope="module")
def logs():
    return {"2afc": validate_log(seed001_2afc_log(seed=5, n_participants=5, reps=1)),
            "yes_no": validate_log(seed003_yes_no_log(6, n_participants=6))}


@pytest.mark.parametrize("test", list(V.TESTS))
def test_every_test_name_means_what_it_says(logs, test):
    assert set(EXPECTED) == set(V.TESTS)
    for fam, log in logs.items():
        ref = "GT" if fam == "2afc" else "EC"
        res = analyze_log(log, AnalysisPlan(tests=(test,), reference=ref, n_boot=0, per_scene=False))
        base = {f"{fam}_units", f"{fam}_omnibus"} | ({f"{fam}_votes"} if fam == "2afc" else set())
        assert set(res.tables) - base == EXPECTED[test][fam], (test, fam)
    scale = analyze_log(logs["2afc"], AnalysisPlan(tests=(test,), reference="GT", n_boot=0,
                                                   per_scene=False)).tables.get("2afc_scale")
    if test == "thurstone":
        assert "jod" in scale.columns and "bt" not in scale.columns
    if test == "bradley_terry":
        assert "bt" in scale.columns and "jod" not in scale.columns


def test_preference_trials_get_plackett_luce(tmp_path):
    import pandas as pd

    rows = [(f"P{p}", "s", "preference", "A|B|C", "ABC"[(p + t) % 3], "ABC"[(p + t + 1) % 3])
            for p in range(5) for t in range(4)]
    log = validate_log(pd.DataFrame(rows, columns=["participant", "scene", "family", "conditions", "chosen",
                                                   "chosen_2"]))
    res = analyze_log(log, AnalysisPlan(tests=("plackett_luce",), n_boot=0, per_scene=False))
    assert "preference_scale" in res.tables
    # chosen counts first choices only, votes first and second
    chosen = analyze_log(log, AnalysisPlan(dv="chosen", tests=("summary_table",), n_boot=0, per_scene=False))
    votes = analyze_log(log, AnalysisPlan(dv="votes", tests=("summary_table",), n_boot=0, per_scene=False))
    assert chosen.tables["preference_units"]["value"].sum() == 20
    assert votes.tables["preference_units"]["value"].sum() == 40
    with pytest.raises(ValueError, match="dv='response' does not fit preference trials"):
        analyze_log(log, AnalysisPlan(dv="response"))


@pytest.mark.parametrize("path", sorted((ROOT / "protocols").glob("*.yaml")), ids=lambda p: p.name)
def test_shipped_protocols_are_valid_and_their_plans_load(path):
    doc = validate_document(load_yaml(path))
    plan = plan_from_mapping(doc["analysis"])
    assert set(plan.tests) <= set(V.TESTS)


def test_schema_refuses_unknown_tests_in_both_forms(tmp_path):
    base = (ROOT / "protocols" / "seed003_task1.yaml").read_text()
    for bad in ("test: kruskal_holm", "test: [summary_table, wilcoxon]", "test: []", "prior: gaussian"):
        p = tmp_path / "p.yaml"
        p.write_text(base.replace("test: summary_table", bad))
        with pytest.raises(ProtocolError, match="analysis"):
            validate_document(load_yaml(p))
    p.write_text(base.replace("test: summary_table", "test: [summary_table, gee]\n  prior: pwcmp"))
    assert plan_from_mapping(validate_document(load_yaml(p))["analysis"]).tests == ("summary_table", "gee")
