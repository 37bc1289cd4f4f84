"""Benchmark of offline rendering on Dask distributed (issue 15 item 6): speed-up, scheduling overhead, budgets.

Run:  .venv/bin/python benchmarks/bench_cluster.py [--part speedup,overhead,budget] [--repeats 3]

- ``speedup``: ``studyapp prepare`` of a bench protocol (``interior`` and ``street_night`` at 960x540, GT,
  VaFR and LaFR(1.8), ``--frames`` frames each) as a fresh process, in process (``--workers 1``) and on a local
  cluster of 2 workers (``--workers 2``), alternately, ``--repeats`` times into fresh folders: wall time and CPU
  seconds (user + sys of the command and its workers), medians; the two stimulus sets must be byte-identical.
- ``overhead``: a local cluster of 2 workers started and stopped (seconds), and ``--tasks`` trivial tasks through
  ``studyapp.cluster.run_tasks`` on it (submission, scheduling, the result back, the progress callback): the
  scheduling overhead per task.
- ``budget``: seconds per frame of every (condition, scene) of the seed 003 protocols, in this process, at their
  size (256x144, GT 256 + 256 samples) and, for their full-size variant (1920x1080, GT 2048 + 2048), at a
  160x90 probe scaled by the pixel count (the renderers' work is per pixel at a fixed visual angle). The
  budgets are frames x seconds per frame / workers (``docs/distributed.md``).

Writes the section ``cluster`` of ``docs/benchmarks.md`` and the section ``budget`` of ``docs/distributed.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

PROTOCOL = """
schema_version: 1
name: bench_cluster
version: "1"
family: 2afc
question: "Which one?"
display: {{width_px: 1920, height_px: 1080, width_cm: 53.0, distance_cm: 45.0}}
scenes: [interior, street_night]
conditions:
  GT: {{renderer: gt}}
  VaFR: {{renderer: vafr}}
  LaFR: {{renderer: lafr, params: {{delta: 1.8}}}}
stimulus:
  kind: sequence
  render_px: [960, 540]
  duration_s: {frames}
  fps: 1
  camera_path: [{{t: 0, yaw_deg: -6}}, {{t: 1, yaw_deg: 6}}]
