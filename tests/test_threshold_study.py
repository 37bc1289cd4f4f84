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
