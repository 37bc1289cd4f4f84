"""Simulated observer: eccentricity from display geometry, the foveated difference, psychometric answers."""

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from data_schema.families.base import phi
from studyapp.presentation.base import Stimulus, TrialDisplay
from studyapp.runner.images import save_png
from studyapp.runner.observer import (
    E2_DEG,
    SimulatedObserver,
    foveated_difference,
    participant_params,
)
from studyapp.runner.protocol import load_protocol
from studyapp.runner.stimuli import synthetic_scene

PROTOCOLS = Path(__file__).resolve().parents[1] / "protocols"


def test_the_observer_uses_the_stimuli_viewing_geometry(task1):
    """Eccentricity comes from the one geometry: the display's visual angle at the image's resolution."""
    obs = SimulatedObserver(task1, "P1", 0, {})
    ecc = obs._eccentricity((36, 64))
    want = task1.render_geometry().resized(64, 36).eccentricity_map()
    np.testing.assert_array_equal(ecc, want)
    assert task1.render_geometry().fov_y_deg == pytest.approx(task1.display.fov_y_deg)


def test_foveated_difference_weights_the_fovea_more():
    ecc = np.array([[0.0, 10.0]])
    gt = np.zeros((1, 2))
    w0, w1 = 1.0, E2_DEG / (10.0 + E2_DEG)
    fovea = foveated_difference(np.array([[0.5, 0.0]]), gt, ecc)
    periphery = foveated_difference(np.array([[0.0, 0.5]]), gt, ecc)
    assert fovea == pytest.approx(math.sqrt(w0 * 0.25 / (w0 + w1)))
    assert periphery == pytest.approx(math.sqrt(w1 * 0.25 / (w0 + w1)))
    assert foveated_difference(gt, gt, ecc) == 0.0
    with pytest.raises(ValueError, match="shapes differ"):
        foveated_difference(np.zeros((2, 2)), gt, ecc)


def test_participant_parameters_are_seeded():
    sim = load_protocol(PROTOCOLS / "seed003_task1.yaml", check_renderers=False).simulation
    a = participant_params(sim, "P1", 0)
    assert a == participant_params(sim, "P1", 0)
    assert a != participant_params(sim, "P2", 0)
    assert a.lapse == sim["lapse"] and a.sensitivity > 0


def _trial(i, family, conds, scene="s", n_picks=1, duration=None):
    return TrialDisplay(index=i, family=family, stimuli=tuple(Stimulus(c, ()) for c in conds), question="?",
                        answer_keys={}, scene=scene, n_picks=n_picks, duration_s=duration)


@pytest.fixture(scope="module")
def task1():
    return load_protocol(PROTOCOLS / "seed003_task1.yaml", check_renderers=False)


def test_yes_rate_falls_with_impairment_and_matches_the_model(task1):
    rates = {}
    for cond in ("CC1", "EC", "CC3", "CC2"):
        yes, n = 0, 0
        for p in range(40):
            obs = SimulatedObserver(task1, f"P{p}", 1, {})
            for i in range(10):
                yes += obs.present(_trial(i, "yes_no", [cond])).answers == ["yes"]
                n += 1
        rates[cond] = yes / n
    assert rates["CC1"] > rates["EC"] > rates["CC3"] > rates["CC2"]
    # Population mean of the model for GT (D = 0): E[Phi(s c + b)] with s ~ lognormal, b ~ normal.
    sim = task1.simulation
    rng = np.random.default_rng(0)
    s = np.exp(sim["sensitivity_sd"] * rng.standard_normal(20000))
    b = sim["bias_sd"] * rng.standard_normal(20000)
    lam = sim["lapse"]
    want = np.mean([lam / 2 + (1 - lam) * phi(si * sim["criterion_jnd"] + bi) for si, bi in zip(s, b)])
    assert rates["CC1"] == pytest.approx(want, abs=0.06)


def test_2afc_prefers_the_less_impaired_and_lapses_bound_it(task1):
    wins = 0
    for p in range(30):
        obs = SimulatedObserver(task1, f"Q{p}", 2, {})
        for i in range(10):
            conds = ("CC2", "CC1") if i % 2 else ("CC1", "CC2")
            r = obs.present(_trial(i, "2afc", conds))
            wins += conds["AB".index(r.answers[0])] == "CC1"
    frac = wins / 300
    assert 0.9 < frac <= 1.0 - task1.simulation["lapse"] / 2 + 0.03


def test_preference_picks_top_two_or_one(task1):
    obs = SimulatedObserver(task1, "R1", 0, {})
    r = obs.present(_trial(0, "preference", ["CC2", "CC1", "CC3", "EC", "CC4"], n_picks=2))
    assert 1 <= len(r.answers) <= 2 and len(set(r.answers)) == len(r.answers)
    assert all(a in {"0", "1", "2", "3", "4"} for a in r.answers)
    firsts = [SimulatedObserver(task1, f"R{p}", 0, {}).present(
        _trial(0, "preference", ["CC2", "CC1", "CC3"], n_picks=2)).answers[0] for p in range(40)]
    assert firsts.count("1") > 30


