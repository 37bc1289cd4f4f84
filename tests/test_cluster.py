"""Offline rendering on Dask distributed (issue 15): a real cluster on loopback.

The fixture starts ``dask scheduler`` and two ``dask worker`` processes (one thread each, no nanny, so a
SIGKILLed worker stays dead) on free ports of 127.0.0.1, with ``PYTHONPATH`` = this repository so the workers
import this code, and kills them in teardown (also when a test fails); the scheduler exits by itself after two
idle minutes and the workers when it is gone, should teardown never run. A tiny protocol (cornell at 32x18,
gt, lafr and sl_gt with 256 + 256 samples, three frames each) is prepared on it; sl_gt's frames take about half
a second, which leaves time to kill a worker mid-task (VaFR's take three seconds at any size: too slow here).
"""

from __future__ import annotations

import json
import pickle
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from studyapp import cluster
from studyapp.runner.protocol import load_protocol
from studyapp.runner.stimuli import frame_paths, prepare

ROOT = Path(__file__).resolve().parents[1]
DASK = Path(sys.executable).with_name("dask")

TINY = """
schema_version: 1
name: tiny_cluster
version: "1"
family: 2afc
question: "Which one?"
display: {width_px: 64, height_px: 36, width_cm: 53.0, distance_cm: 40.95, fov_y_deg: 40}
scenes: [cornell]
conditions:
  GT: {renderer: gt}
  SL: {renderer: sl_gt, params: {lspp: 256, rspp: 256}}
  LaFR: {renderer: lafr, params: {delta: 4.0}}
stimulus:
  kind: sequence
  render_px: [32, 18]
  duration_s: 1.5
  fps: 2
  camera_path: [{t: 0, yaw_deg: -2}, {t: 1, yaw_deg: 2}]
design: {repetitions: 1}
simulation: {ground_truth: GT}
analysis: {dv: chosen, unit: participant, test: thurstone}
full:
  render_px: [48, 27]
  conditions:
    LaFR: {params: {delta: 2.0}}
"""


