"""The benchmark harness: every script in ``benchmarks/`` measures and reports through this module (and no script
imports another).

* **One configuration per child process** (:func:`run_child`): ``python ARGS``; the child prints its row as JSON
  on its last line (:func:`print_row`); the harness adds the child's peak resident memory (``peak_mb``, from
  ``wait4``), its wall time (``wall_s``) and the machine's load average after it (``load``).
* **Medians** of repeated timings after a warm-up (:func:`median_seconds`).
* **Machine and date**: :func:`machine_line` heads every report section; :func:`load_line` records how busy the
  shared machine was.
* **Raw results** (one run's CSV, JSON, figures) go to :data:`RESULTS`, ``benchmarks/results/`` (ignored by git:
  :func:`results_path`, :func:`write_csv`, :func:`write_json`); ``docs/benchmarks.md`` keeps only the summary
  tables, one marked section per script (:func:`replace_section`, :data:`DOC`).
* The GPU backend's configurations (:func:`timed_frames`, :func:`gpu_device_line`, :data:`LLVMPIPE_NOTE`), shared
  by ``bench_gpu*.py``.
"""

from __future__ import annotations

import csv
import datetime
import json
import os
import platform
import shlex
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: The summary tables, one marked section per script.
DOC = os.path.join(ROOT, "docs", "benchmarks.md")
#: One run's raw results (CSV, JSON, figures): not committed (``.gitignore``).
RESULTS = os.path.join(ROOT, "benchmarks", "results")


# -- machine, date, load -------------------------------------------------------------------------------------------
def machine_line() -> str:
    """One line naming the machine the figures were measured on, and the date (UTC)."""
    day = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d")
    return (f"Machine: {os.cpu_count()} cores, {platform.processor() or platform.machine()}, "
            f"Python {platform.python_version()}; measured {day}.")


def load_average() -> tuple[float, float, float]:
    """The 1-, 5- and 15-minute load averages (other jobs on the cores inflate wall times)."""
    return os.getloadavg()


def load_line(before: Sequence[float], after: Sequence[float]) -> str:
    """``'a b c -> d e f'``: the load averages at the start and the end of a run."""
    return f"{' '.join(f'{x:.2f}' for x in before)} -> {' '.join(f'{x:.2f}' for x in after)}"


def command_line(script: str, argv: list[str]) -> str:
    """The shell command that reruns ``script`` with ``argv``, for the report: arguments a shell would split or
    drop (empty, spaces, quotes) are quoted, in double quotes where that is enough (easier to read)."""
    def quote(arg: str) -> str:
        if arg and shlex.quote(arg) == arg:
            return arg
        return f'"{arg}"' if not any(c in arg for c in '"$`\\!') else shlex.quote(arg)
    return " ".join(["python", script, *map(quote, argv)])


# -- timing --------------------------------------------------------------------------------------------------------
def timings(fn: Callable[[], object], repeats: int, warm: bool = True) -> list[float]:
    """The wall times of ``repeats`` calls of ``fn`` (after one untimed call when ``warm``: compilation, caches,
    first allocations)."""
    if warm:
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return times


def median_seconds(fn: Callable[[], object], repeats: int, warm: bool = True) -> float:
    """The median of :func:`timings`."""
    return statistics.median(timings(fn, repeats, warm))


# -- child processes -----------------------------------------------------------------------------------------------
def peak_rss_mb(time_v_report: str) -> float:
    """The maximum resident set size (MB) in ``/usr/bin/time -v``'s report, NaN when it has none."""
    line = next((ln for ln in time_v_report.splitlines() if "Maximum resident set size" in ln), None)
    return int(line.split(":")[1]) / 1024.0 if line else float("nan")


def without_time_report(stderr: str) -> str:
    """A child's standard error without the report ``/usr/bin/time -v`` appends to it (which would bury the
    child's own last line, its error)."""
    cuts = [i for i in (stderr.find("Command exited with non-zero status"), stderr.find("\tCommand being timed:"))
            if i >= 0]
    return stderr[:min(cuts)].rstrip("\n") if cuts else stderr


def child_env(extra: dict | None = None) -> dict:
    """The environment of a child: this one with the project on ``PYTHONPATH``."""
    path = os.pathsep.join(p for p in (ROOT, os.environ.get("PYTHONPATH", "")) if p)
    return {**os.environ, "PYTHONPATH": path, **(extra or {})}


def print_row(row: dict) -> None:
    """A child's result: its row as one JSON line, the last line of its standard output (:func:`run_child`)."""
    print(json.dumps(row), flush=True)


