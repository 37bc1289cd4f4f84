"""Seed 003 tables as records: keys, tables, regions, uniform-count searches, ratios, budget accountings."""

import numpy as np
import pytest
from test_lightcuts_plugin import _diffuse_scene

from renderers import registry
from renderers.lightcuts.tables import lightcut_tables, summary_ratios

TINY = dict(gt_lspp=48, gt_rspp=8, max_lspp=8, max_rspp=4, fovea_deg=10.0)


def _get(rec, table, method, metric, region="all"):
    return next(r["value"] for r in rec if (r["table"], r["method"], r["metric"], r["region"])
                == (table, method, metric, region))


def test_tables_records_and_ratios():
    rec = lightcut_tables(_diffuse_scene(glossy=True), 32, 24, alphas=(0.1, 0.4), **TINY)
    assert rec and all(set(r) == {"table", "scene", "method", "metric", "region", "value"} for r in rec)
    assert {r["table"] for r in rec} == {"1", "2", "3", "4", "fig8", "fig9"}
    assert all(np.isfinite(r["value"]) and r["value"] >= 0 for r in rec)
    t1 = {(r["method"], r["metric"], r["region"]) for r in rec if r["table"] == "1"}
    for m in ("Ours", "SL_e", "SL_as"):
        assert (m, "mse", "all") in t1 and (m, "mse_g", "all") in t1
    t3 = {(r["method"], r["metric"]): r["value"] for r in rec if r["table"] == "3"}
    assert {"Ours", "Ours'", "SL_as", "SL_f", "SL_p"} <= {m for m, k in t3 if k == "ms"}
    assert all(1 <= t3[(m, "lspp")] <= 8 for m in ("SL_e", "SL_f", "SL_p"))
    assert t3[("SL_e", "rspp")] == t3[("SL_e", "lspp")]  # equal time: uniform lspp = rspp
    # sample accounting: uniform SL draws up to lspp per pixel (cut nodes that can contribute) and traverses
    # the tree for every sample
    for m in ("SL_f", "SL_p"):
        assert 0 < t3[(m, "traversals")] == t3[(m, "light_samples")] <= t3[(m, "lspp")] * 32 * 24
    assert t3[("Ours", "traversals")] <= t3[("Ours", "light_samples")] == t3[("Ours'", "light_samples")]
    assert t3[("Ours'", "traversals")] == t3[("Ours'", "light_samples")]
    steps = {(r["method"], r["metric"]) for r in rec if r["table"] == "fig9"}
    assert {("Ours", "ms_fpsm"), ("Ours", "ms_select"), ("SL_f", "ms_select"), ("SL_f", "ms_glossy")} <= steps
    assert ("SL_f", "ms_fpsm") not in steps
    assert len([r for r in rec if r["table"] == "4"]) == 2
    ratios = summary_ratios(rec)
    assert set(ratios) == {"speedup_vs_sl_f", "foveal_mse_sl_e_over_ours", "peripheral_mse_sl_e_over_ours",
                           "multires_speedup", "time_falls_with_alpha"}
    assert ratios["speedup_vs_sl_f"] == pytest.approx(t3[("SL_f", "ms")] / t3[("Ours", "ms")])
    assert ratios["peripheral_mse_sl_e_over_ours"] == pytest.approx(
        _get(rec, "1", "SL_e", "mse", "periphery") / _get(rec, "1", "Ours", "mse", "periphery"))
    assert ratios["multires_speedup"] > 0


def test_equal_samples_budget_gives_sl_e_ours_samples_and_counts_rays():
    sc = _diffuse_scene(glossy=True)
    rec = lightcut_tables(sc, 32, 24, alphas=(), budget="equal-samples", fpsm_reading="retained", **TINY)
    _, st = registry.render(sc, "fsl", {"fpsm_reading": "retained", "max_lspp": 8, "max_rspp": 4}, 32, 24)
    assert st["light_samples"] == _get(rec, "3", "Ours", "light_samples")  # the same (deterministic) frame
    # SL_e's uniform counts are Ours' light samples (low-resolution pass included) per shaded pixel and Ours'
    # glossy rays per glossy pixel, rounded
    assert _get(rec, "3", "SL_e", "lspp") == max(1, min(8, round(st["light_samples"] / st["shading_points"])))
    assert _get(rec, "3", "SL_e", "rspp") == round(st["glossy_rays"] / st["glossy_mask"].sum())
    assert st["light_samples"] > st["spp"].sum()  # the low-resolution pass is counted on top of Table 2's spp
    r = summary_ratios(rec, "equal-samples")
    rays = {m: _get(rec, "3", m, "light_samples") + _get(rec, "3", m, "glossy_rays") for m in ("SL_f", "Ours")}
    assert r["speedup_vs_sl_f"] == pytest.approx(rays["SL_f"] / rays["Ours"])
    assert r["multires_speedup"] == pytest.approx(_get(rec, "3", "Ours'", "traversals")
                                                  / _get(rec, "3", "Ours", "traversals"))
    assert r["multires_speedup"] >= 1 and r["time_falls_with_alpha"] is False  # no alpha sweep asked for


@pytest.mark.parametrize("kw, match", [({"budget": "equal-money"}, "budget='equal-money' is invalid"),
                                       ({"fpsm_reading": "literal"}, "fpsm_reading='literal' is invalid"),
                                       ({"repeats": 0}, "repeats=0 is out of range")])
def test_bad_options_are_one_line_errors(kw, match):
    with pytest.raises(ValueError, match=match) as err:
        lightcut_tables(_diffuse_scene(), 16, 16, **kw)
    assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match="budget"):
        summary_ratios([], "equal-money")
