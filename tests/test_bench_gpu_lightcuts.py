"""sl_gt's frame predicted from a few of its passes (benchmarks/bench_gpu_lightcuts.py ``--gt-model``): the pass
and dispatch counts follow the renderer, the prediction inverts a cost linear in both, and the check against whole
frames reads only whole sl_gt frames of the same sample counts."""

import csv
import json

from hypothesis import given, strategies as st

from benchmarks import bench_gpu_lightcuts as B


def _row(total, cuts, select, shade, glossy, **extra):
    return {"backend": "gpu", "method": "sl_gt", "scene": "cornell_many", "size": "1280x720", "total_ms": total,
            "cuts_ms": cuts, "select_ms": select, "shade_ms": shade, "glossy_ms": glossy, "light_samples": 1000, "peak_mb": 600.0, "load": 1.2, **extra}


def test_the_seed_counts_are_43_light_passes_and_256_glossy_dispatches():
    # sl_gt: ceil(2048 / max_lspp 48) passes of 48 nodes; the glossy pass in dispatches of 8 ray slots
    assert B.gt_units() == (48, 8)
    assert B.gt_passes(2048, 2048) == (43, 256)
    assert B.gt_model_params(2, 3) == {"lspp": 96, "rspp": 24}
    assert B.gt_passes(**B.gt_model_params(2, 3)) == (2, 3)


def test_the_light_steps_scale_with_passes_and_the_glossy_step_with_dispatches():
    row = _row(1000.0, 10.0, 20.0, 30.0, 100.0)  # light passes 50, glossy 100, the rest 850 (cuts: once)
    assert B.gt_frame_ms(row, 2, 1, 43, 32) == 850.0 + 50.0 * 43 / 2 + 100.0 * 32
    full = B.gt_model_row(row, 2, 1, 2048)
    assert (full["full_passes"], full["full_chunks"]) == (43, 256)
    assert full["predicted_light_samples"] == 1000 * 43 // 2


@given(fixed=st.floats(0, 1e4), per_pass=st.floats(0, 1e5), per_chunk=st.floats(0, 1e5),
       passes=st.integers(1, 43), chunks=st.integers(1, 32), split=st.floats(0, 1))
def test_a_cost_linear_in_passes_and_dispatches_is_predicted_exactly(fixed, per_pass, per_chunk, passes, chunks,
                                                                     split):
    light = per_pass * passes
    row = _row(fixed + light + per_chunk * chunks, fixed / 2, split * light, (1 - split) * light,
               per_chunk * chunks)  # the cuts (refined once) are part of the fixed cost
    want = fixed + 43 * per_pass + 32 * per_chunk
    assert abs(B.gt_frame_ms(row, passes, chunks, 43, 32) - want) <= 1e-9 * max(1.0, want)


def _write(path, rows):
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=sorted({k for r in rows for k in r}))
        w.writeheader()
        w.writerows(rows)


def test_whole_frames_are_only_whole_gpu_sl_gt_frames_of_the_same_counts(tmp_path):
    seed = json.dumps({"lspp": 2048, "rspp": 2048})
    _write(tmp_path / "bench_gpu_lightcuts_gt.csv", [
        {"backend": "gpu", "scene": "cornell_many", "size": "1280x720", "method": "sl_gt", "params": seed,
         "total_ms": "1887281"},
        {"backend": "cpu", "scene": "study", "size": "1280x720", "method": "sl_gt", "params": seed,
         "total_ms": "1"},
        {"backend": "gpu", "scene": "yard", "size": "1280x720", "method": "sl_gt",
         "params": json.dumps({"lspp": 256, "rspp": 256}), "total_ms": "2"},
        {"backend": "gpu", "scene": "sponza_vpl", "size": "1280x720", "method": "fsl", "params": "{}",
         "total_ms": "3"}])
    _write(tmp_path / "bench_gpu_lightcuts_gt_model.csv", [  # predictions are not whole frames
        {"backend": "gpu", "scene": "study", "size": "1280x720", "method": "sl_gt",
         "params": json.dumps({"lspp": 96, "rspp": 128}), "total_ms": "4", "predicted_ms": "5"}])
    whole = B.whole_gt_frames(2048, str(tmp_path))
    assert list(whole) == [("cornell_many", "1280x720")]
    assert whole[("cornell_many", "1280x720")]["file"] == "bench_gpu_lightcuts_gt.csv"


def test_the_section_checks_each_prediction_against_its_whole_frame(monkeypatch):
    monkeypatch.setattr(B, "gpu_device_line", lambda: "GPU backend: test.")
    rows = [B.gt_model_row(_row(90_000.0, 2_000.0, 7_000.0, 9_000.0, 70_000.0), 2, 2, 2048),
            {**B.gt_model_row(_row(90_000.0, 2_000.0, 7_000.0, 9_000.0, 70_000.0), 2, 2, 2048), "scene": "yard"}]
    plan = [("gpu", sc, "sl_gt", "1280x720", 1) for sc in ("cornell_many", "yard", "study")]
    whole = {("cornell_many", "1280x720"): {"total_ms": "9000000", "file": "bench_gpu_lightcuts_gt.csv"}}
    text = "\n".join(B.model_section(rows, plan, 600.0, 2048, "python b.py", (2, 2), whole))
    predicted = rows[0]["predicted_ms"]  # 4,000 + 16,000 x 43 / 2 + 70,000 x 256 / 2 = 9,308,000
    assert predicted == 9_308_000.0
    assert "| cornell_many | 1280x720 | 90,000 | 16,000 | 70,000 | 9,308,000 | 155.1 |" in text
    assert "| 9,000,000 | 1.034 |" in text
    assert "| yard | 1280x720 |" in text and "not measured | - |" in text
    assert "Not measured in this run (stopped or failed before they ran): study 1280x720." in text
    assert "`benchmarks/results/bench_gpu_lightcuts_gt.csv`" in text  # a raw result: not in docs/
