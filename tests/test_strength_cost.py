"""The device-independent cost table of a foveation ladder (issue 28 item 5's cost axis): renderers/cost.py."""

from __future__ import annotations

import pandas as pd
import pytest

from data_schema.errors import UserError
from renderers import cost
from renderers.registry import render

W, H = 48, 27


def test_cost_table_counts_are_the_renders_stats_weakest_first():
    table = cost.cost_table("cornell", "vafr", [0.05, 0.1], W, H)
    assert list(table["level"]) == [0.1, 0.05] and set(table["reference"]) == {"gt"}
    assert list(table["lp_pixels"]) == [21_148, 6_114]  # the seed's count of each scale, on any display
    for row in table.itertuples():
        _, stats = render("cornell", "vafr", {"acuity_scale": row.level}, W, H)
        assert all(getattr(row, k) == stats[k] for k in ("shading_points", "rays_primary", "rays_shadow"))
        assert row.light_samples == 0 and row.work == row.rays_primary
    _, gt = render("cornell", "gt", {}, W, H)
    assert set(table["gt_rays_primary"]) == {W * H} and set(table["gt_shading_points"]) == {gt["shading_points"]}
    assert table["work_ratio"].tolist() == pytest.approx([r / (W * H) for r in table["rays_primary"]])


#: A light ground truth (96 samples, not 2048): the table's plumbing, not the reference's quality, is tested.
GT96 = {"lspp": 96, "rspp": 96}


def test_cost_table_is_deterministic_and_reads_the_stimulus_cache(tmp_path):
    first = cost.cost_table("cornell", "sl", [2, 8], 24, 16, reference_params=GT96, cache_dir=tmp_path)
    assert list(first["level"]) == [8, 2] and set(first["reference"]) == {"sl_gt"}
    assert first["light_samples"].iloc[0] > first["light_samples"].iloc[1] > 0
    assert first["work"].tolist() == first["light_samples"].tolist()
    entries = sorted(tmp_path.glob("??/*.json"))
    assert len(entries) == 3  # two levels and the ground truth, as `prepare` stores stimuli
    cost._MEMO.clear()
    again = cost.cost_table("cornell", "sl", [8, 2], 24, 16, reference_params=GT96, cache_dir=tmp_path)
    pd.testing.assert_frame_equal(first, again)
    assert sorted(tmp_path.glob("??/*.json")) == entries
    cost._MEMO.clear()
    pd.testing.assert_frame_equal(first, cost.cost_table("cornell", "sl", [2, 8], 24, 16,
                                                       reference_params=GT96))  # rendered again, same counts


def test_cost_table_refusals_are_one_line():
    with pytest.raises(UserError, match="renderer 'gt' has no foveation strength"):
        cost.cost_table("cornell", "gt", [1], W, H)
    with pytest.raises(UserError, match=r"lafr.delta=0.5 is out of range: allowed \(1, 16\]"):
        cost.cost_table("cornell", "lafr", [2.0, 0.5], W, H)
    with pytest.raises(UserError, match="levels of lmfr.delta are empty"):
        cost.cost_table("cornell", "lmfr", [], W, H)


def test_ground_truth_of():
    assert [cost.ground_truth_of(n) for n in ("vafr", "lafr", "gt", "fsl", "sl_e", "sl_as")] == \
        ["gt", "gt", "gt", "sl_gt", "sl_gt", "sl_gt"]