def _env():
    return {**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_NUM_THREADS": "1"}


def _files(folder: Path) -> dict[str, bytes]:
    """Every file below ``folder`` (relative name -> bytes), the stats JSON of cache entries excepted (it holds
    timings)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.suffix != ".json"}


@pytest.fixture
def tiny(tmp_path):
    f = tmp_path / "tiny.yaml"
    f.write_text(TINY)
    return f


@pytest.fixture(scope="module")
def serial_result(tmp_path_factory):
    """The stimulus set and cache of an in-process (serial) prepare of the tiny protocol."""
    d = tmp_path_factory.mktemp("serial")
    (d / "tiny.yaml").write_text(TINY)
    p = load_protocol(d / "tiny.yaml", stimuli_dir=d / "stim")
    res = prepare(p, cache_dir=d / "cache", cluster=cluster.SERIAL)
    assert res["rendered"] == 9
    return _files(d / "stim"), _files(d / "cache")


class LoopbackCluster:
    """``dask scheduler`` and ``dask worker`` processes on 127.0.0.1, each its own process group."""

    def __init__(self, folder: Path):
        self.folder, self.procs, self.workers = folder, [], {}
        self.file = folder / "scheduler.json"
        self.procs.append(self._start([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0",
                                       "--no-dashboard", "--scheduler-file", str(self.file),
                                       "--idle-timeout", "120"], "scheduler"))
        deadline = time.monotonic() + 30
        while not self.file.is_file() or not self.file.read_text().strip():
            assert time.monotonic() < deadline, "the scheduler did not start: " + self._log("scheduler")
            assert self.procs[0].poll() is None, "the scheduler exited: " + self._log("scheduler")
            time.sleep(0.1)
        self.address = json.loads(self.file.read_text())["address"]
        for name in ("w1", "w2"):
            self.workers[name] = self._start([str(DASK), "worker", self.address, "--nthreads", "1", "--no-nanny",
                                              "--no-dashboard", "--name", name, "--host", "127.0.0.1",
                                              "--death-timeout", "20", "--memory-limit", "0"], name)
            self.procs.append(self.workers[name])
        from distributed import Client

        self.client = Client(self.address, timeout=20, set_as_default=False)
        self.client.wait_for_workers(2, timeout=60)

    def _start(self, cmd, name):
        with open(self.folder / f"{name}.log", "w") as log:  # the child keeps its own copy of the handle
            return subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=_env(), cwd=self.folder,
                                    start_new_session=True)

    def _log(self, name):
        return (self.folder / f"{name}.log").read_text()[-2000:]

    def wait_idle(self, timeout: float = 60) -> None:
        """Until no worker is running a task: a task whose client died still runs to its end (a thread cannot be
        stopped) and writes its frame to the cache."""
        deadline = time.monotonic() + timeout
        while any(self.client.run(lambda dask_worker: len(dask_worker.state.executing)).values()):
            assert time.monotonic() < deadline, "a worker is still busy"
            time.sleep(0.05)

    def pid_of(self, address: str) -> int:
        return self.workers[self.client.scheduler_info()["workers"][address]["name"]].pid

    def close(self):
        try:
            self.client.close(timeout=10)
        finally:
            for p in self.procs:
                if p.poll() is None:
                    p.kill()
            for p in self.procs:
                p.wait(timeout=30)


@pytest.fixture(scope="module")
def loopback(tmp_path_factory):
    c = LoopbackCluster(tmp_path_factory.mktemp("cluster"))
    try:
        yield c
    finally:
        c.close()
        assert all(p.poll() is not None for p in c.procs)  # no process left behind


def _cli(argv, cwd):
    return subprocess.run([sys.executable, "-m", "studyapp", *argv], cwd=cwd, env=_env(), capture_output=True,
                          text=True, timeout=300, check=False)


# -- options ---------------------------------------------------------------------------------------------------
def test_cluster_options_choose_where_frames_render(monkeypatch):
    import argparse

    p = argparse.ArgumentParser()
    cluster.add_arguments(p)
    monkeypatch.delenv(cluster.ENV_SCHEDULER, raising=False)
    assert cluster.from_args(p.parse_args([])) == cluster.ClusterSpec()
    assert not cluster.ClusterSpec(workers=2).in_process
    assert cluster.from_args(p.parse_args(["--workers", "1"])).in_process
    assert cluster.from_args(p.parse_args(["--serial"])).in_process
    monkeypatch.setenv(cluster.ENV_SCHEDULER, "tcp://10.0.0.1:8786")
    assert cluster.from_args(p.parse_args([])).scheduler == "tcp://10.0.0.1:8786"
    assert cluster.from_args(p.parse_args(["--serial"])).in_process  # an explicit choice wins over the env
    with pytest.raises(ValueError, match="--serial and --scheduler exclude each other"):
        cluster.from_args(p.parse_args(["--serial", "--scheduler", "tcp://a:1"]))


def test_scheduler_pointing_at_nothing_is_one_line_exit_2(tiny, tmp_path):
    t0 = time.monotonic()
    r = _cli(["prepare", str(tiny), "--scheduler", "tcp://127.0.0.1:1"], tmp_path)
    assert r.returncode == 2, r.stderr
    assert r.stderr.splitlines() == [r.stderr.strip()]
    assert r.stderr.startswith("studyapp: error: --scheduler tcp://127.0.0.1:1: no Dask scheduler answers there")
    assert time.monotonic() - t0 < 20  # imports and the protocol's checks included; the refusal itself is instant
    assert not (tmp_path / "stimuli").exists()


def test_full_size_variant_is_data_in_the_protocol_and_needs_a_cluster(tiny, tmp_path, capsys):
    from studyapp.commands.study import main

    p, full = load_protocol(tiny), load_protocol(tiny, full=True)
    assert (p.render_size, full.render_size) == ((32, 18), (48, 27))
    assert full.conditions["LaFR"].params == {"delta": 2.0} and full.conditions["SL"].params == {"lspp": 256,
                                                                                                 "rspp": 256}
    assert full.stimuli_dir == p.stimuli_dir / "full" and full.content_hash != p.content_hash
    assert full.render_geometry().fov_y_deg == pytest.approx(p.render_geometry().fov_y_deg)
    assert main(["prepare", str(tiny), "--full"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("studyapp: error: --full renders tiny_cluster at 48x27 ") and "--scheduler" in err
    assert not full.stimuli_dir.exists()
    bad = tmp_path / "bad.yaml"
    bad.write_text(TINY.replace("LaFR: {params: {delta: 2.0}}", "LaFR: {params: {delta: 99}}"))
    with pytest.raises(ValueError, match=r"bad\.yaml:\d+: full\.conditions\.LaFR\.params: .*delta"):
        load_protocol(bad, full=True)
    bad.write_text(TINY.replace("render_px: [48, 27]", "render_px: [48, 48]"))
    with pytest.raises(ValueError, match=r"full\.render_px: 48x48 has not the display's aspect ratio"):
        load_protocol(bad, full=True)


def test_a_failing_frame_in_process_names_it_and_keeps_the_frames_done(tiny, tmp_path, monkeypatch, capsys):
    from renderers import registry
    from studyapp.commands.study import main

    real = registry.render

    def flaky(scene, renderer, params, *a, camera=None, **kw):
        if renderer == "lafr" and "previous" in (camera or {}):
            raise RuntimeError("the plug-in fell over\nsecond line")
        return real(scene, renderer, params, *a, camera=camera, **kw)

    monkeypatch.setattr(registry, "render", flaky)
    cache = tmp_path / "cache"
    assert main(["prepare", str(tiny), "--serial", "--cache", str(cache)]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]  # after the progress lines
    assert err == "studyapp: error: condition LaFR, scene cornell, frame 1: RuntimeError: the plug-in fell over"
    p = load_protocol(tiny)
    assert frame_paths(p, "LaFR", "cornell")[0].is_file() and not frame_paths(p, "LaFR", "cornell")[1].is_file()
    assert len(list(cache.rglob("*.png"))) == 7  # GT's and SL's frames and LaFR's first stay in the cache


# -- a real cluster --------------------------------------------------------------------------------------------
def test_a_failing_frame_on_a_worker_is_one_line_and_a_rerun_completes(tiny, tmp_path, loopback, monkeypatch,
                                                                       capsys, serial_result):
    """The worker's renderer refuses frames 1 and 2 of LaFR (their requests are corrupted on the client, after the
    client's checks): one line naming the frame and the worker's error, exit 2; a rerun renders only what is
    missing and the set equals the serial one."""
    from renderers import stimuli
    from studyapp.commands.study import main

    real = stimuli.frame_request

    def corrupt(*a, **kw):
        req = real(*a, **kw)
        if req.renderer == "lafr" and "previous" in (req.camera or {}):
            from renderers.catalog import resolve

            params = {**req.params, "delta": -1.0}
            key = stimuli.stimulus_key(resolve(req.scene), req.renderer, params, req.width, req.height, req.gaze,
                                       req.camera)
            return stimuli.FrameRequest(**{**req.__dict__, "params": params, "key": key})
        return req

    monkeypatch.setattr(stimuli, "frame_request", corrupt)
    stim, cache = tmp_path / "stim", tmp_path / "cache"
    argv = ["prepare", str(tiny), "--scheduler", loopback.address, "--stimuli", str(stim), "--cache", str(cache)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert re.fullmatch(r"studyapp: error: condition LaFR, scene cornell, frame [12]: lafr\.delta=-1 is out of "
                        r"range: allowed \(1, 16\]", err), err
    done = _files(stim)
    kept = len(list(cache.rglob("*.png")))
    assert kept >= len(list(stim.rglob("*.png")))  # every frame copied into the stimulus folder is in the cache
    monkeypatch.undo()
    res = prepare(load_protocol(tiny, stimuli_dir=stim), cache_dir=cache,
                  cluster=cluster.ClusterSpec(scheduler=loopback.address))
    assert res["rendered"] == 9 - kept  # only what the failed run did not finish
    assert done.items() <= _files(stim).items()
    assert (_files(stim), _files(cache)) == serial_result
    # the full-size variant on the cluster: its own folder, size and parameters
    assert main([*argv, "--full"]) == 0
    full = load_protocol(tiny, stimuli_dir=stim, full=True)
    from PIL import Image

    with Image.open(frame_paths(full, "LaFR", "cornell")[1]) as im:
        assert im.size == (48, 27)
    stats = [json.loads(p.read_text()) for p in cache.rglob("*.json")]
    assert {s["params"]["delta"] for s in stats if s["renderer"] == "lafr"} == {4.0, 2.0}


def test_replay_of_a_live_trial_on_the_cluster_equals_the_serial_replay(tmp_path, loopback):
    from test_live import LIVE

    from studyapp.cli import main

    f = tmp_path / "live.yaml"
    f.write_text(LIVE)
    db = tmp_path / "s.db"
    assert main(["run", str(f), "--participant", "P1", "--simulate", "--db", str(db), "--quiet"]) == 0
    outs = {}
    for how in (["--serial"], ["--scheduler", loopback.address]):
        out = tmp_path / how[0]
        assert main(["replay", "--db", str(db), "--participant", "P1", "--trial", "0", "--out", str(out),
                     "--cache", str(tmp_path / f"cache{how[0]}"), *how]) == 0
        outs[how[0]] = out
    a, b = (_files(o) for o in outs.values())
    assert a.keys() == b.keys() and len([k for k in a if k.endswith(".png")]) >= 4
    assert {k: v for k, v in a.items() if k != "frames.csv"} == {k: v for k, v in b.items() if k != "frames.csv"}


def test_lightcuts_tables_render_their_ground_truths_on_the_cluster(tmp_path, loopback, monkeypatch):
    """The GT of each scene is a task; lightcut_tables then finds it in the cache (no render of its own)."""
    import argparse

    from renderers import registry
    from renderers.lightcuts.scenes import SCENES
    from renderers.lightcuts.tables import gt_frame
    from renderers.stimuli import render_stimulus
    from studyapp.commands.lightcuts import _ground_truths

    args = argparse.Namespace(width=32, height=18, gt_samples=16, seed=0, cache=str(tmp_path / "cache"),
                              scheduler=loopback.address, workers=None, serial=False, backend="cpu")
    _ground_truths(args, ["study", "yard"], 32, 18)
    assert len(list((tmp_path / "cache").rglob("*.png"))) == 2

    def boom(*a, **kw):
        raise AssertionError("rendered again")

    monkeypatch.setattr(registry, "render", boom)
    for name in ("study", "yard"):  # what lightcut_tables asks for, with the scene it builds
        render_stimulus(**gt_frame(SCENES[name](), 32, 18, gt_lspp=16, gt_rspp=16), cache_dir=tmp_path / "cache")


def test_workers_build_each_scene_once_and_tasks_carry_names(tiny, tmp_path, loopback):
    from renderers.catalog import builtin  # its cache, in each worker process: built-in scenes built there

    loopback.client.run(builtin.cache_clear)
    r = _cli(["prepare", str(tiny), "--scheduler", loopback.address, "--stimuli", str(tmp_path / "stim"),
              "--cache", str(tmp_path / "cache")], tmp_path)
    assert r.returncode == 0, r.stderr
    builds = loopback.client.run(builtin.cache_info)
    # one scene (cornell) and 9 frames over 2 workers: each worker built it at most once, and reused it
    assert all(info.misses <= 1 for info in builds.values()), builds
    assert sum(info.hits for info in builds.values()) >= 9 - 2, builds
    # a task's arguments are the frame's names and numbers, a few hundred bytes, never a mesh
    p = load_protocol(tiny, stimuli_dir=tmp_path / "s2", check_renderers=False)
    from renderers.stimuli import frame_request

    g = p.render_geometry()
    req = frame_request(p.scene_ref("cornell"), "gt", {}, g.width, g.height)
    assert isinstance(req.scene, str) and len(pickle.dumps(req)) < 2000


def test_a_killed_prepare_resumes_where_it_stopped(tiny, tmp_path, loopback, serial_result):
    """SIGKILL of the command itself once some frames are in the stimulus folder: running it again renders only
    the frames that had not reached the cache, and the set equals the serial one."""
    stim, cache = tmp_path / "stim", tmp_path / "cache"
    argv = [sys.executable, "-m", "studyapp", "prepare", str(tiny), "--scheduler", loopback.address, "--stimuli",
            str(stim), "--cache", str(cache)]
    proc = subprocess.Popen(argv, cwd=tmp_path, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < deadline and not list(stim.rglob("*.png")):
            time.sleep(0.01)
        proc.kill()
    finally:
        proc.wait()
    loopback.wait_idle()  # the frame a worker was rendering still reaches the cache, whole
    kept = len(list(cache.rglob("*.png")))
    assert 1 <= kept <= 9 and not list(stim.rglob(".*.tmp")) and not list(cache.rglob(".*.tmp"))
    res = prepare(load_protocol(tiny, stimuli_dir=stim), cache_dir=cache,
                  cluster=cluster.ClusterSpec(scheduler=loopback.address))
    assert res["rendered"] == 9 - kept
    assert (_files(stim), _files(cache)) == serial_result


def test_sigkill_of_a_worker_mid_task_and_the_set_is_byte_identical_to_serial(tiny, tmp_path, loopback,
                                                                               serial_result):
    """prepare runs as a CLI subprocess on the loopback cluster; once a frame is in the cache, the worker that
    is busy rendering another is killed with SIGKILL. The scheduler runs its task again on the other worker;
    the set completes and equals the serial run byte for byte (stimuli, cached PNGs and linear images)."""
    stim, cache = tmp_path / "stim", tmp_path / "cache"
    proc = subprocess.Popen([sys.executable, "-m", "studyapp", "prepare", str(tiny), "--scheduler",
                             loopback.address, "--stimuli", str(stim), "--cache", str(cache)],
                            cwd=tmp_path, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = None
    try:
        deadline = time.monotonic() + 120
        while killed is None and time.monotonic() < deadline and proc.poll() is None:
            busy = {w: keys for w, keys in loopback.client.processing().items() if keys}
            if busy and any(cache.rglob("*.png")):
                worker = min(busy)
                killed = (loopback.pid_of(worker), busy[worker])
                os.kill(killed[0], signal.SIGKILL)
            time.sleep(0.02)
        out, err = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert killed is not None, "no worker was busy after the first frame: nothing was killed"
    assert proc.returncode == 0, err
    assert "9 frame(s) built" in out and f"the Dask scheduler {loopback.address}" in out
    assert (_files(stim), _files(cache)) == serial_result
    dead = [p for p in loopback.workers.values() if p.pid == killed[0]]
    assert len(dead) == 1 and dead[0].wait(timeout=10) == -signal.SIGKILL
    assert len(loopback.client.scheduler_info()["workers"]) == 1  # the other worker finished the set


def test_local_cluster_by_default_started_and_stopped_by_the_command(tiny, tmp_path, serial_result):
    r = _cli(["prepare", str(tiny), "--workers", "2", "--stimuli", str(tmp_path / "stim"), "--cache",
              str(tmp_path / "cache")], tmp_path)
    assert r.returncode == 0, r.stderr
    assert "9 frame(s) built (9 rendered, 0 from the cache) on a local cluster of 2 workers" in r.stdout
    assert (_files(tmp_path / "stim"), _files(tmp_path / "cache")) == serial_result


def test_dask_is_imported_only_when_a_cluster_runs():
    code = ("import sys, studyapp.cli, studyapp.cluster, studyapp.runner.stimuli, renderers.stimuli; "
            "studyapp.cli.build_parser(); print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('dask', 'distributed')))")
    r = subprocess.run([sys.executable, "-c", code], env=_env(), capture_output=True, text=True, timeout=120,
                       check=False)
    assert r.stdout.strip() == "[]", r.stderr
