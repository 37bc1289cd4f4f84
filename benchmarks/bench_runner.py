"""Benchmark of the study runner: durable response commits and schedule generation.

Run:  .venv/bin/python benchmarks/bench_runner.py [--commits 2000] [--dir DIR] [--smoke] [--write docs/benchmarks.md]

- Commit latency: ``Store.commit_response`` (one fsynced SQLite transaction in WAL mode, ``synchronous=FULL``)
  for ``--commits`` responses in a scratch study in ``--dir`` (default: a temporary folder on the disk of the
  working tree). For scale, the same run measures the floor every durable commit pays: one 4 KiB ``pwrite`` +
  ``fdatasync`` on the same file system.
- Schedules: ``build_schedule`` for 1,000 participants of each shipped protocol (best of 3 passes), and
  whether a second pass gives byte-identical schedules.
- A whole simulated session (seed 003 Task 1, declared qualities) in a fresh database: wall time.

Each measurement (the commits, each protocol's schedules, the session) runs in its own child process
(``harness.run_child``: its peak memory, wall time and the load after it); the raw rows go to
``benchmarks/results/bench_runner.csv``. ``--smoke`` runs every measurement at tiny sizes.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.harness import (load_average, load_line, machine_line, print_row, replace_section,  # noqa: E402
                                results_ref, run_child, write_csv)


def percentile(values, q):
    import numpy as np

    return float(np.percentile(np.asarray(values), q))


def fdatasync_floor(folder: Path, n: int) -> list[float]:
    path = folder / "fsync_probe.bin"
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
    lat = []
    try:
        block = b"x" * 4096
        for i in range(n):
            os.pwrite(fd, block, 4096 * i)
            t0 = time.perf_counter()
            os.fdatasync(fd)
            lat.append(time.perf_counter() - t0)
    finally:
        os.close(fd)
        path.unlink()
    return lat


def timed_commit_latencies(db_path, n: int = 1000) -> list[float]:
    """Seconds per :meth:`data_schema.store.Store.commit_response` for ``n`` responses in a scratch study."""
    from data_schema.store import PlannedRow, open_store

    lat = []
    with open_store(db_path, "create") as st:
        st.bind_protocol("bench", "1", "0" * 64, {"name": "bench"})
        planned = [PlannedRow(i, "trial", "2afc", "s", "", ("a", "b"), "", False) for i in range(n)]
        st.enrol("B1", 1, 0, "0" * 64, planned)
        sid = st.start_session("B1", "0" * 64, 0, {}, {}, {}, "bench")
        for i in range(n):
            t0 = time.perf_counter()
            st.commit_response("B1", i, sid, ["A"], chosen="a", rt_s=0.5, onset_s=1.0)
            lat.append(time.perf_counter() - t0)
    return lat


def bench_commits(folder: Path, n: int) -> dict:
    lat = timed_commit_latencies(folder / "bench.db", n)
    floor = fdatasync_floor(folder, min(n, 1000))
    return {"n": n, "p50": percentile(lat, 50), "p90": percentile(lat, 90), "p99": percentile(lat, 99),
            "max": max(lat), "floor_p50": percentile(floor, 50), "floor_p99": percentile(floor, 99),
            "share_5ms": sum(x <= 0.005 for x in lat) / len(lat),
            "floor_share_5ms": sum(x <= 0.005 for x in floor) / len(floor)}


def bench_schedule(path: str, n: int = 1000) -> dict:
    """``build_schedule`` for ``n`` participants of the protocol at ``path``: best of 3 passes, and whether the
    passes give byte-identical schedules."""
    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.schedule import build_schedule, schedule_bytes

    p = load_protocol(path, check_renderers=False)
    best, cpu, first = float("inf"), float("inf"), None
    for _ in range(3):
        t0, c0 = time.perf_counter(), time.process_time()
        scheds = [build_schedule(p, f"P{i}", 0) for i in range(n)]
        best = min(best, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
        blob = b"".join(schedule_bytes(s) for s in scheds)
        first = blob if first is None else first
    return {"protocol": p.name, "participants": n, "trials": len(scheds[0]), "seconds": best, "cpu": cpu,
            "identical": blob == first}


def bench_session(folder: Path) -> dict:
    """A whole simulated session of seed003_task1 (declared qualities) in a fresh database: its wall time."""
    from studyapp.runner.observer import SimulatedObserver
    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.session import ground_truth_stimuli, run_session

    p = load_protocol(ROOT / "protocols" / "seed003_task1.yaml", stimuli_dir=folder / "none", check_renderers=False)
    t0 = time.perf_counter()
    s = run_session(p, "P1", folder / "session.db",
                    lambda st, d: SimulatedObserver(p, "P1", 0, ground_truth_stimuli(p, st)),
                    allow_declared=True)
    return {"trials": s.planned, "seconds": time.perf_counter() - t0}


def measure(kind: str, arg, folder: str) -> dict:
    """One configuration in this process (``--one``): ``commits`` (``arg`` responses), ``schedule`` (``arg``: the
    protocol's path) or ``session``, with its scratch databases in a fresh folder under ``folder``."""
    with tempfile.TemporaryDirectory(dir=folder, prefix=".bench_runner_") as tmp:
        if kind == "commits":
            return {"kind": kind, **bench_commits(Path(tmp), arg)}
        if kind == "schedule":
            path, n = arg
            return {"kind": kind, **bench_schedule(path, n)}
        return {"kind": kind, **bench_session(Path(tmp))}


def run(commits: int, participants: int, folder: str) -> list[dict]:
    """Every configuration in its own child process (its peak memory, wall time and the load after it)."""
    jobs = [["commits", commits]] + [["schedule", [str(p), participants]]
                                     for p in sorted((ROOT / "protocols").glob("seed*.yaml"))] + [["session", None]]
    rows = []
    for kind, arg in jobs:
        r = run_child([str(Path(__file__).resolve()), "--one", json.dumps([kind, arg, folder])], f"{kind} {arg or ''}")
        rows.append(r)
        print(f"{kind} {r.get('protocol', '')}: peak {r['peak_mb']:.0f} MB, wall {r['wall_s']:.1f} s, load "
              f"{r['load']:.1f}", file=sys.stderr, flush=True)
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--commits", type=int, default=2000)
    ap.add_argument("--dir", help="folder for the scratch databases (default: a temporary folder in the repo)")
    ap.add_argument("--write", metavar="MD", help="replace the runner section of this Markdown file")
    ap.add_argument("--smoke", action="store_true", help="tiny sizes (50 commits, schedules for 10 participants): "
                    "checks that every configuration runs; its figures mean nothing")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print_row(measure(*json.loads(args.one)))
        return 0
    n_commits, participants = (50, 10) if args.smoke else (args.commits, 1000)
    load0 = load_average()
    rows = run(n_commits, participants, str(Path(args.dir or ROOT).resolve()))
    name = f"bench_runner{'_smoke' if args.smoke else ''}.csv"
    write_csv(rows, name)
    commits = next(r for r in rows if r["kind"] == "commits")
    schedules = [r for r in rows if r["kind"] == "schedule"]
    session = next(r for r in rows if r["kind"] == "session")
    ms = 1000.0
    lines = [
        "## Study runner (`benchmarks/bench_runner.py`)",
        "",
        machine_line() + f" One child process per measurement (peak memory up to "
        f"{max(r['peak_mb'] for r in rows):.0f} MB); load average {load_line(load0, load_average())} (other jobs "
        "share the 2 cores and the disk; wall times include their interference, CPU times do not).",
        "",
        "| measurement | value | target |",
        "|---|---:|---|",
        f"| commit one response (fsynced, WAL, synchronous=FULL), p50 | {commits['p50'] * ms:.2f} ms | |",
        f"| commit one response, p90 | {commits['p90'] * ms:.2f} ms | |",
        f"| commit one response, p99 | {commits['p99'] * ms:.2f} ms | ≤ 5 ms |",
        f"| commit one response, max of {commits['n']} | {commits['max'] * ms:.2f} ms | |",
        f"| share of commits within 5 ms | {commits['share_5ms']:.1%} | |",
        (f"| floor: one 4 KiB pwrite + fdatasync on the same disk, p50 / p99 | {commits['floor_p50'] * ms:.2f} / "
         f"{commits['floor_p99'] * ms:.2f} ms (within 5 ms: {commits['floor_share_5ms']:.1%}) | |"),
    ]
    for r in schedules:
        lines.append(f"| schedules for {r['participants']:,} participants, {r['protocol']} "
                     f"({r['trials']} trials each) | "
                     f"{r['seconds']:.3f} s wall, {r['cpu']:.3f} s CPU"
                     f"{'' if r['identical'] else ' (NOT identical on re-run)'} | ≤ 1 s |")
    lines.append(f"| whole simulated session, seed003_task1 ({session['trials']} trials, fresh DB) | "
                 f"{session['seconds']:.2f} s | |")
    ratio = commits["p99"] / commits["floor_p99"] if commits["floor_p99"] else float("nan")
    verdict = "holds" if commits["p99"] <= 0.005 else "is missed"
    lines += ["", (f"The 5 ms target {verdict} in this run. Commit p99 is {ratio:.2f}× the p99 of a bare "
                   "fdatasync on the same disk: a durable commit cannot be faster than the disk's flush, and on "
                   "this shared virtual disk the flush varies between runs (other runs measured flushes of one "
                   "or two ~4 ms ticks, p99 8-12 ms, while other jobs were writing). Re-running gives "
                   f"byte-identical schedules: {'yes' if all(r['identical'] for r in schedules) else 'NO'}."), "",
              "Reproduce: `.venv/bin/python benchmarks/bench_runner.py --write docs/benchmarks.md` (raw rows: "
              f"`{results_ref(name)}`)"]
    print("\n".join(lines))
    if args.write:
        replace_section(args.write, "runner", lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
