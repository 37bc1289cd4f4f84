"""Ctrl-C and SIGTERM say what the stopped command leaves (issue 25): ``run`` its committed answers and the
--resume hint, ``prepare`` its frame cache, every other command that nothing was written. The hint is each
command's ``interrupted_hint`` default (studyapp.cli.interrupted_hint), printed by the CLI's one handler."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from studyapp import cli
from studyapp.cli import Terminated

ROOT = Path(__file__).resolve().parents[1]
RESUME = "committed answers are kept: continue a session with --resume"
CACHE = "frames rendered so far are kept in the cache: run the same prepare again to continue"
NOTHING = "nothing was written"


def _stop(exc):
    def stopped(*a, **k):
        raise exc
    return stopped


@pytest.mark.parametrize("signal_name,exc,word,status", [("SIGINT", KeyboardInterrupt(), "interrupted", 130),
                                                          ("SIGTERM", Terminated(), "terminated", 143)])
@pytest.mark.parametrize("command", ["run", "prepare", "export", "analyze", "render"])
def test_each_command_says_what_its_interruption_leaves(command, signal_name, exc, word, status, tmp_path,
                                                       monkeypatch, capsys):
    import analysis.io
    import data_schema.store
    import renderers.registry
    import studyapp.runner.session
    import studyapp.runner.stimuli

    monkeypatch.chdir(tmp_path)
    argv, hint = {
        "run": (["run", "seed001_2afc", "--participant", "P1", "--simulate", "--quiet"], RESUME),
        "prepare": (["prepare", "seed001_2afc", "--serial"], CACHE),
        "export": (["export", "--db", "s.db", "--out", "s.csv"], NOTHING),
        "analyze": (["analyze", "log.csv", "--out", "report"], NOTHING),
        "render": (["render", "--scene", "cornell", "--renderer", "gt", "--width", "32", "--height", "32", "--out",
                    "x.png"], NOTHING),
    }[command]
    # stopped where each command does its work (after its checks)
    monkeypatch.setattr(studyapp.runner.session, "run_session", _stop(exc))
    monkeypatch.setattr(studyapp.runner.stimuli, "prepare", _stop(exc))
    monkeypatch.setattr(data_schema.store, "export_csv", _stop(exc))
    monkeypatch.setattr(analysis.io, "read_log", _stop(exc))
    monkeypatch.setattr(renderers.registry, "render", _stop(exc))
    if command == "analyze":
        (tmp_path / "log.csv").write_text("participant,trial\nP1,1\n")
    if command == "export":
        (tmp_path / "s.db").write_bytes(b"")
    assert cli.main(argv) == status
    err = capsys.readouterr().err
    assert err == f"studyapp: {word} ({hint})\n"
    assert not (tmp_path / "s.csv").exists() and not (tmp_path / "report").exists()


def test_an_interruption_before_the_command_is_known_says_nothing_was_written(monkeypatch, capsys):
    class Parser:  # Ctrl-C while the arguments are parsed
        parse_args = staticmethod(_stop(KeyboardInterrupt()))

    monkeypatch.setattr(cli, "build_parser", Parser)
    assert cli.main(["prepare", "x"]) == 130
    assert capsys.readouterr().err == f"studyapp: interrupted ({NOTHING})\n"


def test_sigterm_during_a_prepare_points_at_the_cache(tmp_path):
    """A real signal: the prepare is rendering (its progress shows frames) when SIGTERM arrives."""
    proc = subprocess.Popen([sys.executable, "-m", "studyapp", "prepare", "seed001_2afc", "--serial", "--scale",
                             "0.25"], cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        cache = tmp_path / "stimuli"
        while time.monotonic() < deadline and not any(cache.rglob("*.png")):
            assert proc.poll() is None, proc.stderr.read()
            time.sleep(0.2)
        assert any(cache.rglob("*.png")), "no frame was rendered in 120 s"
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 143, err
    assert err.splitlines()[-1] == f"studyapp: terminated ({CACHE})", err
