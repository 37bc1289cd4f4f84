"""Benchmark of ``studyapp export --format frames`` (issue 25 item 9): peak memory and time against the number
of logged flips.

Run:  .venv/bin/python benchmarks/bench_export.py [--rows 360000,1440000] [--before-rows 360000]
          [--dir DIR] [--write docs/benchmarks.md]

Each database holds ``N`` flips of live 2AFC trials (720 flips each: 8 s at 90 Hz; 100 trials per participant)
written through the store's own insert path (:func:`synthetic_frames_study` below: every row with its
checksum, as a session writes it). Building 1.44 M rows is the slow part (about a minute), so the databases are
kept in ``--dir`` (default: ``$TMPDIR/studyapp_bench_export``) and reused by later runs.

Each export runs as a fresh child (``benchmarks/harness.py``; peak resident memory of the whole process:
Python, pandas, pyarrow and the export; the store's checks on open included): the command itself for Parquet
and CSV, and, for comparison at ``--before-rows``, the whole-table export this streaming replaced (every row in
one DataFrame). Target: peak under 500 MB for 1.44 M frames.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.harness import (  # noqa: E402
    command_line, load_average, load_line, machine_line, replace_section, run_child)

TARGET_MB = 500.0
#: The export before streaming (kept here to measure it): the frames table in one DataFrame.
WHOLE_TABLE = """
import sys
import pandas as pd
from data_schema.store import open_store
with open_store(sys.argv[1]) as st:
    rows = st.frames()
