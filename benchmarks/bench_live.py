"""Benchmark of live, gaze-contingent trials in a real window (issue 14 item 10): frames per second and
gaze-to-flip latency of every method, measured from the per-flip log a study session writes.

Run:  .venv/bin/python benchmarks/bench_live.py [--window 640x480 | --seed-size] [--scenes temple,cornell]
          [--methods gt,vafr_dup,vafr_rep,lmfr,lafr] [--seconds 8] [--backend gpu] [--write docs/benchmarks.md]

What runs is what a participant sees: ``studyapp run`` on a live yes/no protocol (one trial per method and
scene, ``motion: path``, ``gaze: mouse``) in a PsychoPy window, the mouse jumping to a new point every 250 ms
(saccades) so that the foveation moves, a key pressed once each trial has played. With a ``DISPLAY`` (a lab
machine with a GPU) the window opens there; without one, under a private Xvfb server (Mesa llvmpipe: software
OpenGL on the CPU). ``--seed-size`` opens a 4936 x 2740 window with every method binocular: the seed's
2468 x 2740 per eye, both eyes side by side (``--binocular`` does the same at any window size).

Reported per method and scene, from the session's frames table (data_schema.timing, the summary the exports
use): frames rendered, frames per second (median, 5th percentile), render time per frame (median), dropped
flips, and gaze-to-flip latency (flip time - gaze sample time; median and 95th percentile).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "gui"))
from benchmarks.harness import command_line, machine_line, replace_section  # noqa: E402
from xvfb import query as _q  # noqa: E402  (read-only queries while the session writes)

METHODS = {  # renderer, params
    "gt": ("gt", {}),
    "vafr_dup": ("vafr", {"stereo": "dup"}),
    "vafr_rep": ("vafr", {"stereo": "rep"}),
    "vafr": ("vafr", {}),
    "lmfr": ("lmfr", {}),
    "lafr": ("lafr", {"delta": 1.8}),
}
SEED_WINDOW = (2 * 2468, 2740)  # both eyes of the seed's headset side by side

PROTOCOL = """schema_version: 1
name: bench_live
version: "1"
family: yes_no
question: "Y"
display: {{width_px: {w}, height_px: {h}, width_cm: {width_cm}, distance_cm: 45.0, refresh_hz: {refresh},
  stereo: {stereo}}}
fixation: {{x: 0.5, y: 0.5, mark: false}}
scenes: [{scenes}]
conditions:
{conditions}
stimulus:
  kind: live
  duration_s: {seconds}
  motion: path
  gaze: mouse
  camera_path:
    - {{t: 0.0, yaw_deg: -8.0}}
    - {{t: 1.0, yaw_deg: 8.0}}
