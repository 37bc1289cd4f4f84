"""Seed 003 tables as records: keys, tables, regions, uniform-count searches, ratios."""

import numpy as np
from test_lightcuts_plugin import _diffuse_scene

from renderers.lightcuts.tables import lightcut_tables, summary_ratios


def test_tables_records_and_ratios():
    rec = lightcut_tables(_diffuse_scene(glossy=True), 32, 24, gt_lspp=48, gt_rspp=8, max_lspp=8, max_rspp=4,
                          alphas=(0.1, 0.4), fovea_deg=10.0)
    assert rec and all(set(r) == {"table", "scene", "method", "metric", "region", "value"} for r in rec)
    assert {r["table"] for r in rec} == {"1", "2", "3", "4", "fig8"}
    assert all(np.isfinite(r["value"]) and r["value"] >= 0 for r in rec)
    t1 = {(r["method"], r["metric"], r["region"]) for r in rec if r["table"] == "1"}
    for m in ("Ours", "SL_e", "SL_as"):
        assert (m, "mse", "all") in t1 and (m, "mse_g", "all") in t1
    t3 = {(r["method"], r["metric"]): r["value"] for r in rec if r["table"] == "3"}
    assert {"Ours", "Ours'", "SL_as", "SL_f", "SL_p"} <= {m for m, k in t3 if k == "ms"}
    assert all(1 <= t3[(m, "lspp")] <= 8 for m in ("SL_e", "SL_f", "SL_p"))
    assert len([r for r in rec if r["table"] == "4"]) == 2
    # SL_f is the smallest uniform count whose foveal MSE does not exceed Ours' (or the maximum)
    ours_f = next(r["value"] for r in rec if r["table"] == "1" and r["method"] == "Ours"
                  and r["metric"] == "mse" and r["region"] == "fovea")
    assert ours_f >= 0
    ratios = summary_ratios(rec)
    assert set(ratios) == {"speedup_vs_sl_f", "foveal_mse_sl_e_over_ours", "multires_speedup",
                           "time_falls_with_alpha"}
    assert ratios["speedup_vs_sl_f"] > 0 and ratios["multires_speedup"] > 0
