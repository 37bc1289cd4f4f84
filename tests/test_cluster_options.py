"""The cluster options refuse bad input in one line before any process starts (issue 25, items 9 and 10).

``--workers`` is a whole number in digits from 1 up to the machine's cores (more with ``--workers-over-cores``,
never more workers than tasks); ``--scheduler`` and ``DASK_SCHEDULER_ADDRESS`` are checked without Dask (an
empty variable means unset); a Dask configuration Dask refuses (``DASK_CONFIG``) is one line naming it. Every
refusal here is checked to start no process: ``fork``, ``Popen`` and ``multiprocessing`` are made to fail.
"""

from __future__ import annotations

import contextlib
import multiprocessing.process
import os
import subprocess
import sys
from pathlib import Path

import pytest

from studyapp import cluster
from studyapp.cli import main

ROOT = Path(__file__).resolve().parents[1]
TINY = (Path(__file__).with_name("test_cluster.py").read_text().split('TINY = """', 1)[1].split('"""', 1)[0])

#: Run in a child: the CLI with every way of starting a process replaced by an exit naming it.
NO_SPAWN = """
import multiprocessing.process, os, subprocess, sys
def spawned(*a, **k):
    raise SystemExit("a process was started")
os.fork = os.posix_spawn = subprocess.Popen.__init__ = multiprocessing.process.BaseProcess.start = spawned
from studyapp.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.fixture
def tiny(tmp_path):
    f = tmp_path / "tiny.yaml"
    f.write_text(TINY)
    return f


@pytest.fixture
def no_spawn(monkeypatch):
    """Starting a process (a worker, a scheduler, a fork) fails the test."""
    def spawned(*a, **k):
        raise AssertionError("a process was started")

    for obj, name in ((os, "fork"), (os, "posix_spawn"), (subprocess.Popen, "__init__"),
                      (multiprocessing.process.BaseProcess, "start")):
        monkeypatch.setattr(obj, name, spawned)
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    monkeypatch.delenv(cluster.ENV_SCHEDULER, raising=False)


def _refused(capsys, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("studyapp: error: "), err
    return err.strip()


@pytest.mark.parametrize(("value", "says"), [
    ("1e3", "--workers='1e3' is invalid: must be a whole number in digits"),
    ("2.5", "--workers='2.5' is invalid: must be a whole number in digits"),
    ("nan", "--workers='nan' is invalid: must be a whole number in digits"),
    ("inf", "--workers='inf' is invalid: must be a whole number in digits"),
    ("\uff12", "--workers='\uff12' is invalid: must be a whole number in digits"),  # a full-width 2
    ("", "--workers='' is invalid: must be a whole number in digits"),
    ("0", "--workers=0 is out of range: allowed [1, 2]"),
    ("-1", "--workers=-1 is out of range: allowed [1, 2]"),
    ("3", "--workers=3 is out of range: allowed [1, 2] (this machine's 2 cores: add --workers-over-cores for more)"),
    ("99999", "--workers=99999 is out of range: allowed [1, 2] (this machine's 2 cores: add --workers-over-cores"),
    ("9" * 5000, "is out of range: allowed [1, 2], this machine's cores"),
])
def test_workers_refused_in_one_line_before_anything_starts(tiny, tmp_path, capsys, no_spawn, value, says):
    err = _refused(capsys, ["prepare", str(tiny), "--workers", value, "--stimuli", str(tmp_path / "s")])
    assert says in err
    assert not (tmp_path / "s").exists()


def test_workers_over_cores_needs_the_override_and_stays_under_the_ceiling(tiny, capsys, no_spawn):
    import argparse

    p = argparse.ArgumentParser()
    cluster.add_arguments(p)
    assert cluster.from_args(p.parse_args(["--workers", "2"])).workers == 2
    assert cluster.from_args(p.parse_args(["--workers", " +2 "])).workers == 2
    assert cluster.from_args(p.parse_args(["--workers", "64", "--workers-over-cores"])).workers == 64
    err = _refused(capsys, ["prepare", str(tiny), "--workers", "99999", "--workers-over-cores"])
    assert err.endswith(f"--workers=99999 is out of range: allowed [1, {cluster.WORKERS_MAX}]")


A63 = "a" * 63


@pytest.mark.parametrize(("address", "says"), [
    ("", "it is empty (leave the option out for a local cluster)"),
    ("   ", "it is empty"),
    (f"tcp://{'a' * 70}:8786", f"the host name {'a' * 70!r} is not a domain name (label too long; labels of 1-63"),
    (f"tcp://{A63}.{A63}.{A63}.{A63}:8786", "253 characters in all"),  # labels of 63, 255 in all
    ("tcp://a..b:8786", "is not a domain name (label empty or too long; labels of 1-63 characters)"),
    ("tcp://-a:8786", "is not labels of 1-63 letters, digits and hyphens"),
    ("tcp://a b:8786", "it holds spaces or control characters"),
    ("tcp://a\x00b:8786", "it holds spaces or control characters"),
    ("tcp://user@host:8786", "is not labels of 1-63"),
    ("tcp://127.0.0.1", "no port"),
    ("tcp://127.0.0.1:", "no port"),
    ("tcp://127.0.0.1:0", "port '0' is not a whole number in [1, 65535]"),
    ("tcp://127.0.0.1:70000", "port '70000' is not a whole number in [1, 65535]"),
    ("tcp://127.0.0.1:-1", "port '-1' is not"),
    ("tcp://127.0.0.1:8786/path", "port '8786/path' is not"),
    ("tcp://127.0.0.1:\u0668\u0667", "is not a whole number"),  # Arabic-Indic digits
    ("127.0.0.1:8786", "no scheme"),
    ("foo://127.0.0.1:8786", "unknown scheme 'foo': known tcp, tls, ws, wss, ucx"),
    ("inproc://x:1", "unknown scheme 'inproc'"),
    ("tcp://::1:8786", "an IPv6 address needs brackets, e.g. tcp://[::1]:8786"),
    ("tcp://[::1:8786", "an IPv6 address needs brackets"),
    ("tcp://[::g]:8786", "[::g] is not an IPv6 address"),
    ("tcp://999.1.1.1:8786", "999.1.1.1 is not an IPv4 address"),
    ("tcp://:8786", "no host"),
    ("tcp://" + "\u2603" * 62 + ":8786", "is not a domain name (label empty or too long"),
    ("tcp://" + "a" * 100_000 + ":8786", "is not a domain name (label too long"),
    ("tcp://" + "1." * 50_000 + ":8786", "is not an IPv4 address"),
    ("tcp://h:" + "9" * 50_000, "is not a whole number in [1, 65535]"),
    ("x" * 50_000 + "://h:1", "unknown scheme 'xxxxxxxx"),
])
def test_malformed_scheduler_addresses_are_one_line_before_anything_starts(tiny, tmp_path, capsys, no_spawn,
                                                                          monkeypatch, address, says):
    err = _refused(capsys, ["prepare", str(tiny), "--scheduler", address, "--stimuli", str(tmp_path / "s")])
    shown = repr(address) if len(address) < 290 else repr(address)[:296] + "...'"  # a huge one is cut
    assert err.startswith(f"studyapp: error: --scheduler {shown} is not a scheduler address: ")
    assert says in err and err.endswith("give tcp://HOST:PORT, e.g. tcp://192.168.1.10:8786")
    assert len(err) < 1000
    if address and "\x00" not in address:  # the variable says the same, naming itself
        monkeypatch.setenv(cluster.ENV_SCHEDULER, address)
        err = _refused(capsys, ["prepare", str(tiny), "--stimuli", str(tmp_path / "s")])
        assert err.startswith(f"studyapp: error: {cluster.ENV_SCHEDULER}={shown} is not a scheduler address")
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("address", ["tcp://10.0.0.1:8786", "tcp://[::1]:8786", "tls://lab-host.example.org:1",
                                     "tcp://h\u00e9.example:8786", f"tcp://{A63}.b:65535", "ws://a_b:1",
                                     "tcp://localhost.:8786"])
def test_well_formed_scheduler_addresses_pass_the_check(address):
    assert cluster.check_address(address, "--scheduler") == address


def test_an_empty_scheduler_variable_means_unset(monkeypatch):
    import argparse

    p = argparse.ArgumentParser()
    cluster.add_arguments(p)
    monkeypatch.setenv(cluster.ENV_SCHEDULER, "")
    assert cluster.from_args(p.parse_args([])) == cluster.ClusterSpec()
    with pytest.raises(ValueError, match="--scheduler '' is not a scheduler address: it is empty"):
        cluster.from_args(p.parse_args(["--scheduler", ""]))
    with pytest.raises(ValueError, match="--serial and --scheduler exclude each other"):
        cluster.from_args(p.parse_args(["--serial", "--scheduler", ""]))


def test_no_more_local_workers_than_tasks(monkeypatch):
    class Started(Exception):
        pass

    @contextlib.contextmanager
    def connect(spec):
        raise Started(spec)
        yield

    monkeypatch.setattr(cluster, "connect", connect)
    tasks = [cluster.Task(f"t{i}", f"task {i}", abs, (-i,)) for i in range(3)]
    with pytest.raises(Started) as started:
        cluster.run_tasks(tasks, cluster.ClusterSpec(workers=8))
    assert started.value.args == (cluster.ClusterSpec(workers=3),)
    got = []
    cluster.run_tasks(tasks[:1], cluster.ClusterSpec(workers=8), lambda t, r: got.append(r))
    assert got == [0]  # one task: this process, no cluster
    with pytest.raises(Started) as started:
        cluster.run_tasks(tasks[:2], cluster.ClusterSpec(scheduler="tcp://10.0.0.1:8786"))
    assert started.value.args[0].scheduler == "tcp://10.0.0.1:8786"  # a running cluster is never resized
    assert cluster.for_tasks(cluster.ClusterSpec(workers=2), 5) == cluster.ClusterSpec(workers=2)


@pytest.mark.parametrize("content", ["root:x:0:0:root:/root:/bin/bash\n", "a: [1,\n", "distributed:\n  logging: 5\n"])
def test_a_dask_config_dask_refuses_is_one_line_naming_it_and_nothing_starts(tiny, tmp_path, content):
    cfg = tmp_path / "dask.yaml"
    cfg.write_text(content)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "DASK_CONFIG": str(cfg)}
    env.pop(cluster.ENV_SCHEDULER, None)
    r = subprocess.run([sys.executable, "-c", NO_SPAWN, "prepare", str(tiny), "--workers", "2",
                        "--workers-over-cores", "--stimuli",
                        str(tmp_path / "s"), "--cache", str(tmp_path / "c")], env=env, capture_output=True,
                       text=True, timeout=120, check=False)
    assert r.returncode == 2, r.stderr
    assert r.stderr.splitlines() == [r.stderr.strip()]
    assert r.stderr.startswith(f"studyapp: error: DASK_CONFIG={cfg}: Dask cannot read its configuration (")
    assert r.stderr.strip().endswith("fix or unset it, or render in this process with --serial")
    assert not (tmp_path / "s").exists()
