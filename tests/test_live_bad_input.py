"""Bad input for live trials (issue 14): a renderer without a GPU version, a frame-rate cap above the refresh
rate, no OpenGL 4.3, an eye tracker that does not start or fails its validation -> one line, exit 2, and the
study database unchanged (the window checks run before anything is recorded)."""

from __future__ import annotations

import dataclasses
import sqlite3
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from data_schema.errors import UserError
from studyapp.runner.protocol import load_protocol

sys.path.insert(0, str(Path(__file__).resolve().parent / "gui"))
from xvfb import ROOT, Xvfb, missing_tools  # noqa: E402

PROTOCOL = """
schema_version: 1
name: badlive
version: "1"
family: yes_no
question: "Acceptable? Y / N"
display: {{width_px: 320, height_px: 180, width_cm: 40.0, distance_cm: 40.0, refresh_hz: 60}}
fixation: {{x: 0.5, y: 0.5, mark: false}}
scenes: [cornell]
conditions:
  LaFR: {{renderer: lafr, params: {{delta: 4.0}}{extra}}}
  GT: {{renderer: gt}}
stimulus:
  kind: live
  duration_s: 2.0
  motion: explore
  gaze: {gaze}
  explore: {{move_speed_m_s: 0.2, turn_speed_deg: 30}}
{eyetracker}
timing: {{black_s: 0.3}}
design: {{conditions: [LaFR], repetitions: 1, trial_order: interleaved}}
simulation: {{ground_truth: GT}}
analysis: {{dv: response, unit: trial, test: summary_table}}
"""


def _write(tmp_path: Path, gaze: str = "mouse", eyetracker: str = "", extra: str = "") -> Path:
    path = tmp_path / "live.yaml"
    path.write_text(PROTOCOL.format(gaze=gaze, eyetracker=eyetracker, extra=extra))
    return path


def _run(args: list[str], env=None, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "studyapp", *args], env=env, cwd=str(ROOT), capture_output=True,
                          text=True, timeout=timeout)


def _keep_pressing(x: Xvfb, keys: tuple[str, ...], stop: threading.Event) -> None:
    """Press ``keys`` in turn every 0.3 s until ``stop`` is set (a screen ignores the keys it does not ask)."""
    while not stop.is_set():
        for k in keys:
            subprocess.run(["xdotool", "key", k], env=x.env, timeout=10, check=False)
            stop.wait(0.3)


def _one_error_line(proc: subprocess.CompletedProcess, expected: str) -> None:
    assert proc.returncode == 2, proc.stdout + proc.stderr
    ours = [line for line in proc.stderr.splitlines() if line.startswith("studyapp:")]
    assert len(ours) == 1 and expected in ours[0], proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout


def _dump(db: Path) -> list[str]:
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        return list(con.iterdump())
    finally:
        con.close()


def test_a_frame_rate_cap_above_the_refresh_rate_is_refused(tmp_path):
    proc = _run(["validate", str(_write(tmp_path, extra=", max_fps: 75"))])
    _one_error_line(proc, "max_fps")
    assert "60 Hz" in proc.stderr


def test_a_live_condition_needs_a_gpu_version_of_its_renderer(tmp_path, monkeypatch):
    from renderers import registry

    real = registry.get

    def without_gpu(name):
        plugin = real(name)
        return plugin if name != "lafr" else dataclasses.replace(plugin, gpu=None)

    monkeypatch.setattr(registry, "get", without_gpu)
    with pytest.raises(UserError, match="renderer 'lafr' has no GPU version for live stimuli: use backend: cpu"):
        load_protocol(_write(tmp_path), check_renderers=True)
    # the CPU backend is the way out, and the simulated observer never needs the GPU
    load_protocol(_write(tmp_path, extra=", backend: cpu"), check_renderers=True)
    load_protocol(_write(tmp_path), check_renderers=False)


@pytest.mark.parametrize("case", ["no_gl43", "tracker_does_not_start", "validation_fails"])
def test_window_checks_refuse_before_anything_is_recorded(tmp_path, case):
    assert not missing_tools(), f"GUI tests need {missing_tools()} (./run installs them)"
    env_extra, gaze, tracker, expected = {
        "no_gl43": ({"MESA_GL_VERSION_OVERRIDE": "3.3"}, "mouse", "",
                    "OpenGL 4.3 compute shaders are not available"),
        "tracker_does_not_start": ({}, "tracker", "eyetracker: {device: eyetracker.hw.nosuch.EyeTracker}",
                                   "the eye tracker did not start (no iohub device 'eyetracker.hw.nosuch"),
        "validation_fails": ({}, "tracker", "eyetracker: {device: eyetracker.hw.mouse.EyeTracker, "
                             "max_validation_error_deg: 0.01, max_attempts: 1, target_delay_s: 0.1, "
                             "target_duration_s: 0.1}",
                             "eye-tracker validation failed"),
    }[case]
    proto = _write(tmp_path, gaze=gaze, eyetracker=tracker)
    db = tmp_path / "s.db"  # a participant's answers, from the simulated observer (which needs no window)
    done = _run(["run", str(proto), "--participant", "P1", "--db", str(db), "--simulate", "--quiet"])
    assert done.returncode == 0, done.stderr
    before = _dump(db)
    with Xvfb() as x:
        stop = threading.Event()
        if case == "validation_fails":  # SPACE starts the check; after it fails, the experimenter's E ends
            threading.Thread(target=_keep_pressing, args=(x, ("space", "e"), stop), daemon=True).start()
        try:
            old = _run(["run", str(proto), "--participant", "P2", "--db", str(db)], env={**x.env, **env_extra})
        finally:
            stop.set()
        if case == "no_gl43":  # (the other cases refuse at the same point of a run)
            new = _run(["run", str(proto), "--participant", "P9", "--db", str(tmp_path / "new.db")],
                       env={**x.env, **env_extra})
            _one_error_line(new, expected)
            assert not (tmp_path / "new.db").exists()  # a refused first run leaves no database
    _one_error_line(old, expected)
    assert _dump(db) == before  # nothing recorded changed
