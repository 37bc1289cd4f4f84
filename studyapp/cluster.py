"""Offline rendering on Dask distributed: the one module that imports dask (lazily).

Who renders (:class:`ClusterSpec`, the options of :func:`add_arguments`):

- by default a ``LocalCluster`` of one single-threaded worker process per core, started and stopped by the
  command (``--workers N`` sizes it: a whole number up to the cores, more with ``--workers-over-cores``, and
  never more workers than tasks; each worker's numba kernels get ``cores // N`` threads);
- ``--scheduler tcp://HOST:PORT`` (or the environment variable ``DASK_SCHEDULER_ADDRESS``; set but empty means
  unset, as for Dask): a running scheduler and its workers, on this machine or a lab's (docs/distributed.md);
- ``--workers 1`` or ``--serial``: in this process, no Dask at all.

Every option and address is checked by :func:`from_args` before anything runs, without importing Dask
(:func:`check_address`); Dask's own configuration (``DASK_CONFIG``) is read when Dask is imported, and a file
it refuses is one line too (:func:`_distributed`).

What runs: :func:`run_tasks` submits one task per unit of work (a frame), drives the progress bar and the time
left from the futures as they complete (``as_completed``), and turns a failing task into one line naming it
(``condition X, scene Y, frame N: <the worker's error>``, exit status 2). A worker that dies mid-task is
replaced by the scheduler: its task runs again elsewhere (``distributed.scheduler.allowed-failures`` times).
:func:`render_frames` is the stimulus-cache front end used by ``prepare`` and ``lightcuts tables``: the
client computes each frame's cache key (:func:`renderers.stimuli.frame_request`), submits only frames not yet
in the cache (content-addressed, so reruns resume and identical frames render once), a worker renders one
frame through :func:`renderers.stimuli.render_entry` (the scene from its per-process catalogue) and returns the
entry's content, and the client writes it atomically (:func:`renderers.stimuli.write_entry`; workers need not
share the client's file system). Results are byte-identical to an in-process run.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import functools
import ipaddress
import os
import re
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from data_schema.errors import UserError, first_line

#: The environment variable naming a running scheduler (Dask's own name for it).
ENV_SCHEDULER = "DASK_SCHEDULER_ADDRESS"
#: Seconds to wait for a scheduler to answer before giving up in one line.
CONNECT_TIMEOUT_S = 5.0
#: Local workers allowed with ``--workers-over-cores`` (each is a process of ~90 MB).
WORKERS_MAX = 1024
#: Address schemes of Dask's comms that reach another process (``inproc://`` does not).
SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")
#: A DNS label: letters, digits, hyphens (underscores too: some lab hosts have them), 1-63 characters.
_LABEL = re.compile(r"[A-Za-z0-9_](?:[A-Za-z0-9_-]{0,61}[A-Za-z0-9_])?", re.ASCII)


@dataclass(frozen=True)
class ClusterSpec:
    """Where tasks run: a running scheduler, a local cluster of ``workers`` processes, or this process."""

    scheduler: str | None = None
    workers: int | None = None
    serial: bool = False

    @property
    def local_workers(self) -> int:
        return self.workers or os.cpu_count() or 1

    @property
    def in_process(self) -> bool:
        return self.scheduler is None and (self.serial or self.local_workers == 1)

    def describe(self) -> str:
        if self.scheduler:
            return f"the Dask scheduler {self.scheduler}"
        if self.in_process:
            return "this process"
        return f"a local cluster of {self.local_workers} workers"


SERIAL = ClusterSpec(serial=True)


def add_arguments(parser) -> None:
    """The cluster options of a command: ``--scheduler``, ``--workers``, ``--workers-over-cores``, ``--serial``."""
    g = parser.add_argument_group("cluster (docs/distributed.md)")
    g.add_argument("--scheduler", metavar="ADDR",
                   help=f"a running Dask scheduler, e.g. tcp://HOST:8786 (default: ${ENV_SCHEDULER}, else a local "
                        "cluster started for this command)")
    g.add_argument("--workers", type=_whole_number, metavar="N",
                   help="worker processes of the local cluster, at most one per core and per frame (default: one "
                        "per core; 1 renders in this process)")
    g.add_argument("--workers-over-cores", action="store_true",
                   help=f"allow --workers above this machine's cores (up to {WORKERS_MAX})")
    g.add_argument("--serial", action="store_true", help="render in this process, without Dask")


def _whole_number(text: str) -> int:
    """``--workers``' argparse type: digits only (``1e3`` would be read as 1000 by a float parser)."""
    import argparse

    if not re.fullmatch(r"\s*[+-]?[0-9]{1,9}\s*", text, re.ASCII):
        if re.fullmatch(r"\s*[+-]?[0-9]+\s*", text, re.ASCII):  # too many digits to be a count of processes
            raise argparse.ArgumentTypeError(f"--workers={text.strip()} is out of range: allowed [1, "
                                             f"{os.cpu_count() or 1}], this machine's cores")
        raise argparse.ArgumentTypeError(f"--workers={text!r} is invalid: must be a whole number in digits")
    return int(text)


