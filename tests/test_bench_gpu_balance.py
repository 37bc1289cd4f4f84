"""benchmarks/bench_gpu_balance.py: the in-order / interleaved A/B of the GPU workgroups (llvmpipe in CI)."""

from __future__ import annotations

import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from benchmarks import bench_gpu_balance as B  # noqa: E402


def test_one_configuration_times_both_dealings_and_restores_the_default():
    import renderers.gpu.context as C

    default = C.STRIPES
    row = B.measure_one("cornell_many", "sl_e", "48x27", 2)
    assert C.STRIPES == default and row["stripes"] == default
    assert row["in_order_ms"] > 0 and row["interleaved_ms"] > 0
    assert abs(row["speedup"] - row["in_order_ms"] / row["interleaved_ms"]) < 1e-9
    assert 0 < row["in_order_cores"] <= os.cpu_count() + 0.5 and 0 < row["interleaved_cores"] <= os.cpu_count() + 0.5
    text = "\n".join(B.section([{**row, "load": 1.0}], 60.0, "python benchmarks/bench_gpu_balance.py"))
    assert f"| cornell_many | sl_e {row['params']} | 48x27 |" in text and f"| {row['speedup']:.2f} |" in text


def test_unknown_method_is_one_line_and_exit_2(capsys):
    assert B.main(["--methods", "sl_gt,nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--methods" in err[0]
