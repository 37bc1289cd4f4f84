"""Known-truth recovery of the adaptive procedures against the declared psychometric observer (issue 28 item 6),
in small bounded versions; benchmarks/bench_thresholds.py runs the 200-participant ones."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from data_schema.intensity import Axis, grid
from studyapp.runner.observer import DeclaredFunction, declared_function
from studyapp.runner.threshold_study import run_procedure

LEVELS = grid("log", 0.05, 2.0, 24)
QUEST = {"method": "quest_plus", "levels": LEVELS, "scale": "log", "stronger": "lower", "guess": 0.5,
         "stop": {"trials": 40}, "function": "weibull"}
TRUE = DeclaredFunction("VaFR", QUEST, Axis.of_spec(QUEST).to_intensity(0.4), 3.5, 0.02, 0.5)


def test_quest_plus_recovers_the_declared_threshold_and_its_intervals_cover_it():
    """60 simulated participants, 40 trials each: the median posterior-mean threshold lies within 0.1 log10
    units of the declared one, and the 95 % credible intervals cover it in 85-100 % of them (the benchmark's
    200 participants: 90-99 %)."""
    est, covered = [], []
    for i in range(60):
        proc, steps = run_procedure(QUEST, TRUE, 1000 + i)
        assert len(steps) == 40
        est.append(proc.estimate()["mean"])
        lo, hi = proc.credible_interval(0.95)
        covered.append(lo <= TRUE.threshold <= hi)
    assert abs(np.median(est) - TRUE.threshold) < 0.1
    assert 0.85 <= np.mean(covered) <= 1.0
    # the estimates spread: not the prior's mean returned regardless of the answers
    assert np.std(est) > 0.01


def test_one_up_two_down_staircase_converges_to_70_7_percent_correct():
    spec = {"method": "staircase", "levels": LEVELS, "scale": "log", "stronger": "lower", "rule": "1-up-2-down",
            "steps": [1], "stop": {"trials": 80}}
    p = [float(TRUE.p_correct(run_procedure(spec, TRUE, 5000 + i)[0].estimate()["mean"])) for i in range(60)]
    assert np.median(p) == pytest.approx(0.707, abs=0.04)
    spec3 = {**spec, "rule": "1-up-3-down"}
    p3 = [float(TRUE.p_correct(run_procedure(spec3, TRUE, 7000 + i)[0].estimate()["mean"])) for i in range(60)]
    assert np.median(p3) == pytest.approx(0.794, abs=0.04)


def test_run_procedure_is_reproducible_and_answers_depend_on_the_level():
    a = run_procedure(QUEST, TRUE, 7)[1]
    b = run_procedure(QUEST, TRUE, 7)[1]
    assert a == b and run_procedure(QUEST, TRUE, 8)[1] != a
    # far stronger than the threshold (lower acuity scale): nearly always correct; far weaker: near chance
    assert TRUE.p_correct(TRUE.intensity(0.05)) > 0.97 and TRUE.p_correct(TRUE.intensity(2.0)) < 0.52
    assert TRUE.p_correct(TRUE.threshold) == pytest.approx(1 - 0.02 - 0.48 * np.exp(-1))
    assert TRUE.level_at(float(TRUE.p_correct(TRUE.intensity(0.3)))) == pytest.approx(0.3, rel=1e-6)


def test_declared_function_reads_the_simulation_block_with_scene_overrides_and_participant_spread():
    adaptive = SimpleNamespace(varied={"VaFR": None}, spec=lambda c: dict(QUEST))
    protocol = SimpleNamespace(family="2afc", adaptive=adaptive, simulation={
        "threshold_sd": 0.1, "psychometric": {"VaFR": {"threshold": 0.4, "slope": 2.0,
                                                        "scenes": {"street": {"threshold": 0.2}}}}})
    f = declared_function(protocol, "VaFR", "temple", "P01", 0)
    g = declared_function(protocol, "VaFR", "street", "P01", 0)
    assert f.guess == 0.5 and f.slope == 2.0 and f.lapse == 0.02
    spread = [declared_function(protocol, "VaFR", "temple", f"P{i:02d}", 0).threshold for i in range(200)]
    assert np.mean(spread) == pytest.approx(Axis.of_spec(QUEST).to_intensity(0.4), abs=0.03)
    assert np.std(spread) == pytest.approx(0.1, abs=0.02)
    exact = SimpleNamespace(**{**vars(protocol), "simulation": {**protocol.simulation, "threshold_sd": 0.0}})
    t, s = (declared_function(exact, "VaFR", sc, "P01", 0).threshold for sc in ("temple", "street"))
    assert (t, s) == pytest.approx((-np.log10(0.4), -np.log10(0.2)))  # street's override; stronger: lower
    assert g != f
    assert declared_function(protocol, "LaFR", "temple", "P01", 0) is None
    assert f == declared_function(protocol, "VaFR", "temple", "P01", 0)  # seeded