df = pd.DataFrame(rows).rename(columns={"idx": "trial"})
df["gaze_age_ms"] = (df["flip_s"] - df["gaze_t"]) * 1000.0
df.to_parquet(sys.argv[2], index=False)
"""


def synthetic_frames_study(db_path, n_frames: int, per_trial: int = 720, trials_per_participant: int = 100) -> Path:
    """A new study database holding ``n_frames`` flips of live 2AFC trials (``per_trial`` flips each: 8 s at
    90 Hz), written through :meth:`data_schema.store.Store.commit_response` like a session's (this benchmark's
    databases and tests/test_export_frames.py's).

    Every value is one studyapp logs: flips 1/90 s apart, a render time on new frames (None on every 9th: the
    last frame shown again), a gaze sample 4-8 ms old (none on every 50th flip), a camera walking along x,
    every 100th flip dropped.
    """
    from types import SimpleNamespace

    from data_schema.store import PlannedRow, open_store

    n_trials = -(-n_frames // per_trial)
    with open_store(db_path, "create") as st:
        st.bind_protocol("synthetic_frames", "1", "0" * 64, {"name": "synthetic_frames"})
        for p in range(-(-n_trials // trials_per_participant)):
            pid = f"P{p + 1:03d}"
            first = p * trials_per_participant
            count = min(trials_per_participant, n_trials - first)
            st.enrol(pid, p, p, "0" * 64, [PlannedRow(i, "trial", "2afc", "hall", "", ("LaFR", "GT"), "", False)
                                           for i in range(count)])
            sid = st.start_session(pid, "0" * 64, p, {}, {}, {}, "synthetic")
            for i in range(count):
                n = min(per_trial, n_frames - (first + i) * per_trial)
                flips = [SimpleNamespace(
                    frame=k, stimulus=(k // 360) % 2, flip_s=10.0 * i + k / 90.0,
                    render_s=None if k % 9 == 8 else 0.004 + (k % 7) * 1e-4,
                    gaze_t=None if k % 50 == 49 else 10.0 * i + k / 90.0 - 0.004 - (k % 5) * 1e-3,
                    gaze_x=None if k % 50 == 49 else 960.0 + (k % 200) * 1.5,
                    gaze_y=None if k % 50 == 49 else 540.0 - (k % 120) * 0.75,
                    position=(k * 0.01, 1.6, -3.0), look_at=(k * 0.01, 1.2, 0.0), dropped=k % 100 == 99)
                    for k in range(n)]
                st.commit_response(pid, i, sid, ["A"], chosen="LaFR", rt_s=0.8, onset_s=10.0 * i, frames=flips)
            st.end_session(sid, "completed")
    return Path(db_path)


def database(folder: Path, rows: int) -> tuple[Path, float | None]:
    """The cached database of ``rows`` flips (built, under a temporary name then renamed, if missing) and the
    seconds its build took (None: reused)."""
    from data_schema.store import remove_database

    db = folder / f"frames_{rows}.db"
    if db.is_file():
        return db, None
    partial = folder / f".frames_{rows}.partial.db"
    remove_database(partial)
    t0 = time.perf_counter()
    synthetic_frames_study(partial, rows)
    os.replace(partial, db)
    return db, time.perf_counter() - t0


def measure(argv: list[str], out: Path) -> dict:
    """Peak RSS (MB), wall seconds and output size of one child run (:func:`benchmarks.harness.run_child`)."""
    out.unlink(missing_ok=True)
    r = run_child(argv, " ".join(argv[:4]), row=False)
    size = out.stat().st_size
    out.unlink()
    return {"peak_mb": r["peak_mb"], "seconds": r["wall_s"], "size_mb": size / 1e6}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rows", default="360000,1440000", help="flips per database, comma-separated")
    ap.add_argument("--before-rows", default="360000",
                    help="flips of the whole-table export measured for comparison ('' for none)")
    ap.add_argument("--dir", help="where the databases are kept (default: $TMPDIR/studyapp_bench_export)")
    ap.add_argument("--write", metavar="MD", help="replace the frames-export section of this Markdown file")
    args = ap.parse_args()
    sizes = [int(x) for x in args.rows.split(",") if x]
    before = [int(x) for x in args.before_rows.split(",") if x]
    folder = Path(args.dir or Path(tempfile.gettempdir()) / "studyapp_bench_export").resolve()  # children: cwd ROOT
    folder.mkdir(parents=True, exist_ok=True)
    load0 = load_average()
    results, built = [], {}
    for n in sorted(set(sizes) | set(before)):
        db, seconds = database(folder, n)
        if seconds is not None:
            built[n] = seconds
        runs = []
        if n in sizes:
            runs += [("streamed (this command)", fmt, ["-m", "studyapp", "export", "--db", str(db), "--format",
                                                       "frames", "--out", str(folder / f"out{n}.{fmt}")],
                      folder / f"out{n}.{fmt}") for fmt in ("parquet", "csv")]
        if n in before:
            before_out = folder / "before.parquet"
            runs.append(("whole table (before)", "parquet", ["-c", WHOLE_TABLE, str(db), str(before_out)], before_out))
        for how, fmt, argv, out in runs:
            m = measure(argv, out)
            results.append({"rows": n, "how": how, "format": fmt, **m})
            print(f"{n:>9,} {fmt:<8} {how:<24} peak {m['peak_mb']:7.0f} MB  {m['seconds']:6.1f} s  "
                  f"{m['size_mb']:6.1f} MB", flush=True)
    load1 = load_average()

    from data_schema.store import FRAMES_BLOCK_ROWS, FRAMES_ROW_GROUP_ROWS

    largest = max(sizes)
    worst = max(r["peak_mb"] for r in results if r["rows"] == largest and r["how"].startswith("streamed"))
    lines = ["## Frames export (`benchmarks/bench_export.py`)", "",
             f"`{command_line('benchmarks/bench_export.py', sys.argv[1:])}`. {machine_line()} Load averages at the "
             f"start and end: {load_line(load0, load1)} (wall "
             "times are a shared machine's).", "",
             "`studyapp export --db DB --format frames --out FILE` on databases of live 2AFC trials (720 flips each, "
             "100 trials per participant) written through the store's insert path; peak resident memory of the "
             "whole child process (its maximum resident set: Python, pandas, pyarrow, the store's checks on open and the "
             f"export). The export reads {FRAMES_BLOCK_ROWS:,} rows at a time from a cursor and writes them as runs "
             f"of CSV lines or gathers them into Parquet row groups of {FRAMES_ROW_GROUP_ROWS:,} rows (Arrow "
             "columns); \"whole table (before)\" is the export this replaced (every row in one DataFrame; one "
             "row group per 1,048,576 rows, pyarrow's default, hence its smaller file).", "",
             "| frames | format | export | peak memory | wall | file |",
             "|---:|---|---|---:|---:|---:|"]
    for r in results:
        lines.append(f"| {r['rows']:,} | {r['format']} | {r['how']} | {r['peak_mb']:,.0f} MB | {r['seconds']:.1f} s "
                     f"| {r['size_mb']:.1f} MB |")
    verdict = "holds" if worst < TARGET_MB else "is MISSED"
    lines += ["", f"Target: peak under {TARGET_MB:.0f} MB for {largest:,} frames: {verdict} ({worst:,.0f} MB)."]
    if built:
        lines.append("Building the databases (cached for later runs): " + ", ".join(
            f"{n:,} rows in {s:.0f} s" for n, s in sorted(built.items())) + ".")
    print("\n".join(lines))
    if args.write:
        replace_section(args.write, "frames-export", lines)
    return 0 if worst < TARGET_MB else 1


if __name__ == "__main__":
    raise SystemExit(main())
