"""Speed and memory of the whole study analysis (`studyapp analyze`) against the log size.

Run:  .venv/bin/python benchmarks/bench_analysis.py [--sizes 4500,100000,1000000,10000000] [--repeats 5]
                                                   [--write docs/benchmarks.md]

Each size is a CSV log written beforehand (not timed): the seed 001 2AFC log (4,500 trials) and synthetic
2AFC logs of 600 trials per participant. Every measurement runs in a fresh child process
(``benchmarks/harness.py``), which reads the CSV,
runs the plan (votes, omnibus, pairwise Kruskal-Wallis + Holm overall and per scene, Dunn, summary vs
reference, Thurstone and Bradley-Terry with 1,000 bootstrap replicates each) and writes every table and
figure; peak memory is that process's maximum resident set. Medians over the repeats (one run at 10^7).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.harness import machine_line, replace_section, run_child  # noqa: E402

CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
from analysis.io import read_log
from analysis.plan import AnalysisPlan
from analysis.report import write_report
from analysis.study import analyze_log
t1 = time.perf_counter()
df = read_log(sys.argv[1])
t2 = time.perf_counter()
res = analyze_log(df, AnalysisPlan(n_boot=1000))
t3 = time.perf_counter()
write_report(res, sys.argv[2])
t4 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "read_s": t2 - t1, "analyze_s": t3 - t2, "write_s": t4 - t3,
                  "total_s": t4 - t1}))
"""


def make_log(n: int, path: str) -> None:
    import pyarrow as pa
    from pyarrow import csv as pacsv

    from analysis.synthetic import seed001_2afc_log, synthetic_2afc_log

    df = seed001_2afc_log(seed=0) if n == 4500 else synthetic_2afc_log(n, seed=0)
    pacsv.write_csv(pa.Table.from_pandas(df, preserve_index=False), path)


def measure(path: str, out: str) -> dict:
    """One analysis of the log ``path`` in a child process: its stage times, peak memory and the load."""
    return run_child(["-c", CHILD, path, out], f"analysis of {os.path.basename(path)}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="4500,100000,1000000,10000000")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--write", metavar="MD", help="replace the analysis section of this Markdown file")
    a = ap.parse_args()
    sizes = [int(s) for s in a.sizes.split(",")]
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            path = os.path.join(tmp, f"log_{n}.csv")
            make_log(n, path)
            reps = 1 if n >= 5_000_000 else a.repeats
            runs = [measure(path, os.path.join(tmp, f"out_{n}_{i}")) for i in range(reps)]
            row = {"trials": n, "repeats": reps, "csv_mb": os.path.getsize(path) / 1e6}
            for k in runs[0]:
                row[k] = statistics.median(r[k] for r in runs)
            row["load"] = max(r["load"] for r in runs)
            results.append(row)
            print(json.dumps(row), flush=True)
            os.remove(path)
    if a.write:
        write_markdown(a.write, results)
    return 0


def write_markdown(path: str, results: list[dict]) -> None:
    lines = ["## Study analysis (`benchmarks/bench_analysis.py`)", "",
             machine_line() + " Each row: a fresh process reads the CSV log, runs the whole plan (votes, "
             "omnibus and pairwise Kruskal-Wallis + Holm overall and per scene, Dunn, summary against the "
             "reference, Thurstone and Bradley-Terry with 1,000 bootstrap replicates each) and writes every "
             "table and figure. Median of the repeats; peak memory = the process's maximum resident set; load: "
             "the 5-minute load average after the runs (at most).", "",
             "| trials | CSV (MB) | read (s) | analyse (s) | write tables+figures (s) | total (s) | "
             "s per 10^6 trials | peak memory (MB) | repeats | load |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in results:
        lines.append(f"| {r['trials']:,} | {r['csv_mb']:.1f} | {r['read_s']:.3f} | {r['analyze_s']:.3f} | "
                     f"{r['write_s']:.3f} | {r['total_s']:.3f} | {r['total_s'] / r['trials'] * 1e6:.2f} | "
                     f"{r['peak_mb']:.0f} | {r['repeats']} | {r['load']:.1f} |")
    small = next((r for r in results if r["trials"] == 4500), None)
    big = next((r for r in results if r["trials"] >= 10_000_000), None)
    lines.append("")
    if small:
        lines.append(f"- 4,500-trial seed 001 log: read + analyse {small['read_s'] + small['analyze_s']:.3f} s "
                     f"(target ≤ 0.5 s); with every table and figure written {small['total_s']:.3f} s; Python "
                     f"start-up and imports add {small['import_s']:.2f} s.")
    if big:
        lines.append(f"- 10^7 trials: {big['total_s']:.1f} s (target ≤ 60 s), peak {big['peak_mb']:.0f} MB "
                     "(target ≤ 4,096 MB).")
    mids = [r for r in results if r["trials"] >= 100_000]
    if len(mids) >= 2:
        a, b = mids[0], mids[-1]
        lines.append(f"- Growth: {b['trials'] / a['trials']:.0f}× the trials take "
                     f"{b['total_s'] / a['total_s']:.1f}× the time (linear or better).")
    lines += ["", "Reproduce: `.venv/bin/python benchmarks/bench_analysis.py --write docs/benchmarks.md`"]
    replace_section(path, "analysis", lines)


if __name__ == "__main__":
    raise SystemExit(main())
