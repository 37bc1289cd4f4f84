"""Benchmark of how the GPU backend's workgroups are dealt to llvmpipe's threads: blocks in order (``STRIPES`` = 1,
each thread one contiguous part of the image) against interleaved stripes (the default, ``renderers/gpu/context.py``
``STRIPES``), in the same process, frames alternating, medians of ``--repeats``; with the cores busy (process CPU
time / wall time) for each. The frames are bit for bit the same either way
(``tests/test_gpu_agreement.py::test_dealing_workgroups_in_stripes_changes_no_pixel``); only the time differs.

On a GPU the order of workgroups costs nothing and the two columns should agree; on llvmpipe the in-order dealing
leaves a core idle wherever the work is uneven over the image. Writes section ``gpu-balance`` of
``docs/benchmarks.md`` and ``docs/bench_gpu_balance.csv``.

    python benchmarks/bench_gpu_balance.py                    # sl_gt (96 + 64), fsl, sl_e on the four scenes
    python benchmarks/bench_gpu_balance.py --size 640x360 --repeats 5 --scenes yard
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from benchmarks._report import command_line, machine_line, replace_section  # noqa: E402
from benchmarks.bench_gpu import LLVMPIPE_NOTE, _gpu_device_line, run_child, write_csv  # noqa: E402

SCENES = ("cornell_many", "study", "yard", "sponza_vpl")
#: Methods and the counts they are measured with (sl_gt with fewer samples than the seed's: 2 passes, 8 dispatches).
METHODS = {"sl_gt": {"lspp": 96, "rspp": 64}, "fsl": {}, "sl_e": {"lspp": 8, "rspp": 8}}


def _cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def measure_one(scene: str, method: str, size: str, repeats: int) -> dict:
    """In this process: an untimed warm-up frame, then ``repeats`` rounds of one frame in order and one
    interleaved; medians of wall time and of the cores kept busy."""
    import renderers.gpu.context as C
    from renderers import registry

    interleaved = C.STRIPES
    W, H = (int(v) for v in size.split("x"))
    params = METHODS[method]
    registry.render(scene, method, params, 64, 48, backend="gpu")
    times: dict[int, list[tuple[float, float]]] = {1: [], interleaved: []}
    for _ in range(repeats):
        for stripes in times:
            C.STRIPES = stripes
            t0, c0 = time.perf_counter(), _cpu_seconds()
            registry.render(scene, method, params, W, H, backend="gpu")
            wall = time.perf_counter() - t0
            times[stripes].append((wall, (_cpu_seconds() - c0) / wall))
    C.STRIPES = interleaved
    med = {s: (statistics.median(w for w, _ in v), statistics.median(b for _, b in v)) for s, v in times.items()}
    return {"scene": scene, "method": method, "params": json.dumps(params), "size": size, "repeats": repeats,
            "in_order_ms": 1e3 * med[1][0], "interleaved_ms": 1e3 * med[interleaved][0],
            "speedup": med[1][0] / med[interleaved][0], "in_order_cores": med[1][1],
            "interleaved_cores": med[interleaved][1], "stripes": interleaved}


def section(rows, elapsed: float, command: str) -> list[str]:
    lines = ["## GPU backend: workgroups dealt in order against interleaved (`benchmarks/bench_gpu_balance.py`)", "",
             machine_line(), _gpu_device_line(),
             f"Command: `{command}` ({elapsed / 60:.1f} min). Each row: one process, an untimed 64x48 frame, then "
             f"{rows[0]['repeats'] if rows else 0} rounds of one frame with the workgroups dealt in order (each of "
             "llvmpipe's threads one contiguous part of the image) and one interleaved in "
             f"{rows[0]['stripes'] if rows else '-'} stripes (the default); medians. `cores`: process CPU time / "
             "wall time. The frames are bit for bit the same either way.", "", LLVMPIPE_NOTE, "",
             "| scene | method | size | in order ms | interleaved ms | in order / interleaved | cores in order | "
             "cores interleaved | load |", "|---|---|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['method']} {r['params']} | {r['size']} | {r['in_order_ms']:,.0f} | "
                     f"{r['interleaved_ms']:,.0f} | {r['speedup']:.2f} | {r['in_order_cores']:.2f} | "
                     f"{r['interleaved_cores']:.2f} | {r['load']:.1f} |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(SCENES), help="comma-separated (default: the four many-light scenes)")
    ap.add_argument("--methods", default=",".join(METHODS), help=f"comma-separated of {', '.join(METHODS)}")
    ap.add_argument("--size", default="320x180", help="frame size WxH (default 320x180)")
    ap.add_argument("--repeats", type=int, default=3, help="rounds per configuration (default 3)")
    ap.add_argument("--one", nargs=2, metavar=("SCENE", "METHOD"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    unknown = [m for m in args.methods.split(",") if m not in METHODS]
    if unknown or args.repeats < 1:
        print(f"bench_gpu_balance: --methods takes {', '.join(METHODS)} and --repeats at least 1", file=sys.stderr)
        return 2
    if args.one:
        print(json.dumps(measure_one(*args.one, args.size, args.repeats)))
        return 0
    t0 = time.perf_counter()
    command = command_line("benchmarks/bench_gpu_balance.py", argv if argv is not None else sys.argv[1:])
    rows = []
    for scene in args.scenes.split(","):
        for method in args.methods.split(","):
            r = run_child(os.path.abspath(__file__), ["--one", scene, method, "--size", args.size,
                                                      "--repeats", str(args.repeats)], f"{scene} {method}")
            rows.append(r)
            print(f"{scene} {method}: in order {r['in_order_ms']:,.0f} ms, interleaved {r['interleaved_ms']:,.0f} ms "
                  f"({r['speedup']:.2f}x; cores {r['in_order_cores']:.2f} -> {r['interleaved_cores']:.2f})",
                  flush=True)
            write_csv(rows, "bench_gpu_balance.csv")
            replace_section(os.path.join(ROOT, "docs", "benchmarks.md"), "gpu-balance",
                            section(rows, time.perf_counter() - t0, command))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
