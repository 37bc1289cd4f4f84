"""Benchmark of offline rendering on Dask distributed (issue 15 item 6): speed-up, scheduling overhead, budgets.

Run:  .venv/bin/python benchmarks/bench_cluster.py [--part speedup,memory,overhead,budget] [--repeats 3]

- ``speedup``: ``studyapp prepare`` of a bench protocol (``interior`` and ``street_night`` at 960x540, GT,
  VaFR and LaFR(1.8), ``--frames`` frames each) as a fresh process: in process (``--workers 1``), on a local
  cluster of 2 workers (``--workers 2``), and on a running scheduler (started by the benchmark on loopback,
  fresh per run) with 1 and with 2 single-threaded workers (the scale-out target: 2 workers >= 1.7x 1 worker);
  alternately, ``--repeats`` times into fresh folders: wall time and CPU seconds (user + sys of the command and
  its workers), medians; every configuration's stimulus set must be byte-identical.
- ``scaleout``: the running-scheduler configurations alone (1 and 2 workers) over 3 x ``--frames`` frames, so
  that the workers' start-up weighs less.
- ``memory``: peak resident memory of ``prepare --serial`` (one process) and of one ``dask worker`` rendering
  the same frames (``/usr/bin/time -v``).
- ``overhead``: a local cluster of 2 workers started and stopped (seconds), and ``--tasks`` trivial tasks through
  ``studyapp.cluster.run_tasks`` on it (submission, scheduling, the result back, the progress callback): the
  scheduling overhead per task.
- ``budget``: seconds per frame of every (condition, scene) of the seed 003 protocols, in this process, at their
  size (256x144, GT 256 + 256 samples) and, for their full-size variant (1920x1080, GT 2048 + 2048), at a
  160x90 probe scaled by the pixel count (the renderers' work is per pixel at a fixed visual angle). The
  budgets are frames x seconds per frame / workers (``docs/distributed.md``).

Writes the section ``cluster`` of ``docs/benchmarks.md`` and the section ``budget`` of ``docs/distributed.md``; the
raw results go to ``benchmarks/results/bench_cluster.json`` (not committed; ``--from-json`` rewrites the sections
from it).
"""

from __future__ import annotations

import argparse
import json
import resource
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.harness import (  # noqa: E402
    DOC, child_env, load_average, load_line, machine_line, peak_rss_mb, replace_section, results_ref, write_json)

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


CONFIGS = {
    "1": "in process (`--workers 1`; numba's kernels on both cores)",
    "2": "local cluster of 2 workers (`--workers 2`; numba: 1 thread each; start-up included)",
    "w1": "running scheduler, 1 worker (`dask worker --nthreads 1`, NUMBA_NUM_THREADS=1)",
    "w2": "running scheduler, 2 workers (each as `w1`)",
}