timing: {{black_s: 0.3}}
design: {{repetitions: 1, trial_order: interleaved}}
analysis: {{dv: response, unit: trial, test: summary_table}}
"""




def _xdotool(env: dict, *args: str) -> None:
    subprocess.run(["xdotool", *args], env=env, check=False, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def run_session(workdir: Path, protocol: str, env: dict, seconds: float, timeout_s: float) -> Path:
    """Run one session of ``protocol`` and answer every trial once it has played; returns the database."""
    proto, db = workdir / "bench_live.yaml", workdir / "bench_live.db"
    proto.write_text(protocol)
    log = open(workdir / "run.log", "w")
    proc = subprocess.Popen([sys.executable, "-m", "studyapp", "run", str(proto), "--participant", "B1", "--db",
                             str(db), "--quiet"], env=env, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT)
    stop = threading.Event()
    try:
        end = time.monotonic() + 120
        while not _q(db, "SELECT display FROM sessions"):
            if proc.poll() is not None or time.monotonic() > end:
                raise RuntimeError(f"the session did not start: {(workdir / 'run.log').read_text()[-800:]}")
            time.sleep(0.1)
        display = json.loads(_q(db, "SELECT display FROM sessions")[0][0])
        (wx, wy), (ww, wh) = display["window_pos_px"], display["window_size_px"]
        n_trials = _q(db, "SELECT COUNT(*) FROM planned_trials")[0][0]
        rng = random.Random(0)

        def saccades():  # a new gaze point every 250 ms, inside the window
            while not stop.wait(0.25):
                _xdotool(env, "mousemove", str(wx + rng.randrange(ww)), str(wy + rng.randrange(wh)))

        threading.Thread(target=saccades, daemon=True).start()
        time.sleep(1.0)
        _xdotool(env, "key", "space")  # leave the instructions
        deadline = time.monotonic() + timeout_s
        for answered in range(n_trials):
            time.sleep(seconds)
            while (_q(db, "SELECT COUNT(*) FROM responses") or [(-1,)])[0][0] <= answered:  # (-1: busy)
                if proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"the session stopped: {(workdir / 'run.log').read_text()[-800:]}")
                _xdotool(env, "key", "y")
                time.sleep(0.5)
        proc.wait(timeout=60)
    finally:
        stop.set()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        log.close()
    return db


def summarise(db: Path) -> tuple[list[dict], dict]:
    """Per trial: method, scene and the timing summary (plus render time and frame counts); the GL facts."""
    from data_schema.store import open_store
    from data_schema.timing import summary

    rows = []
    with open_store(db) as st:
        planned = {p.idx: p for p in st.planned("B1")}
        facts = json.loads(_q(db, "SELECT display FROM sessions")[0][0])
        for idx in sorted(planned):
            frames = st.frames("B1", idx)
            if not frames:
                continue
            render = [f["render_s"] for f in frames if f["render_s"] is not None]
            s = summary([f["flip_s"] for f in frames], [f["render_s"] for f in frames],
                        [f["gaze_t"] for f in frames], [f["dropped"] for f in frames], [f["stimulus"] for f in frames])
            rows.append({"method": planned[idx].conditions[0], "scene": planned[idx].scene, "flips": len(frames), "frames": len(render),
                         "render_ms": 1000 * statistics.median(render) if render else float("nan"), **s})
    return rows, facts


def table(rows: list[dict], facts: dict, window: tuple[int, int], seconds: float, backend: str,
          binocular: bool) -> list[str]:
    gl = (facts.get("gpu") or {}).get("gl_renderer") or facts.get("gl_renderer", "?")
    out = [f"Window {window[0]}x{window[1]} ({'every method binocular, both eyes side by side' if binocular else 'one view; VaFR dup/rep: both eyes rendered, the left one shown'}), "
           f"{backend} backend on {gl}; {seconds:g}-s trials, `motion: path`, the mouse as the gaze jumping every "
           f"250 ms. {machine_line()} Frames: new frames rendered in the trial; fps: new frames per second; "
           "dropped flips: flips PsychoPy counted as late (a render outlasted the refresh interval); latency: "
           "gaze sample to the flip that showed the frame rendered for it.", "",
           "| method | scene | frames | fps median | fps p5 | render ms (median) | dropped flips | latency p50 ms | latency p95 ms |",
           "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in sorted(rows, key=lambda r: (r["scene"], r["method"])):
        out.append(f"| {r['method']} | {r['scene']} | {r['frames']} | {r['fps_median']:.2f} | {r['fps_p5']:.2f} | "
                   f"{r['render_ms']:,.0f} | {100 * r['dropped_share']:.0f} % | {r['latency_p50_ms']:,.0f} | "
                   f"{r['latency_p95_ms']:,.0f} |")
    return out


def condition(method: str, binocular: bool, backend: str) -> str:
    """The protocol's condition of ``method`` (YAML flow mapping); binocular: both eyes (stereo dup) unless
    the method has its own stereo mode."""
    renderer, params = METHODS[method]
    if binocular and "stereo" not in params:
        params = {**params, "stereo": "dup"}
    return json.dumps({"renderer": renderer, "params": params, "backend": backend})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--window", default="640x480", help="window size WxH (default 640x480)")
    ap.add_argument("--seed-size", action="store_true", help=f"the seed's headset: a {SEED_WINDOW[0]}x"
                    f"{SEED_WINDOW[1]} window, every method binocular (2468x2740 per eye)")
    ap.add_argument("--binocular", action="store_true", help="every method renders both eyes (side by side)")
    ap.add_argument("--scenes", default="temple,cornell")
    ap.add_argument("--methods", default="gt,vafr_dup,vafr_rep,lmfr,lafr")
    ap.add_argument("--seconds", type=float, default=8.0, help="trial duration (default 8)")
    ap.add_argument("--backend", choices=("gpu", "cpu"), default="gpu")
    ap.add_argument("--refresh", type=int, default=60, help="the display's refresh rate, Hz (default 60)")
    ap.add_argument("--write", metavar="MD", help="replace this script's section of the Markdown file")
    args = ap.parse_args(argv)
    window = SEED_WINDOW if args.seed_size else tuple(int(v) for v in args.window.lower().split("x"))
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    unknown = sorted(set(methods) - set(METHODS))
    if unknown:
        ap.error(f"unknown methods {unknown}: choose from {', '.join(METHODS)}")
    conditions = "\n".join(f"  {m}: {condition(m, args.binocular or args.seed_size, args.backend)}" for m in methods)
    protocol = PROTOCOL.format(w=window[0], h=window[1], width_cm=round(53.0 * window[0] / 1920, 2),
                               refresh=args.refresh, scenes=args.scenes, conditions=conditions,
                               stereo=str(bool(args.binocular or args.seed_size)).lower(),
                               seconds=args.seconds)
    n_trials = len(methods) * len(args.scenes.split(","))
    with tempfile.TemporaryDirectory(prefix="bench_live_") as tmp:
        work = Path(tmp)
        if os.environ.get("DISPLAY"):
            db = run_session(work, protocol, dict(os.environ), args.seconds, 600 * n_trials)
        else:
            from xvfb import Xvfb

            with Xvfb(screen=f"{window[0] + 64}x{window[1] + 64}x24") as x:
                db = run_session(work, protocol, x.env, args.seconds, 600 * n_trials)
        rows, facts = summarise(db)
    lines = table(rows, facts, window, args.seconds, args.backend, args.binocular or args.seed_size)
    print("\n".join(lines))
    if args.write:
        cmd = command_line("benchmarks/bench_live.py", argv if argv is not None else sys.argv[1:])
        replace_section(args.write, "bench_live", [
            "## Live trials: frame rate and gaze-to-flip latency (`benchmarks/bench_live.py`)", "",
            f"`{cmd}`.", "", *lines, ""])
    return 0


if __name__ == "__main__":
    sys.exit(main())
