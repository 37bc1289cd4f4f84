"""Adaptive designs in protocols: the four shipped threshold protocols, their level conditions (the ladder), and
every bad adaptive design refused in one line with exit status 2 and nothing created (issue 28 item 9)."""

import os
from pathlib import Path

import pytest

from data_schema.intensity import Axis
from data_schema.protocol_schema import ProtocolError
from studyapp.runner.protocol import load_protocol
from studyapp.runner.schedule import build_schedule
from studyapp.runner.stimuli import needed_stimuli

ROOT = Path(__file__).resolve().parents[1]
PROTOCOLS = ROOT / "studyapp" / "protocols"
BASE = PROTOCOLS / "threshold_foveation.yaml"
THRESHOLDS = ["threshold_foveation", "threshold_foveation_live", "seed003_alpha_threshold",
              "latency_threshold_live"]


def _edit(tmp_path, old, new, base=BASE):
    text = base.read_text()
    assert old in text, old
    f = tmp_path / "p.yaml"
    f.write_text(text.replace(old, new, 1))
    return f


def test_the_ladder_is_the_prepared_stimulus_set():
    p = load_protocol(BASE)
    vafr = p.adaptive.varied["VaFR"]
    assert (vafr.param, vafr.stronger, len(vafr.levels)) == ("acuity_scale", "lower", 7)
    assert vafr.levels[0] == 0.1 and vafr.levels[-1] == 1.5
    assert p.conditions["VaFR(0.1)"].params == {"acuity_scale": 0.1}
    assert p.conditions["LaFR(8)"].params == {"delta": 8.0}
    need = {(n.condition, n.scene) for n in needed_stimuli(p)}
    assert len(need) == 2 * (3 * 7 + 1) and ("LMFR(1.2)", "temple") in need and ("VaFR", "temple") not in need
    # the detection axis: stronger VaFR (lower acuity_scale) has the higher intensity
    spec = p.adaptive.spec("VaFR")
    assert Axis.of_spec(spec).to_intensity(0.1) > Axis.of_spec(spec).to_intensity(1.5)
    sched = build_schedule(p, "P1", 0)
    assert len(sched) == 3 * 2 * 40
    by_proc = {}
    for t in sched:
        test = [c for c in t.conditions if c != "GT"][0]
        by_proc[(test, t.scene)] = by_proc.get((test, t.scene), 0) + 1
        assert "GT" in t.conditions and len(t.conditions) == 2
    assert set(by_proc.values()) == {40} and len(by_proc) == 6
    # a scene block interleaves its three procedures
    first = [t for t in sched if t.scene == sched[0].scene][:12]
    assert len({c for t in first for c in t.conditions}) == 4


@pytest.mark.parametrize("name", THRESHOLDS)
def test_shipped_threshold_protocols_validate(name, capsys):
    from studyapp.commands.study import main

    assert main(["validate", str(PROTOCOLS / f"{name}.yaml"), "--scale", "0.1"]) == 0
    out = capsys.readouterr().out
    assert "valid" in out and "adaptive:" in out


def test_latency_protocol_varies_delta_at_five_gaze_latencies():
    p = load_protocol(PROTOCOLS / "latency_threshold_live.yaml")
    assert sorted(p.conditions[c].latency_ms for c in p.adaptive.varied) == [0, 20, 40, 80, 150]
    assert all(v.param == "delta" and v.stronger == "higher" for v in p.adaptive.varied.values())
    assert p.conditions["LaFR_150ms(8)"].latency_ms == 150


def test_yes_no_alpha_protocol_shows_the_varied_condition_alone_after_the_labelled_truth():
    p = load_protocol(PROTOCOLS / "seed003_alpha_threshold.yaml")
    sched = build_schedule(p, "P1", 0)
    assert sched[0].kind == "reference" and sched[0].conditions == ("GT",)
    trials = [t for t in sched if t.kind == "trial"]
    assert len(trials) == 80 and {t.conditions for t in trials} == {("FSL",)}
    assert p.adaptive.guess == (0.0, 0.05, 0.1, 0.2)  # the yes/no false-alarm grid


CASES = [
    # a domain outside the parameter's allowed range
    ("VaFR: {param: acuity_scale, scale: log, min: 0.1,", "VaFR: {param: acuity_scale, scale: log, min: 0.01,",
     "design.adaptive.vary.VaFR.levels: vafr.acuity_scale=0.01 is out of range: allowed [0.05, 2]"),
    # a non-numeric parameter
    ("VaFR: {param: acuity_scale,", "VaFR: {param: stereo,", "vafr.stereo is not numeric"),
    # a reference that is itself adaptive
    ("reference: GT", "reference: VaFR", "design.adaptive.reference: 'VaFR' is itself varied"),
    # a ladder of one level
    ("LaFR: {param: delta, scale: log, min: 1.2, max: 8.0, levels: 7}",
     "LaFR: {param: delta, scale: log, min: 1.2, max: 8.0, levels: 1}", "a ladder of one level"),
    ("LaFR: {param: delta, scale: log, min: 1.2, max: 8.0, levels: 7}", "LaFR: {param: delta, levels: [2.0]}",
     "a ladder of one level"),
    # stopping rules that can never stop
    ("stop: {trials: 40}", "stop: {sd_below: 0.05}", "design.adaptive.stop: the stopping rule can never stop"),
    ("stop: {trials: 40}", "stop: {trials: 40, sd_below: 0}", "the stopping rule can never stop"),
    # a family without a correct answer
    ("family: 2afc", "family: preference", "preference trials have no correct answer"),
    # others
    ("LMFR: {param: delta,", "LMFR: {param: gamma,", "renderer 'lmfr' has no parameter 'gamma'"),
    ("procedure: {method: quest_plus, function: weibull}", "procedure: {method: staircase, function: weibull}",
     "belongs to method quest_plus"),
    ("procedure: {method: quest_plus, function: weibull}", "procedure: {method: quest_plus, guess: [0.1]}",
     "2afc trials guess 0.5"),
    ("  adaptive:\n", "  repetitions: 2\n  adaptive:\n", "give repetitions (a fixed design) or adaptive"),
]


@pytest.mark.parametrize("old,new,message", CASES)
def test_bad_adaptive_designs_are_refused_in_one_line(tmp_path, capsys, old, new, message):
    from studyapp.commands.study import main

    f = _edit(tmp_path, old, new)
    with pytest.raises(ProtocolError) as info:
        load_protocol(f)
    assert message in str(info.value) and str(info.value).startswith(f"{f}:")
    before = sorted(os.listdir(tmp_path))
    assert main(["validate", str(f)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("studyapp: error: ") and message in err
    assert sorted(os.listdir(tmp_path)) == before  # nothing created


def test_bad_adaptive_design_line_number_points_at_the_field(tmp_path):
    f = _edit(tmp_path, "reference: GT", "reference: VaFR")
    line = next(i for i, t in enumerate(f.read_text().splitlines(), 1) if "reference: VaFR" in t)
    with pytest.raises(ProtocolError, match=rf"^{f}:{line}: "):
        load_protocol(f)