class _Workers:
    """A ``dask scheduler`` and ``n`` single-threaded ``dask worker`` processes on loopback, started fresh per run
    (as a lab's machines would be: `docs/distributed.md`), so each run's workers build their scenes anew."""

    def __init__(self, folder: Path, n: int, env: dict, measure_memory: bool = False):
        dask = Path(sys.executable).with_name("dask")
        self.logs = [folder / f"worker{i}.time" for i in range(n)]
        wrap = (lambda i: ["/usr/bin/time", "-v", "-o", str(self.logs[i])]) if measure_memory else (lambda i: [])
        self.file = folder / "scheduler.json"
        self.file.unlink(missing_ok=True)
        # MALLOC_TRIM_THRESHOLD_: what a Dask nanny sets for its worker (distributed.nanny.pre-spawn-environ);
        # these workers run without a nanny so that /usr/bin/time measures the worker process itself
        wenv = {**env, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MALLOC_TRIM_THRESHOLD_": "65536"}
        self.procs = [subprocess.Popen([str(dask), "scheduler", "--host", "127.0.0.1", "--port", "0",
                                        "--no-dashboard", "--scheduler-file", str(self.file)], env=env,
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
        deadline = time.monotonic() + 60
        while not self.file.is_file() or not self.file.read_text().strip():
            if time.monotonic() > deadline:
                raise SystemExit("the benchmark's dask scheduler did not start")
            time.sleep(0.1)
        self.address = json.loads(self.file.read_text())["address"]
        self.procs += [subprocess.Popen([*wrap(i), str(dask), "worker", self.address, "--nthreads", "1",
                                         "--no-nanny", "--no-dashboard", "--host", "127.0.0.1", "--memory-limit", "0"],
                                        env=wenv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                       for i in range(n)]
        from distributed import Client

        with Client(self.address, timeout=30, set_as_default=False) as c:
            c.wait_for_workers(n, timeout=120)

    def close(self):
        for p in reversed(self.procs):
            # /usr/bin/time passes SIGINT on to the worker and then writes its report; SIGTERM would kill it first
            p.send_signal(signal.SIGINT if p.args[0] == "/usr/bin/time" else signal.SIGTERM)
        for p in self.procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()


def speedup(folder: Path, frames: int, repeats: int, configs=tuple(CONFIGS)) -> dict:
    """Wall and CPU seconds of ``studyapp prepare`` in process, on a local cluster of 2 workers, and on a running
    scheduler with 1 and with 2 single-threaded workers (fresh processes, alternately, ``repeats`` times)."""
    proto = folder / "bench.yaml"
    proto.write_text(PROTOCOL.format(frames=float(frames)))
    env = child_env()
    out: dict[str, dict[str, list]] = {w: {"wall": [], "cpu": [], "load": []} for w in configs}
    sets = {}
    for rep in range(repeats):
        for cfg in configs:
            label = CONFIGS[cfg]
            stim, cache = folder / f"s{cfg}_{rep}", folder / f"c{cfg}_{rep}"
            workers = _Workers(folder, int(cfg[1:]), env) if cfg.startswith("w") else None
            where = ["--scheduler", workers.address] if workers else ["--workers", cfg]
            try:
                cpu0, t0 = _children_cpu(), time.perf_counter()
                r = subprocess.run([sys.executable, "-m", "studyapp", "prepare", str(proto), *where,
                                    "--stimuli", str(stim), "--cache", str(cache)], env=env, capture_output=True,
                                   text=True, check=False)
                wall = time.perf_counter() - t0
            finally:
                if workers:
                    workers.close()
            cpu = _children_cpu() - cpu0  # the scheduler's and workers' CPU time is counted once they exit
            if r.returncode != 0:
                raise SystemExit(r.stderr)
            out[cfg]["wall"].append(wall)
            out[cfg]["cpu"].append(cpu)
            out[cfg]["load"].append(load_average()[0])
            print(f"prepare, {label}, run {rep + 1}: {wall:.1f} s wall, {cpu:.1f} CPU s; "
                  f"load {load_average()[0]:.1f}", flush=True)
            sets[cfg] = _files(stim)
    n = 2 * 3 * frames
    med = {w: {k: statistics.median(d[k]) for k in ("wall", "cpu")} for w, d in out.items()}
    first = next(iter(sets.values()))
    res = {"frames": n, "runs": out, "median": med, "identical": all(v == first for v in sets.values())}
    if "1" in med and "2" in med:
        res["speedup"] = med["1"]["wall"] / med["2"]["wall"]
    if "w1" in med and "w2" in med:
        res["scaleout"] = med["w1"]["wall"] / med["w2"]["wall"]
    return res


def memory(folder: Path, frames: int) -> dict:
    """Peak memory of rendering the bench protocol in one process (``prepare --serial``: today's per-render
    path, every scene built in that process) and of a ``dask worker`` rendering the same frames for
    ``prepare --scheduler`` (``/usr/bin/time -v``, maximum resident set size)."""
    proto = folder / "bench_mem.yaml"
    proto.write_text(PROTOCOL.format(frames=float(frames)))
    env = child_env()
    report = folder / "serial.time"
    r = subprocess.run(["/usr/bin/time", "-v", "-o", str(report), sys.executable, "-m", "studyapp", "prepare",
                        str(proto), "--serial", "--stimuli", str(folder / "ms"), "--cache", str(folder / "mc")],
                       env=env, capture_output=True, text=True, check=False)
    if r.returncode != 0:
        raise SystemExit(r.stderr)
    serial = peak_rss_mb(report.read_text())
    workers = _Workers(folder, 1, env, measure_memory=True)
    try:
        r = subprocess.run([sys.executable, "-m", "studyapp", "prepare", str(proto), "--scheduler", workers.address,
                            "--stimuli", str(folder / "mw"), "--cache", str(folder / "mwc")], env=env,
                           capture_output=True, text=True, check=False)
    finally:
        workers.close()
    if r.returncode != 0:
        raise SystemExit(r.stderr)
    worker = peak_rss_mb(workers.logs[0].read_text())
    idle = _Workers(folder, 1, env, measure_memory=True)  # Dask's own runtime: a worker that renders nothing
    idle.close()
    idle_mb = peak_rss_mb(idle.logs[0].read_text())
    empty = folder / "python.time"
    subprocess.run(["/usr/bin/time", "-v", "-o", str(empty), sys.executable, "-c", "import studyapp.cli"], env=env,
                   check=True)
    base_mb = peak_rss_mb(empty.read_text())
    print(f"peak RSS: in process {serial:.0f} MB, one dask worker {worker:.0f} MB (an idle worker {idle_mb:.0f} MB, "
          f"python with studyapp's CLI {base_mb:.0f} MB)", flush=True)
    return {"frames": 2 * 3 * frames, "serial_mb": serial, "worker_mb": worker, "idle_worker_mb": idle_mb,
            "python_mb": base_mb}


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
                          f"load {load_average()[0]:.1f}", flush=True)
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
    lines = ["## Offline rendering on a cluster (`benchmarks/bench_cluster.py`)", "",
             machine_line() + " The cores are shared with other jobs (load averages below, from `uptime`), so wall "
             f"times carry their load; every run is niced. Raw results: `{results_ref('bench_cluster.json')}` (not "
             "committed).", ""]
    if "speedup" in res:
        s = res["speedup"]
        m = s["median"]
        cfgs = [c for c in CONFIGS if c in s["runs"]]
        lines += [f"`studyapp prepare` of {s['frames']} frames (interior and street_night at 960x540: GT, VaFR, "
                  f"LaFR(1.8)), a fresh process (and fresh workers) per run, {len(s['runs']['1']['wall'])} runs of "
                  "each configuration, alternating; medians. Load averages (1, 5, 15 min) at the start and end: "
                  f"{s.get('load', '?')}.", "",
                  "| configuration | wall s (median) | CPU s (median) | cores used | runs (wall s) | load after each |",
                  "|---|---:|---:|---:|---|---|"]
        for w in cfgs:
            lines.append(f"| {CONFIGS[w]} | {m[w]['wall']:.1f} | {m[w]['cpu']:.1f} | "
                         f"{m[w]['cpu'] / m[w]['wall']:.2f} | {', '.join(f'{x:.1f}' for x in s['runs'][w]['wall'])} "
                         f"| {', '.join(f'{x:.1f}' for x in s['runs'][w].get('load', []))} |")
        lines += [""]
        if "scaleout" in s:
            ok = "met" if s["scaleout"] >= 1.7 else "missed"
            lines += [f"Scale-out, 2 workers over 1 on a running scheduler: **{s['scaleout']:.2f}x** (target >= 1.7x: "
                      f"{ok}); each run includes its workers' start-up (imports, compiled kernels, scene and BVH "
                      "builds: seconds per worker, paid in parallel), which a longer run amortises (below)."]
        lines += [f"`--workers 2` over in process: **{s['speedup']:.2f}x** (in process numba already runs every "
                  "frame's pixels on both cores, so a local cluster on this machine gains nothing over it: it adds "
                  "the workers' start-up, imports and scene builds). The stimulus sets of every configuration are "
                  f"{'byte-identical' if s['identical'] else 'DIFFERENT'}.", ""]
    if "scaleout" in res:
        s = res["scaleout"]
        m = s["median"]
        ok = "met" if s["scaleout"] >= 1.7 else "missed"
        lines += [f"Longer runs, `--part scaleout`: {s['frames']} frames, running scheduler, fresh workers per run, "
                  f"{len(s['runs']['w1']['wall'])} runs each, alternating: 1 worker {m['w1']['wall']:.1f} s, 2 workers "
                  f"{m['w2']['wall']:.1f} s (runs: {', '.join(f'{x:.1f}' for x in s['runs']['w1']['wall'])} / "
                  f"{', '.join(f'{x:.1f}' for x in s['runs']['w2']['wall'])}): **{s['scaleout']:.2f}x** (target >= "
                  f"1.7x: {ok}); sets byte-identical: {s['identical']}. Load: {s.get('load', '?')}.", ""]
    if "memory" in res:
        mm = res["memory"]
        lines += [f"Memory (item 3): peak resident set of `prepare --serial` of {mm['frames']} frames (every frame "
                  f"and scene in one process, today's path) **{mm['serial_mb']:.0f} MB**; peak of one `dask worker` "
                  f"rendering the same frames for `prepare --scheduler` **{mm['worker_mb']:.0f} MB** "
                  f"(`/usr/bin/time -v`; the worker with `MALLOC_TRIM_THRESHOLD_=65536`, which Dask's nanny sets for "
                  "its workers, `dask worker` without `--no-nanny`). Above a bare process, rendering adds "
                  f"{mm['serial_mb'] - mm['python_mb']:.0f} "
                  f"MB in process and {mm['worker_mb'] - mm['idle_worker_mb']:.0f} MB in the worker (which holds one "
                  "frame at a time and its scenes, like the process); the rest of the difference is Dask's own "
                  f"runtime (an idle worker: {mm['idle_worker_mb']:.0f} MB; python with studyapp's CLI: "
                  f"{mm['python_mb']:.0f} MB).", ""]
    if "overhead" in res:
        o = res["overhead"]
        lines += [f"Scheduling overhead: {o['tasks']} trivial tasks through `studyapp.cluster.run_tasks` on a local "
                  f"cluster of 2 workers take **{o['per_task_ms']:.2f} ms per task** (median of 3 rounds; in "
                  f"process {o['per_task_serial_ms']:.3f} ms); starting the cluster takes {o['start_s']:.1f} s and "
                  f"stopping it {o['stop_s']:.1f} s (once per command). Load: {o.get('load', '?')}.", ""]
    replace_section(DOC, "cluster", lines)
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
    ap.add_argument("--part", default="speedup,memory,overhead,budget")
    ap.add_argument("--frames", type=int, default=8, help="frames per (condition, scene) of the bench protocol")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--tasks", type=int, default=500)
    ap.add_argument("--from-json", metavar="FILE", help="write the sections from an earlier run's results")
    args = ap.parse_args(argv)
    parts = [p for p in args.part.split(",") if p]
    res = json.loads(Path(args.from_json).read_text()) if args.from_json else {}
    with tempfile.TemporaryDirectory(prefix="bench_cluster_") as tmp:
        for part, run in (("speedup", lambda: speedup(Path(tmp), args.frames, args.repeats)),
                          ("scaleout", lambda: speedup(Path(tmp), 3 * args.frames, args.repeats, ("w1", "w2"))),
                          ("memory", lambda: memory(Path(tmp), min(args.frames, 2))),
                          ("overhead", lambda: overhead(args.tasks)), ("budget", budget)):
            if part in parts:
                before = load_average()
                res[part] = run()
                res[part]["load"] = load_line(before, load_average())
    write_json(res, "bench_cluster.json")
    report(res)
    print(json.dumps({k: v for k, v in res.items() if k != "budget"}, indent=1, default=str))


if __name__ == "__main__":
    main()
