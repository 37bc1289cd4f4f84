"""Benchmark of the foveation core (issue: full-screen forward at 8K, inverse over VaFR's shaded pixels).

Run:  .venv/bin/python benchmarks/bench_foveation.py [--repeats 5] [--write docs/benchmarks.md]

Each measurement runs in a fresh child process (``benchmarks/harness.py``) so that peak memory (its maximum resident
set) belongs to that measurement alone; times are medians over the repeats inside that process, after one warm-up
call (numba compiles on first use and caches to disk). The scaling from 2K to 8K is reported as a ratio measured in
the same run.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.harness import machine_line, print_row, replace_section, run_child, timings  # noqa: E402


def _measure(kind: str, method: str, W: int, H: int, repeats: int) -> dict:
    from renderers.foveation import make_mapping

    m = make_mapping(method, W, H, 100.0)
    if kind == "forward_screen":
        fn = m.forward_screen
        n = W * H
    elif kind == "inverse_shaded":
        u, v = m.shaded_coordinates()
        n = u.size

        def fn():
            return m.inverse(u, v)
    else:
        raise SystemExit(f"unknown kind {kind}")
    times = timings(fn, repeats)  # after a warm-up call (compilation, page faults of the first allocation)
    return {"kind": kind, "method": method, "width": W, "height": H, "elements": n,
            "median_s": statistics.median(times), "min_s": min(times), "repeats": repeats}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--write", metavar="MD", help="replace the foveation section of this Markdown file")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        print_row(_measure(*json.loads(a.child)))
        return 0
    jobs = [("forward_screen", m, 7680, 4320, a.repeats) for m in ("vafr", "lmfr", "lafr")]
    jobs += [("forward_screen", "vafr", 2560, 1440, a.repeats),
             ("inverse_shaded", "vafr", 7680, 4320, a.repeats)]
    results = []
    for job in jobs:
        r = run_child([os.path.abspath(__file__), "--child", json.dumps(job)], " ".join(map(str, job[:4])))
        results.append(r)
        print(f"{r['kind']:<24} {r['method']:<5} {r['width']}x{r['height']}: median {r['median_s']:.3f} s "
              f"(min {r['min_s']:.3f}), peak {r['peak_mb']:.0f} MB", flush=True)
    if a.write:
        write_markdown(a.write, results)
    return 0


def write_markdown(path: str, results: list[dict]) -> None:
    small = next(r for r in results if r["kind"] == "forward_screen" and r["width"] == 2560)
    lines = ["<!-- foveation:start -->", "## Foveation mappings (`benchmarks/bench_foveation.py`)", "",
             f"{machine_line()} Median of the repeats after a warm-up call; peak memory is the "
             "process's maximum resident set, one fresh process per row; load average "
             f"{max(r['load'] for r in results):.1f} at most.", "",
             "| operation | method | resolution | elements | median (s) | peak memory (MB) | target |",
             "|---|---|---|---:|---:|---:|---|"]
    for r in results:
        target = ""
        if r["kind"] == "forward_screen" and r["width"] == 7680:
            target = "≤ 2 s, ≤ 2048 MB"
        if r["kind"] == "inverse_shaded":
            target = "≤ 0.2 s"
        lines.append(f"| {r['kind']} | {r['method']} | {r['width']}×{r['height']} | {r['elements']:,} | "
                     f"{r['median_s']:.3f} | {r['peak_mb']:.0f} | {target} |")
    fw = next(r for r in results if r["kind"] == "forward_screen" and r["method"] == "vafr" and r["width"] == 7680)
    lines += ["", f"Same-run ratio: the VaFR forward map takes {fw['median_s'] / small['median_s']:.1f}× longer at 8K "
              f"than at 2K for {fw['elements'] / small['elements']:.1f}× the pixels (linear in the pixel count).",
              "", "Reproduce: `.venv/bin/python benchmarks/bench_foveation.py --write docs/benchmarks.md`",
              "<!-- foveation:end -->"]
    replace_section(path, "foveation", lines[1:-1])


if __name__ == "__main__":
    raise SystemExit(main())