def check_workers(n: int, over_cores: bool = False, cores: int | None = None) -> int:
    """``n`` local workers, or the one-line refusal: 1 up to ``cores`` (this machine's), up to
    :data:`WORKERS_MAX` with ``over_cores``."""
    from data_schema.ranges import Range

    cores = cores or os.cpu_count() or 1
    if over_cores:
        return Range(1, WORKERS_MAX, integer=True).check("--workers", n)
    try:
        return Range(1, cores, integer=True).check("--workers", n)
    except UserError as exc:
        if n < 1:
            raise
        raise UserError(f"{exc} (this machine's {cores} cores: add --workers-over-cores for more)") from None


def check_address(address: str, where: str) -> str:
    """``address`` if it is a Dask scheduler address another process can reach, else the one-line refusal
    naming ``where`` it came from (``--scheduler ADDR``): a known scheme, a host (a DNS name of labels of 1-63
    characters and 253 in all, an IPv4 address, or an IPv6 address in brackets), a port 1-65535. Dask is not
    imported; nothing is resolved or connected."""
    def refuse(why: str) -> UserError:
        return UserError(f"{where} is not a scheduler address: {why}; give tcp://HOST:PORT, e.g. "
                         "tcp://192.168.1.10:8786")

    if not address.strip():
        raise refuse("it is empty (leave the option out for a local cluster)")
    if any(c.isspace() or not c.isprintable() for c in address):
        raise refuse("it holds spaces or control characters")
    scheme, sep, loc = address.partition("://")
    if not sep:
        raise refuse("no scheme")
    if scheme not in SCHEMES:
        raise refuse(f"unknown scheme {_shown(scheme, 40)}: known {', '.join(SCHEMES)}")
    host, sep, port = loc.rpartition(":")
    if not sep or not port:
        raise refuse("no port: a scheduler listens on 8786 unless told otherwise")
    if not re.fullmatch(r"[0-9]{1,5}", port, re.ASCII) or not 1 <= int(port) <= 65535:
        raise refuse(f"port {_shown(port, 40)} is not a whole number in [1, 65535]")
    if host.startswith("[") and host.endswith("]"):
        try:
            ipaddress.IPv6Address(host[1:-1])
        except ValueError:
            raise refuse(f"{_shown(host, 100)[1:-1]} is not an IPv6 address") from None
        return address
    if ":" in host or "[" in host or "]" in host:
        raise refuse("an IPv6 address needs brackets, e.g. tcp://[::1]:8786")
    if not host:
        raise refuse("no host")
    if re.fullmatch(r"[0-9.]+", host, re.ASCII):
        try:
            ipaddress.IPv4Address(host)
        except ValueError:
            raise refuse(f"{_shown(host, 100)[1:-1]} is not an IPv4 address") from None
        return address
    try:
        name = host.encode("idna").decode("ascii")  # a unicode name as DNS sees it (each label <= 63 bytes)
    except UnicodeError as exc:  # Python's codec says "label too long" or "label empty or too long"
        why = str(exc).rpartition("UnicodeError: ")[2].rstrip(")") or "not IDNA"
        raise refuse(f"the host name {_shown(host, 100)} is not a domain name ({why}; labels of 1-63 "
                     "characters)") from None
    labels = name[:-1].split(".") if name.endswith(".") else name.split(".")
    if len(name) > 253 or not all(_LABEL.fullmatch(lb) for lb in labels):
        raise refuse(f"the host name {_shown(host, 100)} is not labels of 1-63 letters, digits and hyphens, 253 "
                     "characters in all")
    return address


def _shown(text: str, most: int = 300) -> str:
    """``text`` quoted for a one-line error, cut to ``most`` characters (an address may be any argument)."""
    shown = repr(text)
    return shown if len(shown) <= most else shown[: most - 4] + "...'"