def test_rt_is_ex_gaussian_after_the_sequence(task1):
    obs = SimulatedObserver(task1, "T1", 0, {})
    rts = np.array([obs.present(_trial(i, "yes_no", ["EC"], duration=8.0)).rt_s for i in range(300)])
    p = obs.params
    assert rts.min() >= 8.15
    extra = rts - 8.0
    assert extra.mean() == pytest.approx(p.rt_mu_s * 1.1 + p.rt_tau_s, rel=0.25)


def test_same_trial_same_answer_across_instances(task1):
    a = SimulatedObserver(task1, "U1", 5, {}).present(_trial(17, "yes_no", ["CC3"]))
    b = SimulatedObserver(task1, "U1", 5, {}).present(_trial(17, "yes_no", ["CC3"]))
    assert (a.answers, a.rt_s) == (b.answers, b.rt_s)


def test_images_are_used_when_present(tmp_path, task1):
    w, h = 40, 24
    gt = synthetic_scene(w, h, "s")
    save_png(tmp_path / "gt.png", gt)
    save_png(tmp_path / "same.png", gt)
    noisy = np.clip(gt + np.random.default_rng(0).normal(0, 0.2, gt.shape), 0, 1)
    save_png(tmp_path / "noisy.png", noisy)
    obs = SimulatedObserver(task1, "V1", 0, {"s": Stimulus("CC1", (tmp_path / "gt.png",))})
    assert obs.impairment(Stimulus("EC", (tmp_path / "same.png",)), "s") == 0.0  # declared quality ignored
    d = obs.impairment(Stimulus("CC2", (tmp_path / "noisy.png",)), "s")
    assert d > 3.0  # ~0.2 RMS noise on a 0.02 JND scale (clipping shrinks it a little)
    assert obs.impairment(Stimulus("CC2", ()), "s") == pytest.approx(5 * (1 - task1.conditions["CC2"].quality))


def test_condition_without_images_or_quality_is_an_error(task1, tmp_path):
    import dataclasses

    from studyapp.runner.protocol import Condition
    conds = dict(task1.conditions)
    conds["EC"] = Condition("EC", renderer="fsl")
    p = dataclasses.replace(task1, conditions=conds)
    with pytest.raises(ValueError, match="condition EC: no stimuli for scene s and no declared quality"):
        SimulatedObserver(p, "W", 0, {}).impairment(Stimulus("EC", ()), "s")


@given(st.integers(0, 2**32 - 1), st.floats(0.1, 4.0))
def test_foveated_difference_is_a_weighted_rms(seed, k):
    rng = np.random.default_rng(seed)
    gt = rng.random((6, 9))
    err = rng.normal(0, 0.1, (6, 9))
    ecc = rng.uniform(0, 40, (6, 9))
    d = foveated_difference(gt + err, gt, ecc)
    assert d == pytest.approx(foveated_difference(gt, gt + err, ecc), rel=1e-12)  # symmetric
    assert foveated_difference(gt + k * err, gt, ecc) == pytest.approx(k * d, rel=1e-9)  # homogeneous
    w = E2_DEG / (ecc + E2_DEG)
    assert d == pytest.approx(math.sqrt((w * err**2).sum() / w.sum()), rel=1e-9)
    assert abs(err).min() - 1e-12 <= d <= abs(err).max() + 1e-12  # a weighted mean of |err|^2


def test_a_live_condition_too_coarse_for_a_64_pixel_thumbnail_is_still_simulated(tmp_path, monkeypatch, capsys):
    """LaFR delta 12 passes validation at 320x180 (15 LP rows) but has 3 rows at the observer's 64x36
    thumbnail (fewer than the 4 a render needs): the observer takes a thumbnail twice as wide, so a run that
    validate accepted completes instead of dying after its first answer."""
    from studyapp.cli import main
    from studyapp.runner.observer import SIM_WIDTH
    from tests.crafted_db import live_protocol

    protocol = live_protocol(tmp_path, params="{delta: 12}", render_px=(320, 180), repetitions=1)
    assert main(["validate", str(protocol)]) == 0
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(protocol), "--participant", "P1", "--db", "t.db", "--simulate"]) == 0
    assert "completed, 1/1 trials answered" in capsys.readouterr().out
    from studyapp.runner.live import live_stimulus

    p = load_protocol(protocol)
    live = live_stimulus(p, "LaFR", "cornell")
    obs = SimulatedObserver(p, "P1", 0, {})
    assert obs._thumbnail_size(live, p.conditions["Ref"]) == (2 * SIM_WIDTH, 72)