design: {{repetitions: 1}}
simulation: {{ground_truth: GT}}
analysis: {{dv: chosen, unit: participant, test: thurstone}}
"""
SEED003 = ("seed003_task1", "seed003_task2")
PROBE = (160, 90)


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def speedup(folder: Path, frames: int, repeats: int) -> dict:
    """Wall and CPU seconds of ``studyapp prepare`` with 1 and 2 local workers (fresh processes, alternately)."""
    proto = folder / "bench.yaml"
    proto.write_text(PROTOCOL.format(frames=float(frames)))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out: dict[str, dict[str, list]] = {w: {"wall": [], "cpu": [], "load": []} for w in ("1", "2")}
    sets = {}
    for rep in range(repeats):
        for workers in (1, 2):
            stim, cache = folder / f"s{workers}_{rep}", folder / f"c{workers}_{rep}"
            cpu0, t0 = _children_cpu(), time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "studyapp", "prepare", str(proto), "--workers", str(workers),
                                "--stimuli", str(stim), "--cache", str(cache)], env=env, capture_output=True,
                               text=True, check=False)
            wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
            if r.returncode != 0:
                raise SystemExit(r.stderr)
            out[str(workers)]["wall"].append(wall)
            out[str(workers)]["cpu"].append(cpu)
            out[str(workers)]["load"].append(os.getloadavg()[0])
            print(f"prepare, {workers} worker(s), run {rep + 1}: {wall:.1f} s wall, {cpu:.1f} CPU s; "
                  f"load {os.getloadavg()[0]:.1f}", flush=True)
            sets[workers] = _files(stim)
    n = 2 * 3 * frames
    med = {w: {k: statistics.median(d[k]) for k in ("wall", "cpu")} for w, d in out.items()}
    return {"frames": n, "runs": out, "median": med, "speedup": med["1"]["wall"] / med["2"]["wall"],
            "identical": sets[1] == sets[2]}


def overhead(n_tasks: int) -> dict:
    """Start-up and shut-down of a 2-worker local cluster, and the per-task overhead of trivial tasks on it."""
    from studyapp import cluster

    spec = cluster.ClusterSpec(workers=2)
    tasks = [cluster.Task(f"noop-{i}", f"task {i}", abs, (-i,)) for i in range(n_tasks)]
    got = []
    t0 = time.perf_counter()
    with cluster.connect(spec) as client:
        started = time.perf_counter() - t0
        cluster.run_tasks(tasks[:20], spec, client=client)  # the workers' first tasks: imports, connections
        per_round = []
        for _ in range(3):
            got.clear()
            wall = cluster.run_tasks(tasks, spec, lambda t, r: got.append(r), client=client)
            per_round.append(wall / n_tasks)
        t1 = time.perf_counter()
    stopped = time.perf_counter() - t1
    assert sorted(got) == sorted(range(n_tasks))
    serial = cluster.run_tasks(tasks, cluster.SERIAL) / n_tasks
    return {"start_s": started, "stop_s": stopped, "per_task_ms": 1000 * statistics.median(per_round),
            "per_task_serial_ms": 1000 * serial, "tasks": n_tasks}


def budget() -> dict:
    """Seconds per frame of each (condition, scene) of the seed 003 protocols at both sizes (measured here, in
    process), and the frames each protocol renders: ``{"seconds": [...], "frames": [...]}``."""
    from renderers.registry import render
    from studyapp.commands.study import SHIPPED
    from studyapp.runner.camera import frame_camera
    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.stimuli import needed_stimuli

    seconds: dict = {}
    frames = []
    for name in SEED003:
        for full in (False, True):
            p = load_protocol(SHIPPED / f"{name}.yaml", full=full)
            g = p.render_geometry()
            w, h = PROBE if full else (g.width, g.height)
            for need in needed_stimuli(p):
                cond = p.conditions[need.condition]
                if not cond.renderer:
                    continue
                key = _pair(cond.renderer, cond.params, need.scene, full)
                frames.append({"protocol": name, "full": full, "condition": need.condition, "scene": need.scene,
                               "frames": p.n_frames, "pair": key})
                if key not in seconds:
                    render(p.scene_ref(need.scene), cond.renderer, cond.params, 16, 9)  # kernels, BVH
                    cam = frame_camera(p, need.scene, 1)
                    _, st = render(p.scene_ref(need.scene), cond.renderer, cond.params, w, h, camera=cam)
                    scale = g.width * g.height / (w * h)
                    seconds[key] = {"seconds": st["seconds"]["total"], "probe": [w, h], "scale": scale}
                    print(f"{cond.renderer} {cond.params} {need.scene} at {w}x{h}: {st['seconds']['total']:.2f} s "
                          f"(x{scale:g} -> {st['seconds']['total'] * scale:.1f} s at {g.width}x{g.height}); "
                          f"load {os.getloadavg()[0]:.1f}", flush=True)
    return {"seconds": seconds, "frames": frames}


def _pair(renderer: str, params: dict, scene: str, full: bool) -> str:
    return f"{renderer} {json.dumps(params, sort_keys=True)} {scene}{' full' if full else ''}"


#: Seed 003's own sequences: 8 s at 90 fps, 2468 x 2740 per eye (one eye), 5 conditions x 5 scenes.
SEED_FRAMES, SEED_PX = 8 * 90, (2468, 2740)


def budget_table(measured: dict) -> dict:
    """CPU seconds per protocol (and condition) from :func:`budget`'s measurements, and seed 003's own size."""
    sec = {k: v["seconds"] * v["scale"] for k, v in measured["seconds"].items()}
    out: dict = {}
    for f in measured["frames"]:
        name = f"{f['protocol']}{' --full' if f['full'] else ''}"
        row = out.setdefault(name, {"frames": 0, "cpu_s": 0.0, "by_condition": {}})
        t = f["frames"] * sec[f["pair"]]
        row["frames"] += f["frames"]
        row["cpu_s"] += t
        row["by_condition"][f["condition"]] = row["by_condition"].get(f["condition"], 0.0) + t
    # the seed's sequences: every main condition x scene of Task 1 at full size, per frame, scaled to its pixels
    main = [f for f in measured["frames"] if f["protocol"] == SEED003[0] and f["full"]
            and f["condition"] in ("EC", "CC1", "CC2", "CC3", "CC4") and f["scene"] != "cornell"]
    px = SEED_PX[0] * SEED_PX[1] / (1920 * 1080)
    out["seed 003's own: 8 s at 90 fps, 2468x2740"] = {
        "frames": SEED_FRAMES * len(main), "cpu_s": SEED_FRAMES * px * sum(sec[f["pair"]] for f in main),
        "by_condition": {}}
    return out


def _hours(s: float) -> str:
    return f"{s / 3600:.1f} h" if s >= 3600 else f"{s / 60:.1f} min"


def report(res: dict) -> None:
    from _report import machine_line, replace_section

    lines = ["## Offline rendering on a cluster (`benchmarks/bench_cluster.py`)", "",
             machine_line() + " The cores are shared with other jobs (load averages below, from `uptime`), so wall "
             "times carry their load; every run is niced. Raw results: `docs/bench_cluster.json`.", ""]
    if "speedup" in res:
        s = res["speedup"]
        m = s["median"]
        lines += [f"`studyapp prepare` of {s['frames']} frames (interior and street_night at 960x540: GT, VaFR, "
                  f"LaFR(1.8)), a fresh process per run, {len(s['runs']['1']['wall'])} runs of each, alternating; "
                  "medians. `--workers 1` renders in process (numba's kernels use both cores); `--workers 2` starts "
                  "a local cluster of 2 single-threaded workers (numba: 1 thread each). Load averages (1, 5, 15 "
                  f"min) at the start and end: {s.get('load', '?')}; after each run (1 min): 1 worker "
                  f"{', '.join(f'{x:.1f}' for x in s['runs']['1'].get('load', []))}, 2 workers "
                  f"{', '.join(f'{x:.1f}' for x in s['runs']['2'].get('load', []))}.", "",
                  "| workers | wall s (median) | CPU s (median) | runs (wall s) |", "|---:|---:|---:|---|"]
        for w in ("1", "2"):
            lines.append(f"| {w} | {m[w]['wall']:.1f} | {m[w]['cpu']:.1f} | "
                         f"{', '.join(f'{x:.1f}' for x in s['runs'][w]['wall'])} |")
        ok = "met" if s["speedup"] >= 1.7 else "missed"
        lines += ["", f"Speed-up of 2 workers over 1: **{s['speedup']:.2f}x** (target >= 1.7x: {ok}); the stimulus "
                  f"sets are {'byte-identical' if s['identical'] else 'DIFFERENT'}. In process the command got "
                  f"{m['1']['cpu'] / m['1']['wall']:.2f} cores on average, the cluster "
                  f"{m['2']['cpu'] / m['2']['wall']:.2f}; the cluster spent {m['2']['cpu'] - m['1']['cpu']:+.1f} "
                  "CPU s more (each worker process imports Dask and the renderers, loads the compiled kernels and "
                  "builds the scenes and their BVHs once; task traffic).", ""]
    if "overhead" in res:
        o = res["overhead"]
        lines += [f"Scheduling overhead: {o['tasks']} trivial tasks through `studyapp.cluster.run_tasks` on a local "
                  f"cluster of 2 workers take **{o['per_task_ms']:.2f} ms per task** (median of 3 rounds; in "
                  f"process {o['per_task_serial_ms']:.3f} ms); starting the cluster takes {o['start_s']:.1f} s and "
                  f"stopping it {o['stop_s']:.1f} s (once per command). Load: {o.get('load', '?')}.", ""]
    replace_section(str(ROOT / "docs" / "benchmarks.md"), "cluster", lines)
    if "budget" in res:
        b = budget_table(res["budget"])
        rows = ["| protocol | frames | 1 worker (CPU time) | 2 workers (this machine) | 16 workers | 64 workers |",
                "|---|---:|---:|---:|---:|---:|"]
        for name, v in b.items():
            rows.append(f"| `{name}` | {v['frames']:,} | {_hours(v['cpu_s'])} | "
                        f"{_hours(v['cpu_s'] / 2)} | {_hours(v['cpu_s'] / 16)} | {_hours(v['cpu_s'] / 64)} |")
        detail = []
        for name, v in b.items():
            if not v["by_condition"]:
                continue
            parts = ", ".join(f"{c} {_hours(t)}" for c, t in sorted(v["by_condition"].items()))
            detail.append(f"- `{name}`: {parts}.")
        lines = ["Measured by `benchmarks/bench_cluster.py --part budget` (" + machine_line() +
                 f" Load averages at the start and end: {res['budget'].get('load', '?')}, so frame times are "
                 "those of a shared machine): one frame of every (condition, scene) in one process, at the protocol's "
                 f"size, and for `--full` at {PROBE[0]}x{PROBE[1]} scaled by the pixel count to 1920x1080. "
                 "Budget = frames x seconds per frame / workers (workers of this machine's speed, one frame "
                 "each; add the cluster's start-up, seconds, and its scheduling, milliseconds per frame: "
                 "docs/benchmarks.md).", "",
                 *rows, "", "CPU time by condition:", "", *detail]
        replace_section(str(ROOT / "docs" / "distributed.md"), "budget", lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", default="speedup,overhead,budget")
    ap.add_argument("--frames", type=int, default=8, help="frames per (condition, scene) of the bench protocol")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--tasks", type=int, default=500)
    ap.add_argument("--from-json", metavar="FILE", help="write the sections from an earlier run's results")
    args = ap.parse_args(argv)
    parts = [p for p in args.part.split(",") if p]
    res = json.loads(Path(args.from_json).read_text()) if args.from_json else {}
    with tempfile.TemporaryDirectory(prefix="bench_cluster_") as tmp:
        for part, run in (("speedup", lambda: speedup(Path(tmp), args.frames, args.repeats)),
                          ("overhead", lambda: overhead(args.tasks)), ("budget", budget)):
            if part in parts:
                before = os.getloadavg()
                res[part] = run()
                res[part]["load"] = f"{' '.join(f'{x:.2f}' for x in before)} -> " \
                                    f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}"
    out = ROOT / "docs" / "bench_cluster.json"
    from data_schema.atomic import write_text

    write_text(out, json.dumps(res, indent=1, default=str) + "\n")
    report(res)
    print(json.dumps({k: v for k, v in res.items() if k != "budget"}, indent=1, default=str))


if __name__ == "__main__":
    main()
