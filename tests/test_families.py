"""Trial families (data_schema.families): each module's declarations are consistent and used everywhere."""

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from data_schema import families
from data_schema.families import Observer
from data_schema.trial_log import FAMILY_COLUMNS

ROOT = Path(__file__).resolve().parents[1]
CONDS = ("GT", "VaFR", "LaFR", "LMFR")


class Stream:
    """A deterministic stand-in for the scheduler's random stream."""

    def __init__(self):
        self.rng = np.random.default_rng(0)

    def below(self, n):
        return int(self.rng.integers(n))

    def shuffle(self, items):
        items = list(items)
        self.rng.shuffle(items)
        return items


def test_the_schema_lists_exactly_the_families():
    schema = json.loads((ROOT / "data_schema" / "protocol.schema.json").read_text())
    assert tuple(schema["properties"]["family"]["enum"]) == families.NAMES == ("2afc", "preference", "yes_no")
    assert set(FAMILY_COLUMNS) == set(families.NAMES)


@pytest.mark.parametrize("name", families.NAMES)
def test_declarations_agree_with_each_other(name):
    fam = families.get(name)
    keys = fam.default_keys(len(CONDS))
    assert set(keys["answer"].values()) <= fam.answer_values(len(CONDS))
    assert all(0 <= i <= fam.max_switch(len(CONDS)) for i in keys["switch"].values())
    assert not set(keys["answer"]) & set(keys["switch"])
    assert fam.record_dv in fam.dvs and fam.default_dv in fam.dvs
    assert set(fam.scale_tests) <= set(fam.tests)
    assert set(fam.tidy_columns(CONDS)) <= set(fam.log_columns) | set(fam.condition_columns)
    assert len(fam.labels(2 if name == "2afc" else len(CONDS))) == (2 if name == "2afc" else
                                                                    len(CONDS) if name == "preference" else 4)


@pytest.mark.parametrize("name", families.NAMES)
def test_what_the_analysis_and_the_report_ask_is_declared(name):
    """analysis/ and the report read these instead of testing the family's name (tests/test_architecture.py):
    a scale has a scaling in analysis.study.SCALES, a GEE its captions, a plan asking for a GEE the family has
    none of a note, the ``chosen`` dependent variable its words, and every family exports CSV and Parquet."""
    from analysis.study import SCALES

    fam = families.get(name)
    assert (fam.scale_model is None) == (not fam.scale_tests)
    assert fam.scale_model is None or fam.scale_model in SCALES
    if "gee" in fam.tests:
        assert fam.gee_odds_caption and fam.gee_note and not fam.no_gee_note
    else:
        assert fam.no_gee_note and not fam.gee_odds_caption
    assert bool(fam.chosen_caption) == ("chosen" in fam.dvs)
    assert {"csv", "parquet"} <= set(fam.exports) and ("pwcmp" in fam.exports) == (fam.scale_model == "pairs")


def test_declared_values():
    two, pref, yn = (families.get(n) for n in ("2afc", "preference", "yes_no"))
    assert (two.scale_model, pref.scale_model, yn.scale_model) == ("pairs", "rankings", None)
    assert (two.chosen_caption, pref.chosen_caption) == ("times chosen", "times chosen first")
    assert yn.gee_odds_caption == "odds of a yes against" and two.exports == ("csv", "parquet", "pwcmp")
    assert families.single_stimulus() is yn


@pytest.mark.parametrize("name,reps,expected", [("2afc", 3, 6 * 3), ("yes_no", 2, 4 * 2), ("preference", 5, 5)])
def test_schedule_items_of_one_scene(name, reps, expected):
    fam = families.get(name)
    items = fam.main_items(CONDS, "temple", reps, position_balance=True, flip_seed=1, stream=Stream())
    assert len(items) == expected
    lo, hi = fam.stimuli_range(len(CONDS))
    assert all(lo <= len(i["conditions"]) <= hi and i["scene"] == "temple" for i in items)
    if name == "2afc":  # every pair, balanced: each order shown as often as the other (odd repetition aside)
        for a, b in itertools.combinations(CONDS, 2):
            orders = [i["conditions"] for i in items if set(i["conditions"]) == {a, b}]
            assert len(orders) == 3 and abs(orders.count((a, b)) - orders.count((b, a))) == 1


@pytest.mark.parametrize("name", families.NAMES)
def test_simulated_answers_are_answers_the_family_interprets(name):
    fam = families.get(name)
    rng = np.random.default_rng(1)
    n = {"2afc": 2, "yes_no": 1, "preference": len(CONDS)}[name]
    shown = CONDS[:n]
    for lapse in (False, True):
        for _ in range(20):
            answers, margin, switches = fam.simulate(list(rng.uniform(0, 5, n)), Observer(1.0, 0.0, 1.0), rng,
                                                     lapse, 2)
            got = fam.interpret(shown, answers, 2)
            assert margin >= 0 and switches >= 0
            if fam.kind == "score":
                assert got["response"] in (0, 1) and got["chosen"] == ""
            else:
                assert got["chosen"] in shown and got["response"] is None
    with pytest.raises(ValueError):
        fam.interpret(shown, ["maybe"], 2)


def test_a_clearly_worse_stimulus_loses():
    rng = np.random.default_rng(0)
    obs = Observer(sensitivity=2.0, bias=0.0, criterion=1.0)
    two = families.get("2afc")
    wins = sum(two.simulate([0.0, 4.0], obs, rng, False, 1)[0] == ["A"] for _ in range(200))
    assert wins > 190  # A (no impairment) against B (4 JND)
    yn = families.get("yes_no")
    yes = sum(yn.simulate([0.0], obs, rng, False, 1)[0] == ["yes"] for _ in range(200))
    assert yes > 180  # 0 JND against a criterion of 1 JND


@pytest.mark.parametrize("name", families.NAMES)
def test_export_columns_are_columns_the_family_logs(name):
    """An export layout a family declares (``export_columns``: layout -> tidy-log columns) takes only columns its
    trials fill; pwcmp takes three (first/left, second/right, chosen), and only the pair family declares it."""
    fam = families.get(name)
    logged = set(fam.log_columns) | set(fam.condition_columns)
    assert all(set(cols) <= logged for cols in fam.export_columns.values())
    assert all(len(cols) == 3 for layout, cols in fam.export_columns.items() if layout == "pwcmp")
    assert ("pwcmp" in fam.export_columns) == (fam.condition_columns == ("condition_a", "condition_b"))
