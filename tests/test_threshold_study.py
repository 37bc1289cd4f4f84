"""A threshold study end to end, small: simulated sessions of threshold_foveation (declared observer), `studyapp
analyze` on the database (fits, group table, Pareto table and figure), `studyapp power`, one-line refusals."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from studyapp.cli import main
from studyapp.commands.study import SHIPPED, _protocol, simulated_study
from studyapp.runner.observer import declared_function


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """threshold_foveation with 20 trials per procedure, 3 simulated participants, in a fresh database."""
    import yaml

    d = tmp_path_factory.mktemp("thr")
    data = yaml.safe_load((SHIPPED / "threshold_foveation.yaml").read_text())
    data["design"]["adaptive"]["stop"] = {"trials": 20}
    path = d / "thr.yaml"
    path.write_text(yaml.safe_dump(data))
    p = _protocol(str(path), stimuli=str(d / "stimuli"))
    db = simulated_study(p, d / "thr.db", 3, allow_declared=True)
    return p, db, path


def _fake_cost_table(scene, renderer, levels, width, height, *, params=None, reference=None,
                     reference_params=None, gaze=None, camera=None, cache_dir=None):
    """renderers.cost.cost_table's columns with counts that fall as 1/level (delta) or grow as the level
    (acuity_scale), GT 1000 per pixel: the real counts need renders (tests/test_strength_cost.py checks them)."""
    lv = np.asarray(sorted(levels), float)
    work = width * height * (lv if renderer == "vafr" else 1.0 / lv)
    return pd.DataFrame({"scene": scene, "renderer": renderer, "level": lv, "work": work,
                         "gt_work": 1000.0 * width * height})


def test_analyze_writes_fits_group_and_pareto_of_an_adaptive_study(study, tmp_path, capsys, monkeypatch):
    import renderers.cost

    monkeypatch.setattr(renderers.cost, "cost_table", _fake_cost_table)
    p, db, _ = study
    out = tmp_path / "rep"
    assert main(["analyze", str(db), "--out", str(out), "--cost-scale", "0.1", "--n-boot", "200"]) == 0
    assert "wrote" in capsys.readouterr().out
    fits = pd.read_csv(out / "tables" / "thresholds_fits.csv")
    assert len(fits) == 3 * 3 * 2 + 3 * 2  # participants x renderers x scenes, and the pooled fits
    assert (fits["n_trials"][fits["participant"] != "(pooled)"] == 20).all()
    pooled = fits[fits["participant"] == "(pooled)"].set_index(["condition", "scene"])
    for (c, s), r in pooled.iterrows():  # the declared observer's level at 75 % correct, within 0.3 log10
        truth = declared_function(p, c, s, "P01", 0)
        exact = truth.level_at(0.75)
        assert r["estimable"] and r["ci_low"] < r["threshold"] < r["ci_high"]
        assert abs(math.log10(r["threshold"] / exact)) < 0.3, (c, s, r["threshold"], exact)
    pareto = pd.read_csv(out / "tables" / "thresholds_pareto.csv")
    assert len(pareto) == 6
    assert np.allclose(pareto["relative_cost"], pareto["cost"] / pareto["gt_cost"])
    # the cost at the threshold, interpolated in log-log between ladder levels: exact for a power law
    w, h = (round(v * 0.1) for v in p.render_size)
    expect = np.where(pareto["condition"] == "VaFR", pareto["threshold"], 1.0 / pareto["threshold"]) * w * h
    assert np.allclose(pareto["cost"], expect, rtol=1e-9) and (pareto["gt_cost"] == 1000.0 * w * h).all()
    assert (pareto["cost_ci_low"] <= pareto["cost"]).all() and (pareto["cost"] <= pareto["cost_ci_high"]).all()
    for name in ("pareto.png", "fits_P01.png", "fits_pooled.png"):
        assert (out / "figures" / name).stat().st_size > 10_000
    report = (out / "report.md").read_text()
    assert "Prior: psignifit 4 default priors" in report and "Speed at threshold" in report
    assert json.loads((out / "analysis.json").read_text())["criterion"] == 0.75


def test_power_prints_ci_widths_and_pair_probabilities_reproducibly(study, capsys, monkeypatch):
    import renderers.cost

    monkeypatch.setattr(renderers.cost, "cost_table", _fake_cost_table)
    _, _, path = study
    argv = ["power", str(path), "--participants", "3", "--trials", "16", "--replications", "2", "--seed", "4",
            "--cost-scale", "0.1"]
    assert main(argv) == 0
    first = capsys.readouterr().out
    assert "3 participants, 16 trials per procedure, 2 simulated studies, seed 4" in first
    for line in ("VaFR         temple", "P(told apart)"):
        assert line in first
    pairs = [ln for ln in first.splitlines() if " vs " in ln]
    assert len(pairs) == 3 * 2  # renderer pairs x scenes
    # LaFR and LMFR vary the same parameter (delta): compared on it; VaFR's acuity_scale only through the cost
    assert all(("strength axis" in ln) == ("VaFR" not in ln) for ln in pairs)
    assert all(ln.endswith("%") for ln in pairs)
    assert main(argv) == 0
    assert capsys.readouterr().out == first


def test_power_and_analyze_refuse_in_one_line(study, tmp_path, capsys):
    _, db, path = study
    fixed = SHIPPED / "seed001_2afc.yaml"
    assert main(["power", str(fixed), "--participants", "3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "has no adaptive design" in err[0]
    import yaml

    data = yaml.safe_load(path.read_text())
    del data["simulation"]["psychometric"]["LMFR"]
    bare = tmp_path / "bare.yaml"
    bare.write_text(yaml.safe_dump(data))
    assert main(["power", str(bare), "--participants", "2", "--trials", "4", "--replications", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "LMFR: no declared psychometric function" in err[0]  # before any rendering
    assert not (tmp_path / "none").exists()
    assert main(["power", str(path), "--participants", "0"]) == 2


def _frame_times_csv(p, path, scale=0.1, drop=None, size=None):
    """A crafted frame-time CSV of ``p``'s ladders (no timing): ms = 10 x level (VaFR) or 100 / level (delta),
    GT 500 ms; ``drop``: (condition, scene, level) left out; ``size``: another (w, h)."""
    from studyapp.runner.threshold_study import cost_size

    w, h = size or cost_size(p, scale)
    rows = [{"protocol": p.name, "backend": "cpu", "width": w, "height": h, "condition": "GT", "renderer": "gt",
             "param": "", "level": "", "scene": s, "median_ms": 500.0, "repeats": 3, "machine": "test"}
            for s in p.scenes]
    for c, v in p.adaptive.varied.items():
        for s in p.scenes:
            for lv in v.levels:
                if drop != (c, s, lv):
                    rows.append({**rows[0], "condition": c, "renderer": p.conditions[c].renderer, "param": v.param,
                                 "level": lv, "scene": s, "median_ms": 10 * lv if c == "VaFR" else 100 / lv})
    pd.DataFrame(rows).to_csv(path, index=False)
    return path


def test_frame_times_interpolate_in_log_level_and_log_time_between_ladder_levels(study, tmp_path):
    from studyapp.runner.threshold_study import frame_times

    p, _, _ = study
    path = _frame_times_csv(p, tmp_path / "t.csv")
    df = pd.read_csv(path)
    lv = p.adaptive.varied["LaFR"].levels
    df.loc[(df["condition"] == "LaFR") & (df["scene"] == "temple") & (df["level"] == lv[1]), "median_ms"] = 40.0
    df.to_csv(path, index=False)
    time_ms, gt_ms, label = frame_times(path, p, 0.1)
    # between ladder levels 1 and 2: log time linear in log level (100/lv[2] at lv[2], 40 at lv[1])
    mid = math.sqrt(lv[1] * lv[2])
    assert time_ms("LaFR", "temple", mid) == pytest.approx(math.sqrt(40.0 * 100 / lv[2]), rel=1e-12)
    assert time_ms("LaFR", "temple", lv[1]) == pytest.approx(40.0)
    assert time_ms("VaFR", "street_night", 0.5) == pytest.approx(5.0)  # a power law is exact
    assert gt_ms("temple") == 500.0
    w, h = (round(v * 0.1) for v in p.render_size)
    assert label == f"ms per frame at {w}x{h} on the cpu backend (test)"


def test_analyze_with_frame_times_adds_the_time_at_threshold_its_ci_and_speedup(study, tmp_path, capsys,
                                                                                monkeypatch):
    import renderers.cost

    monkeypatch.setattr(renderers.cost, "cost_table", _fake_cost_table)
    p, db, _ = study
    out = tmp_path / "rep"
    csv = _frame_times_csv(p, tmp_path / "t.csv")
    assert main(["analyze", str(db), "--out", str(out), "--cost-scale", "0.1", "--n-boot", "100", "--no-figures",
                 "--frame-times", str(csv)]) == 0
    t = pd.read_csv(out / "tables" / "thresholds_pareto.csv")
    vafr = t["condition"] == "VaFR"
    assert np.allclose(t["time_ms"], np.where(vafr, 10 * t["threshold"], 100 / t["threshold"]), rtol=1e-9)
    lo = np.where(vafr, 10 * t["ci_low"], 100 / t["ci_high"])
    hi = np.where(vafr, 10 * t["ci_high"], 100 / t["ci_low"])
    assert np.allclose(t["time_ms_ci_low"], lo, rtol=1e-9) and np.allclose(t["time_ms_ci_high"], hi, rtol=1e-9)
    assert (t["gt_time_ms"] == 500.0).all() and np.allclose(t["time_speedup"], 500.0 / t["time_ms"])
    report = (out / "report.md").read_text()
    assert "Time at threshold: ms per frame at 96x54 on the cpu backend (test)" in report
    assert "not measured" not in report
    # without the CSV the report says time was not measured and how to measure it
    out2 = tmp_path / "rep2"
    assert main(["analyze", str(db), "--out", str(out2), "--cost-scale", "0.1", "--n-boot", "100",
                 "--no-figures"]) == 0
    report = (out2 / "report.md").read_text()
    assert "Frame time at threshold: not measured" in report and "--ladder-times threshold_foveation" in report
    assert "time_ms" not in pd.read_csv(out2 / "tables" / "thresholds_pareto.csv").columns


def test_analyze_refuses_frame_times_that_do_not_match_the_protocol(study, tmp_path, capsys):
    p, db, _ = study
    lv = p.adaptive.varied["LMFR"].levels[3]
    cases = [
        (_frame_times_csv(p, tmp_path / "a.csv", drop=("LMFR", "street_night", lv)),
         f"no time for LMFR delta={lv:g} on street_night"),
        (_frame_times_csv(p, tmp_path / "b.csv", size=(480, 270)),
         "measured at 480x270, the cost is counted at 96x54"),
    ]
    df = pd.read_csv(_frame_times_csv(p, tmp_path / "c.csv"))
    df[~((df["condition"] == "GT") & (df["scene"] == "temple"))].to_csv(tmp_path / "c.csv", index=False)
    cases.append((tmp_path / "c.csv", "no time for GT on temple"))
    (tmp_path / "d.csv").write_text("protocol,backend\nx,cpu\n")
    cases.append((tmp_path / "d.csv", "lacks the column(s) width, height"))
    for csv, msg in cases:
        out = tmp_path / f"out_{csv.stem}"
        assert main(["analyze", str(db), "--out", str(out), "--cost-scale", "0.1", "--frame-times", str(csv)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and msg in err[0], (msg, err)
        assert not out.exists()