def from_args(args) -> ClusterSpec:
    """The :class:`ClusterSpec` of parsed :func:`add_arguments` options (and ``$DASK_SCHEDULER_ADDRESS``)."""
    scheduler = getattr(args, "scheduler", None)
    workers = getattr(args, "workers", None)
    serial = bool(getattr(args, "serial", False))
    if serial and scheduler is not None:
        raise UserError("--serial and --scheduler exclude each other: choose one")
    if scheduler is not None and workers:
        raise UserError("--workers sizes the local cluster: the workers of --scheduler are started with "
                        "`dask worker` (docs/distributed.md)")
    if scheduler is not None:
        check_address(scheduler, f"--scheduler {_shown(scheduler)}")
    elif not serial and not workers:
        # Set but empty means unset, as Dask reads it (and as `DASK_SCHEDULER_ADDRESS= studyapp ...` intends).
        scheduler = os.environ.get(ENV_SCHEDULER) or None
        if scheduler is not None:
            check_address(scheduler, f"{ENV_SCHEDULER}={_shown(scheduler)}")
    if workers is not None:
        workers = check_workers(workers, bool(getattr(args, "workers_over_cores", False)))
    return ClusterSpec(scheduler=scheduler, workers=workers, serial=serial)


@contextlib.contextmanager
def connect(spec: ClusterSpec) -> Iterator:
    """A Dask ``Client`` for ``spec`` (None in process); a local cluster is stopped on exit."""
    if spec.in_process:
        yield None
        return
    distributed = _distributed()
    Client, LocalCluster = distributed.Client, distributed.LocalCluster  # noqa: N806 - classes
    import logging

    if spec.scheduler:
        client = _client(Client, spec.scheduler)
        try:
            yield client
        finally:
            client.close()
        return
    n = spec.local_workers
    threads = str(max(1, (os.cpu_count() or 1) // n))
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                           silence_logs=logging.ERROR, env={"NUMBA_NUM_THREADS": threads})
    try:
        client = Client(cluster, set_as_default=False)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()


def _distributed():
    """The ``distributed`` module, or one line saying why not: not installed, or Dask refused its configuration
    (read at import: ``DASK_CONFIG``, ``~/.config/dask``, ``/etc/dask``; e.g. ``DASK_CONFIG=/etc/passwd``)."""
    try:
        import distributed
    except ImportError as exc:
        raise UserError(f"Dask distributed is not installed here ({exc}): pip install 'dask[distributed]', or "
                        "render in this process with --serial") from None
    except Exception as exc:  # noqa: BLE001 - Dask's config files are the user's input: one line
        where = (f"DASK_CONFIG={os.environ['DASK_CONFIG']}" if "DASK_CONFIG" in os.environ else
                 "Dask's configuration (~/.config/dask, /etc/dask)")
        raise UserError(f"{where}: Dask cannot read its configuration ({first_line(exc).rstrip(':, ')}): fix or "
                        "unset it, or render in this process with --serial") from None
    return distributed


def _client(client_class, address: str):
    """A ``Client`` of the scheduler at ``address``, or one line (within ``CONNECT_TIMEOUT_S``) saying why not."""
    import gc
    import socket
    import sys
    import threading

    from distributed.comm.addressing import parse_address, parse_host_port

    where = f"--scheduler {address}" if os.environ.get(ENV_SCHEDULER) != address else \
        f"{ENV_SCHEDULER}={address}"
    hint = "start one with `dask scheduler` (docs/distributed.md), or drop --scheduler to use a local cluster"
    try:
        scheme, loc = parse_address(address, strict=True)
        host, port = parse_host_port(loc)
    except (ValueError, TypeError) as exc:
        raise UserError(f"{where}: not a scheduler address ({first_line(exc)}): give tcp://HOST:PORT") from None
    if scheme == "tcp":  # nothing listening: say so at once, not after Dask's retries
        try:
            socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S).close()
        except (OSError, UnicodeError) as exc:  # UnicodeError: a name the resolver cannot encode
            why = getattr(exc, "strerror", None) or first_line(exc)
            raise UserError(f"{where}: no Dask scheduler answers there ({why}): {hint}") from None
    # In a thread with a deadline: a service that accepts the connection but is no scheduler never answers.
    box: dict = {}

    def make():
        try:
            box["client"] = client_class(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
        except Exception as exc:  # noqa: BLE001 - reported below in one line
            box["reason"] = first_line(exc)

    thread = threading.Thread(target=make, name="studyapp-connect", daemon=True)
    thread.start()
    thread.join(2 * CONNECT_TIMEOUT_S)
    if "client" in box:
        return box["client"]
    reason = box.get("reason", f"no answer in {2 * CONNECT_TIMEOUT_S:g} s")
    hook = sys.unraisablehook
    try:  # the half-made Client complains from __del__: keep the error one line
        sys.unraisablehook = lambda *a: None
        gc.collect()
    finally:
        sys.unraisablehook = hook
    raise UserError(f"{where}: no Dask scheduler answers there ({reason}): {hint}")


def for_tasks(spec: ClusterSpec, n_tasks: int) -> ClusterSpec:
    """``spec`` for ``n_tasks`` tasks: a local cluster of no more workers than tasks (an idle worker is a
    process started for nothing; one task renders in this process)."""
    if spec.scheduler or spec.in_process or spec.local_workers <= n_tasks:
        return spec
    return ClusterSpec(workers=max(1, n_tasks))


def task_error(label: str, exc: BaseException) -> UserError:
    """One line naming the task and the worker's error (its first line)."""
    name = type(exc).__name__
    if name == "KilledWorker":
        why = "every worker that ran it died (distributed.scheduler.allowed-failures reached; out of memory?)"
    elif isinstance(exc, UserError):
        why = first_line(exc)
    else:
        why = f"{name}: {first_line(exc)}"
    return UserError(f"{label}: {why}")


@dataclass(frozen=True)
class Ref:
    """An argument of a task that is the result of an earlier task (named ``name``)."""

    name: str


@dataclass(frozen=True)
class Task:
    """One unit of work: ``fn(*args)`` on a worker. ``name`` is its Dask key (unique; content-addressed where
    possible, so that equal work is shared); ``label`` names it in errors (``condition X, scene Y, frame N``).
    ``fetch=False``: the result stays on the cluster for the tasks that take it (a full image), the client only
    counts it."""

    name: str
    label: str
    fn: Callable
    args: tuple = ()
    fetch: bool = True


def run_tasks(tasks: list[Task], spec: ClusterSpec, on_result: Callable[[Task, object], None] | None = None,
              progress: Callable[[int, int, float], None] | None = None, client=None) -> float:
    """Run ``tasks`` (dependencies before dependents) on ``spec``; ``on_result(task, result)`` runs on the client
    as each completes (in completion order), then ``progress(done, total, seconds_left)``; the time left is the
    tasks left times the wall time per completed task so far. A failing task cancels the rest and raises one
    line (:func:`task_error`); results handed to ``on_result`` before it stay. Returns the wall seconds."""
    t0 = time.perf_counter()
    if not tasks:
        return 0.0
    if client is None and not spec.in_process:
        spec = for_tasks(spec, len(tasks))
    if client is None and not spec.in_process:
        with connect(spec) as c:
            return run_tasks(tasks, spec, on_result, progress, client=c)
    total = len(tasks)

    def report(done):
        if progress:
            progress(done, total, (total - done) * (time.perf_counter() - t0) / done)

    if client is None:
        last_use = {a.name: i for i, t in enumerate(tasks) for a in t.args if isinstance(a, Ref)}
        results: dict[str, object] = {}
        for i, t in enumerate(tasks):
            try:
                res = t.fn(*(results[a.name] if isinstance(a, Ref) else a for a in t.args))
            except Exception as exc:
                raise task_error(t.label, exc) from exc
            if t.name in last_use:
                results[t.name] = res
            for a in t.args:
                if isinstance(a, Ref) and last_use[a.name] == i:
                    del results[a.name]
            if on_result and t.fetch:
                on_result(t, res)
            del res
            report(i + 1)
        return time.perf_counter() - t0

    from distributed import as_completed

    futures, by_key = {}, {}
    for t in tasks:
        args = tuple(futures[a.name] if isinstance(a, Ref) else a for a in t.args)
        futures[t.name] = client.submit(t.fn, *args, key=t.name, pure=False)
        by_key[futures[t.name].key] = t
    pending = list(futures.values())
    done = 0
    gone = (f"cancelled: the Dask scheduler {spec.scheduler or '(local)'} went away; run the command again to "
            "continue (frames done are kept)")
    try:
        for batch in as_completed(pending, loop=client.loop).batches():
            wanted = []
            for fut in batch:
                task = by_key[fut.key]
                if task.name not in futures:  # handed over already
                    continue
                if fut.status == "error":
                    raise task_error(task.label, fut.exception())
                if task.fetch:
                    wanted.append((task, fut))
                    continue
                futures.pop(task.name).release()  # its dependents hold it on the cluster
                done += 1
                report(done)
            if not wanted:
                continue
            try:  # the batch's results in one round trip (one lost with a dying worker is computed again)
                results = client.gather([f for _, f in wanted])
            except (concurrent.futures.CancelledError, asyncio.CancelledError):
                raise UserError(f"{wanted[0][0].label}: {gone}") from None
            except Exception as exc:  # noqa: BLE001 - the worker's error, one line
                task = next((t for t, f in wanted if f.status == "error"), wanted[0][0])
                raise task_error(task.label, exc) from None
            for (task, fut), res in zip(wanted, results):
                fut.release()  # the worker may drop the result once no dependent needs it
                futures.pop(task.name, None)
                if on_result:
                    on_result(task, res)
                done += 1
                report(done)
            del results, res
    finally:
        if futures:
            client.cancel(list(futures.values()))
    return time.perf_counter() - t0


def render_frames(frames: list[tuple[str, dict]], cache_dir, spec: ClusterSpec,
                  on_frame: Callable[[int, Path], None] | None = None,
                  progress: Callable[[int, int, float], None] | None = None, render=None) -> dict:
    """Bring every frame into the stimulus cache ``cache_dir``; ``on_frame(index, png)`` runs on the client as
    frame ``frames[index]`` is there. A frame is ``(label, kwargs of renderers.stimuli.render_stimulus)``.

    In process each frame goes through ``render`` (default :func:`renderers.stimuli.render_stimulus`, which
    looks the frame up first). On a cluster the client computes every key first, hands frames already cached to
    ``on_frame`` at once and submits one task per missing key (a key shared by several frames renders once).
    Temporary files that a killed run left in the cache are removed first. Returns ``{"rendered": tasks run,
    "cached": frames found in the cache, "removed": temporary files removed, "seconds": wall time}``.
    """
    from renderers import stimuli

    t0 = time.perf_counter()
    removed = stimuli.remove_stale_cache_temporaries(cache_dir)
    if spec.in_process:
        render = render or stimuli.render_stimulus
        tasks = [Task(f"frame-{i}", label, functools.partial(render, **kw, cache_dir=cache_dir))
                 for i, (label, kw) in enumerate(frames)]
        index = {t.name: i for i, t in enumerate(tasks)}
        run_tasks(tasks, spec, (lambda t, png: on_frame(index[t.name], png)) if on_frame else None, progress)
        return {"rendered": len(tasks), "cached": 0, "removed": removed, "seconds": time.perf_counter() - t0}
    if render is not None:
        raise ValueError("a custom render function runs in process only (spec.serial)")
    todo: dict[str, list[int]] = {}
    requests = {}
    cached = 0
    for i, (label, kw) in enumerate(frames):
        try:
            req = stimuli.frame_request(**kw)
        except ValueError as exc:
            raise task_error(label, exc) from None
        if not isinstance(req.scene, str):
            raise TypeError(f"{label}: a task carries a scene's name or file, not a Scene object")
        png = stimuli.cached_entry(cache_dir, req.key, (req.height, req.width, 3))  # checked; a bad one re-renders
        if png is not None:
            cached += 1
            if on_frame:
                on_frame(i, png)
            continue
        requests.setdefault(req.key, (label, req))
        todo.setdefault(req.key, []).append(i)
    tasks = [Task(f"stimulus-{key}", label, stimuli.render_entry, (req,)) for key, (label, req) in requests.items()]

    def written(task, entry):
        if entry.key != task.name[len("stimulus-"):]:
            raise UserError(f"{task.label}: a worker returned the entry {entry.key[:12]} for another frame")
        png = stimuli.write_entry(cache_dir, entry)
        for i in todo[entry.key]:
            if on_frame:
                on_frame(i, png)

    def counted(done, total, left):
        if progress:
            progress(cached + done, cached + total, left)

    if cached and progress:
        progress(cached, cached + len(tasks), float("nan"))
    run_tasks(tasks, spec, written, counted)
    return {"rendered": len(tasks), "cached": cached, "removed": removed, "seconds": time.perf_counter() - t0}
