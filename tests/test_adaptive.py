"""The adaptive procedures (studyapp/runner/adaptive.py): QUEST+ against the questplus package step by step,
exact replay from the stored history, the transformed up-down rules and their convergence, the intensity axis."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from data_schema.intensity import Axis, grid
from studyapp.runner.adaptive import AdaptiveSpecError, check_spec, make_procedure, replay

LADDER = grid("log", 0.1, 1.5, 7)


def _spec(**over):
    spec = {"method": "quest_plus", "levels": LADDER, "scale": "log", "stronger": "lower", "guess": 0.5,
            "stop": {"trials": 40}, "function": "weibull"}
    spec.update(over)
    return spec


def intensity(spec, level):
    return Axis.of_spec(spec).to_intensity(level)


def test_intensity_axis_grows_with_foveation_and_inverts():
    # acuity_scale: lower is stronger -> x = -log10(v); delta: higher is stronger -> x = log10(v)
    assert intensity({"scale": "log", "stronger": "lower"}, 0.1) == pytest.approx(1.0)
    assert intensity({"scale": "log", "stronger": "higher"}, 100.0) == pytest.approx(2.0)
    assert intensity({"scale": "linear", "stronger": "lower"}, 3.0) == -3.0
    for spec in ({"scale": "log", "stronger": "lower"}, {"scale": "linear", "stronger": "higher"}):
        ax = Axis.of_spec(spec)
        assert ax.to_level(ax.to_intensity(0.37)) == pytest.approx(0.37)
        # scalars come back as floats, arrays element by element as the scalars
        assert type(ax.to_intensity(0.37)) is float and type(ax.to_level(0.5)) is float
        v = np.array([0.1, 0.37, 2.0])
        np.testing.assert_allclose(ax.to_intensity(v), [ax.to_intensity(s) for s in v], rtol=1e-15)
        np.testing.assert_allclose(ax.to_level(ax.to_intensity(v)), v, rtol=1e-12)
    assert grid("log", 0.1, 1.0, 3) == [0.1, 0.316228, 1.0]
    # a procedure's axis is its spec's, bounded by the ladder
    proc = make_procedure(_spec(), 0)
    assert proc.axis == Axis("log", "lower", (0.1, 1.5)) and proc.x == sorted(proc.x)


def test_quest_plus_credible_interval_is_the_central_mass_of_its_threshold_posterior():
    proc = make_procedure(_spec(), 3)
    for i, correct in [(0, True), (2, True), (5, False), (3, True), (4, False), (3, True)]:
        proc.update(LADDER[i], correct)
    t, marg = proc.posterior()
    np.testing.assert_allclose(t, np.linspace(proc.x[0], proc.x[-1], 31))
    assert marg.sum() == pytest.approx(1.0) and marg.shape == t.shape
    lo, hi = proc.credible_interval(0.95)
    inside = marg[(t >= lo) & (t <= hi)].sum()
    assert lo < proc.estimate()["mean"] < hi and inside >= 0.95
    # the narrowest such grid interval: dropping either end point leaves less than 97.5 % on that side
    assert marg[t <= lo].sum() >= 0.025 and marg[t >= hi].sum() >= 0.025
    lo50, hi50 = proc.credible_interval(0.5)
    assert lo <= lo50 <= hi50 <= hi and (hi50 - lo50) < (hi - lo)
    # a copy: changing it does not change the procedure
    t[:] = 0.0
    assert proc.posterior()[0][0] == proc.x[0]


@pytest.mark.parametrize("function", ["weibull", "logistic"])
def test_quest_plus_places_and_updates_as_the_questplus_package_does(function):
    """The numpy placement and update equal questplus' own next_stim/update at every step (30 trials)."""
    proc = make_procedure(_spec(function=function), seed=1)
    qp = proc._qp
    rng = np.random.default_rng(5)
    for _ in range(30):
        level = proc.next_level()
        ref = qp.next_stim["intensity"]
        assert intensity(proc.spec, level) == pytest.approx(ref, abs=1e-12)
        correct = bool(rng.random() < 0.7)
        qp.update(stim={"intensity": ref}, outcome={"response": "Correct" if correct else "Incorrect"})
        proc.update(level, correct)
        post = qp.posterior.transpose("threshold", "slope", "lower_asymptote", "lapse_rate").values.ravel()
        np.testing.assert_allclose(proc._post, post, rtol=1e-9, atol=1e-15)
    marg = qp.marginal_posterior["threshold"]
    assert proc.estimate()["mean"] == pytest.approx(float(np.sum(marg * qp.param_domain["threshold"])))


@settings(max_examples=25, deadline=None)
@given(answers=st.lists(st.booleans(), min_size=0, max_size=25),
       method=st.sampled_from(["quest_plus", "staircase"]))