def run_child(args: list[str], label: str, row: bool = True, env: dict | None = None) -> dict:
    """Run ``python args`` (a script and its options, or ``-c CODE ...``, or ``-m MODULE ...``) in a child process:
    one configuration, so that its peak memory is its own. Returns the JSON row the child printed last (``row``;
    otherwise an empty one) with ``peak_mb`` (the child's maximum resident set, from ``wait4``: what
    ``/usr/bin/time -v`` reports, without needing it), ``wall_s`` and ``load`` (the 5-minute load average after it)
    added. A child that fails raises ``RuntimeError`` whose last line is the child's own last line of error."""
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env=env or child_env(), cwd=ROOT)
    streams: dict[str, str] = {}
    readers = [threading.Thread(target=lambda k=k, f=f: streams.__setitem__(k, f.read()))
               for k, f in (("out", p.stdout), ("err", p.stderr))]
    for t in readers:
        t.start()
    for t in readers:
        t.join()
    p.stdout.close()
    p.stderr.close()
    _, status, usage = os.wait4(p.pid, 0)  # this child's own resource usage (Popen.wait would not give it)
    p.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t0
    if p.returncode != 0:  # the child's error last, so that callers can show the last line
        raise RuntimeError(f"{label} failed:\n{streams['err'].rstrip(chr(10))[-2000:]}")
    out = json.loads(streams["out"].strip().splitlines()[-1]) if row else {}
    out["peak_mb"] = usage.ru_maxrss / 1024.0  # kB on Linux
    out["wall_s"] = wall
    out["load"] = load_average()[1]
    return out


# -- raw results and report sections -------------------------------------------------------------------------------
def results_path(name: str) -> str:
    """``benchmarks/results/NAME`` (the folder is made if missing): where a run's raw results go."""
    os.makedirs(RESULTS, exist_ok=True)
    return os.path.join(RESULTS, name)


def results_ref(name: str) -> str:
    """How a report names a raw result: its path from the repository's root (the file is not committed)."""
    return os.path.relpath(os.path.join(RESULTS, name), ROOT)


def write_csv(rows: list[dict], name: str) -> str:
    """``rows`` as ``benchmarks/results/NAME`` (written atomically; columns: every key, in order of appearance)."""
    from data_schema.atomic import atomic_path

    path = results_path(name)
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(dict.fromkeys(k for r in rows for k in r)), restval="")
            w.writeheader()
            w.writerows(rows)
    return path


def write_json(obj, name: str) -> str:
    """``obj`` as ``benchmarks/results/NAME`` (indented JSON, written atomically)."""
    from data_schema.atomic import write_text

    path = results_path(name)
    write_text(path, json.dumps(obj, indent=1, default=str) + "\n")
    return path


def replace_section(path: str, name: str, lines: list[str]) -> None:
    """Write ``lines`` as the section ``name`` of the Markdown file ``path`` (appended if new), between
    ``<!-- NAME:start -->`` and ``<!-- NAME:end -->``; the other sections are kept."""
    from data_schema.atomic import write_text

    start, end = f"<!-- {name}:start -->", f"<!-- {name}:end -->"
    block = "\n".join([start, *lines, end]) + "\n"
    old = open(path, encoding="utf-8").read() if os.path.exists(path) else "# Benchmarks\n\n"
    if start in old:
        head, rest = old.split(start, 1)
        tail = rest.split(end, 1)[1].lstrip("\n")
        new = head + block + ("\n" + tail if tail else "")
    else:
        new = old.rstrip("\n") + "\n\n" + block
    write_text(path, new)


# -- the GPU backend's configurations (bench_gpu*.py) --------------------------------------------------------------
#: What figures measured on llvmpipe say, and the `load` column (the GPU benchmarks' sections).
LLVMPIPE_NOTE = (
    "Mesa's llvmpipe is a software OpenGL 4.5 implementation on the CPU cores, not a GPU: these figures say that the "
    "GPU backend runs and what it costs there, not how fast it is on a graphics card; the same script runs "
    "unchanged on a machine with a GPU (headless, EGL) and writes the same table. `load`: the machine's 5-minute "
    "load average after the configuration (other jobs share the cores; above the core count, times are inflated).")
#: A configuration whose first full-size frame takes longer than this is measured once (:func:`timed_frames`).
ONCE_SECONDS = 60.0


def gpu_device_line() -> str:
    """One line naming the OpenGL device the GPU backend runs on."""
    from renderers.gpu.context import get_device

    d = get_device()
    return f"GPU backend: {d.renderer}, OpenGL {d.version} ({d.source})."


def timed_frames(backend: str, scene: str, name: str, params: dict, size: str, repeats: int) -> list[dict]:
    """The stats of the timed frames of one configuration in this process: a small untimed warm-up frame (shader
    compilation, scene upload or BVH build, numba caches), then frames at ``size``; the first full-size frame also
    allocates the frame buffers, so the timed frames are the ``repeats`` after it (or that frame alone if it took
    longer than :data:`ONCE_SECONDS`)."""
    from renderers import registry

    W, H = (int(x) for x in size.split("x"))
    registry.render(scene, name, params, 64, 48, backend=backend)
    _, st = registry.render(scene, name, params, W, H, backend=backend)
    if st["seconds"]["total"] >= ONCE_SECONDS:
        return [st]
    return [registry.render(scene, name, params, W, H, backend=backend)[1] for _ in range(repeats)]
