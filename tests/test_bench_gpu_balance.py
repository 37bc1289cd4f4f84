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
    assert C.STRIPES == default and row["stripes"] == default and row["ab"] == "stripes"
    assert row["old_ms"] > 0 and row["default_ms"] > 0
    assert abs(row["speedup"] - row["old_ms"] / row["default_ms"]) < 1e-9
    assert 0 < row["old_cores"] <= os.cpu_count() + 0.5 and 0 < row["default_cores"] <= os.cpu_count() + 0.5
    text = "\n".join(B.section([{**row, "load": 1.0}], 60.0, "python benchmarks/bench_gpu_balance.py"))
    assert f"| cornell_many | sl_e {row['params']} | 48x27 |" in text and f"| {row['speedup']:.2f} |" in text
    assert "in order ms | interleaved ms" in text


def test_the_grid_ab_uses_full_rows_then_restores_the_fitted_grid(monkeypatch):
    import renderers.gpu.context as C

    fitted, seen = C.grid_shape, []
    dev = C.get_device()
    monkeypatch.setattr(dev, "max_groups", 40)  # a 48x27 frame's 21 blocks -> 64 padded: two rows of the grid

    class Spy:  # records each dispatch's grid, then dispatches it
        def __init__(self, prog):
            self.prog = prog

        def __getattr__(self, name):
            return getattr(self.prog, name)

        def __contains__(self, name):
            return name in self.prog

        def __setitem__(self, name, value):
            self.prog[name] = value

        def __getitem__(self, name):
            return self.prog[name]

        def run(self, gx, gy, gz):
            seen.append((C.grid_shape is fitted, gx, gy))
            self.prog.run(gx, gy, gz)

    program = dev.program
    monkeypatch.setattr(dev, "program", lambda *a, **kw: Spy(program(*a, **kw)))
    row = B.measure_one("cornell_many", "sl_e", "48x27", 1, ab="grid")
    assert C.grid_shape is fitted and row["ab"] == "grid" and row["old_ms"] > 0 and row["default_ms"] > 0
    assert {(gx, gy) for is_fitted, gx, gy in seen if not is_fitted and gy > 1} == {(40, 2)}  # full rows: 80
    assert {(gx, gy) for is_fitted, gx, gy in seen if is_fitted and gy > 1} == {(32, 2)}  # fitted: 64
    text = "\n".join(B.section([{**row, "load": 1.0}], 60.0, "python benchmarks/bench_gpu_balance.py --ab grid",
                               "grid"))
    assert "full rows ms | fitted ms" in text


def test_unknown_method_or_ab_is_one_line_and_exit_2(capsys):
    for argv in (["--methods", "sl_gt,nope"], ["--ab", "nope"]):
        assert B.main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--methods" in err[0] and "--ab" in err[0]