def test_replay_of_the_history_reaches_the_same_state(answers, method):
    over = {"method": method} if method == "quest_plus" else {
        "method": "staircase", "rule": "1-up-2-down", "steps": [2, 1], "stop": {"trials": 40}}
    spec = _spec(**over)
    if method == "staircase":
        spec.pop("function")
    proc = make_procedure(spec, seed=3)
    levels = []
    for a in answers:
        levels.append(proc.next_level())
        proc.update(levels[-1], a)
    again = replay(spec, 3, proc.history)
    assert again.state() == proc.state()
    assert [lv for lv, _ in again.history] == levels


def test_staircase_1_up_2_down_steps_and_reversals():
    spec = {"method": "staircase", "levels": [1, 2, 3, 4, 5], "scale": "linear", "stronger": "higher",
            "rule": "1-up-2-down", "steps": [2, 1], "stop": {"trials": 100, "reversals": 3}}
    p = make_procedure(spec, 0)
    assert p.next_level() == 5  # starts at the strongest foveation (most detectable)
    p.update(5, True)
    assert p.next_level() == 5  # one correct: stay
    p.update(5, True)
    assert p.next_level() == 3  # two correct: down by the first step (2)
    p.update(3, False)
    assert p.next_level() == 4 and p.reversals == [3.0]  # wrong: up, a reversal, the step is now 1
    p.update(4, True)
    p.update(4, True)
    assert p.next_level() == 3 and p.reversals == [3.0, 4.0]
    p.update(3, False)
    assert p.reversals == [3.0, 4.0, 3.0] and p.finished()  # stop.reversals reached
    assert p.estimate()["mean"] == pytest.approx(10 / 3)


@pytest.mark.parametrize("rule,target", [("1-up-2-down", 0.5 ** 0.5), ("1-up-3-down", 0.5 ** (1 / 3))])
def test_staircase_converges_on_its_rules_target(rule, target):
    """Levitt 1971: 1-up-n-down tracks p = 0.5^(1/n) correct. A logistic observer (2afc, no lapse) on a fine
    ladder; the mean of the reversals over 40 runs of 200 trials lies within 0.05 of the target's level."""
    levels = [round(0.02 * i, 2) for i in range(101)]  # intensity 0 .. 2
    t, b = 1.0, 6.0

    def p_correct(x):
        return 0.5 + 0.5 / (1.0 + math.exp(-b * (x - t)))

    x_target = t - math.log(0.5 / (target - 0.5) - 1.0) / b
    rng = np.random.default_rng(11)
    means = []
    for _ in range(40):
        p = make_procedure({"method": "staircase", "levels": levels, "scale": "linear", "stronger": "higher",
                            "rule": rule, "steps": [4, 1], "stop": {"trials": 200}, "estimate_reversals": 100},
                           0)
        while not p.finished():
            lv = p.next_level()
            p.update(lv, bool(rng.random() < p_correct(lv)))
        means.append(np.mean(p.reversals[4:]))
    assert abs(np.mean(means) - x_target) < 0.05


def test_quest_plus_recovers_a_known_threshold():
    """40 trials of QUEST+ (logistic) against an observer of the same family: the median estimate of 30 runs
    lies within 0.1 log10 units of the true threshold."""
    spec = _spec(function="logistic", levels=grid("log", 0.05, 1.5, 15))
    true_t, slope = intensity(spec, 0.3), 8.0
    rng = np.random.default_rng(2)
    est = []
    for _ in range(30):
        p = make_procedure(spec, 0)
        while not p.finished():
            lv = p.next_level()
            x = intensity(spec, lv)
            p.update(lv, bool(rng.random() < 0.5 + 0.48 / (1 + math.exp(-slope * (x - true_t)))))
        est.append(p.estimate()["mean"])
    assert abs(np.median(est) - true_t) < 0.1


@pytest.mark.parametrize("over,message", [
    ({"levels": [0.5]}, "a ladder of one level"),
    ({"stop": {}}, "can never stop"),
    ({"stop": {"trials": 10, "sd_below": 0}}, "can never stop"),
    ({"stop": {"trials": 10, "reversals": 4}}, r"QUEST\+ has no reversals"),
    ({"levels": [0.5, "x"]}, "not a finite number"),
    ({"levels": [0.0, 1.0]}, "positive levels"),
    ({"method": "staircase", "stop": {"trials": 10, "sd_below": 0.1}}, "a staircase has no posterior"),
])
def test_specs_that_cannot_run_are_refused_in_one_line(over, message):
    with pytest.raises(AdaptiveSpecError, match=message) as info:
        check_spec(_spec(**over))
    assert "\n" not in str(info.value)


def test_sd_below_stops_quest_plus_early():
    p = make_procedure(_spec(stop={"trials": 200, "sd_below": 0.08}), 0)
    while not p.finished():
        lv = p.next_level()
        p.update(lv, intensity(p.spec, lv) > 0.4)
    assert len(p.history) < 200 and p.estimate()["sd"] < 0.08
