"""Benchmark of how the GPU backend's workgroups reach llvmpipe's threads, two A/Bs (``--ab``), in the same process,
frames alternating, medians of ``--repeats``, with the cores busy (process CPU time / wall time) for each:

* ``stripes``: blocks in order (``STRIPES`` = 1, each thread one contiguous part of the image) against interleaved
  stripes (the default, ``renderers/gpu/context.py`` ``STRIPES``). Section ``gpu-balance``.
* ``grid``: a dispatch of more than 65,535 workgroups laid out in full rows of 65,535 (the grid before 2c6f99b:
  at 2160 x 2160 the second half of the grid, one thread's share, was nearly all idle) against the grid of
  :func:`renderers.gpu.context.grid_shape` (the default). Section ``gpu-balance-grid``; needs a size above
  2048 x 2048 to differ.

The frames are bit for bit the same either way
(``tests/test_gpu_agreement.py::test_dealing_workgroups_in_stripes_changes_no_pixel``); only the time differs.
On a GPU neither should cost anything; on llvmpipe the first of each pair leaves a core idle wherever the work is
uneven over the grid. Writes ``docs/benchmarks.md`` and the raw rows to
``benchmarks/results/bench_gpu_balance[_grid].csv`` (``benchmarks/harness.py``).

    python benchmarks/bench_gpu_balance.py                    # sl_gt (96 + 64), fsl, sl_e on the four scenes
    python benchmarks/bench_gpu_balance.py --size 640x360 --repeats 5 --scenes yard
    python benchmarks/bench_gpu_balance.py --ab grid --size 2160x2160 --methods sl_e --repeats 2
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.harness import (  # noqa: E402
    DOC, LLVMPIPE_NOTE, command_line, gpu_device_line, machine_line, print_row, replace_section, run_child,
    write_csv)

SCENES = ("cornell_many", "study", "yard", "sponza_vpl")
#: Methods and the counts they are measured with (sl_gt with fewer samples than the seed's: 2 passes, 8 dispatches).
METHODS = {"sl_gt": {"lspp": 96, "rspp": 64}, "fsl": {}, "sl_e": {"lspp": 8, "rspp": 8}}


def _cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _full_rows(groups: int, max_groups: int) -> tuple[int, int]:
    """The grid before 2c6f99b: rows of ``max_groups`` workgroups, the last one mostly idle."""
    gx = min(groups, max_groups)
    return gx, -(-groups // gx)


#: Each A/B and its labels, the old way first, the default second (:func:`_switch` sets either).
AB = {"stripes": ("in order", "interleaved"), "grid": ("full rows", "fitted")}


def _switch(ab: str, old: bool, defaults: dict) -> None:
    import renderers.gpu.context as C

    if ab == "stripes":
        C.STRIPES = 1 if old else defaults["stripes"]
    else:
        C.grid_shape = _full_rows if old else defaults["grid"]


def measure_one(scene: str, method: str, size: str, repeats: int, ab: str = "stripes") -> dict:
    """In this process: an untimed warm-up frame, then ``repeats`` rounds of one frame the old way and one the
    default way (:data:`AB`); medians of wall time and of the cores kept busy. The defaults are restored."""
    import renderers.gpu.context as C
    from renderers import registry

    defaults = {"stripes": C.STRIPES, "grid": C.grid_shape}
    W, H = (int(v) for v in size.split("x"))
    params = METHODS[method]
    registry.render(scene, method, params, 64, 48, backend="gpu")
    times: dict[bool, list[tuple[float, float]]] = {True: [], False: []}
    try:
        for _ in range(repeats):
            for old in times:
                _switch(ab, old, defaults)
                t0, c0 = time.perf_counter(), _cpu_seconds()
                registry.render(scene, method, params, W, H, backend="gpu")
                wall = time.perf_counter() - t0
                times[old].append((wall, (_cpu_seconds() - c0) / wall))
    finally:
        _switch(ab, False, defaults)
    med = {k: (statistics.median(w for w, _ in v), statistics.median(b for _, b in v)) for k, v in times.items()}
    return {"ab": ab, "scene": scene, "method": method, "params": json.dumps(params), "size": size,
            "repeats": repeats, "old_ms": 1e3 * med[True][0], "default_ms": 1e3 * med[False][0],
            "speedup": med[True][0] / med[False][0], "old_cores": med[True][1], "default_cores": med[False][1],
            "stripes": C.STRIPES}


def section(rows, elapsed: float, command: str, ab: str = "stripes") -> list[str]:
    old, new = AB[ab]
    n = rows[0]["repeats"] if rows else 0
    how = (f"dealt in order (each of llvmpipe's threads one contiguous part of the image) and one interleaved in "
           f"{rows[0]['stripes'] if rows else '-'} stripes (the default)" if ab == "stripes" else
           "laid out in full rows of 65,535 workgroups (before 2c6f99b; the last row mostly idle, one thread's "
           "share) and one in the fewest rows that hold the work (`grid_shape`, the default)")
    lines = [f"## GPU backend: workgroups {old} against {new} (`benchmarks/bench_gpu_balance.py --ab {ab}`)", "",
             machine_line(), gpu_device_line(),
             f"Command: `{command}` ({elapsed / 60:.1f} min). Each row: one process, an untimed 64x48 frame, then "
             f"{n} rounds of one frame with the workgroups {how}; medians. `cores`: process CPU time / "
             "wall time. The frames are bit for bit the same either way.", "", LLVMPIPE_NOTE, "",
             f"| scene | method | size | {old} ms | {new} ms | {old} / {new} | cores {old} | "
             f"cores {new} | load |", "|---|---|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['method']} {r['params']} | {r['size']} | {r['old_ms']:,.0f} | "
                     f"{r['default_ms']:,.0f} | {r['speedup']:.2f} | {r['old_cores']:.2f} | "
                     f"{r['default_cores']:.2f} | {r['load']:.1f} |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(SCENES), help="comma-separated (default: the four many-light scenes)")
    ap.add_argument("--methods", default=",".join(METHODS), help=f"comma-separated of {', '.join(METHODS)}")
    ap.add_argument("--size", default="320x180", help="frame size WxH (default 320x180)")
    ap.add_argument("--repeats", type=int, default=3, help="rounds per configuration (default 3)")
    ap.add_argument("--ab", default="stripes", help=f"which A/B: {', '.join(AB)} (default stripes)")
    ap.add_argument("--one", nargs=2, metavar=("SCENE", "METHOD"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    unknown = [m for m in args.methods.split(",") if m not in METHODS]
    if unknown or args.repeats < 1 or args.ab not in AB:
        print(f"bench_gpu_balance: --methods takes {', '.join(METHODS)}, --ab {' or '.join(AB)} and --repeats at "
              "least 1", file=sys.stderr)
        return 2
    if args.one:
        print_row(measure_one(*args.one, args.size, args.repeats, args.ab))
        return 0
    t0 = time.perf_counter()
    command = command_line("benchmarks/bench_gpu_balance.py", argv if argv is not None else sys.argv[1:])
    rows, old, new = [], *AB[args.ab]
    name = "gpu-balance" if args.ab == "stripes" else f"gpu-balance-{args.ab}"
    for scene in args.scenes.split(","):
        for method in args.methods.split(","):
            r = run_child([os.path.abspath(__file__), "--one", scene, method, "--size", args.size,
                           "--repeats", str(args.repeats), "--ab", args.ab], f"{scene} {method}")
            rows.append(r)
            print(f"{scene} {method}: {old} {r['old_ms']:,.0f} ms, {new} {r['default_ms']:,.0f} ms "
                  f"({r['speedup']:.2f}x; cores {r['old_cores']:.2f} -> {r['default_cores']:.2f})", flush=True)
            write_csv(rows, f"bench_{name.replace('-', '_')}.csv")
            replace_section(DOC, name, section(rows, time.perf_counter() - t0, command, args.ab))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
