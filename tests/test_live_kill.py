"""SIGKILL during simulated live trials, resume each time: no committed answer or its frames lost or changed,
and the final log (answers and frame poses/gaze) equals an uninterrupted run's."""

import os
import random
import sqlite3
import subprocess
import sys
from pathlib import Path

from sigkill import start_and_kill

ROOT = Path(__file__).resolve().parents[1]
KILLS = 8

PROTOCOL = """
schema_version: 1
name: kill_live
version: "1"
family: 2afc
question: "Which one?"
display: {width_px: 320, height_px: 180, width_cm: 30.0, distance_cm: 40.0, refresh_hz: 60}
scenes: [cornell]
conditions:
  GT: {renderer: gt, backend: cpu}
  LaFR: {renderer: lafr, params: {delta: 4.0}, backend: cpu, max_fps: 30}
stimulus: {kind: live, render_px: [64, 36], duration_s: 1.0, motion: path, gaze: fixation,
           camera_path: [{t: 0, yaw_deg: -3}, {t: 1, yaw_deg: 3}]}
design: {repetitions: 8}
simulation: {ground_truth: GT}
analysis: {dv: chosen, unit: participant, test: thurstone}
"""


def _cmd(proto, db, resume):
    return [sys.executable, "-m", "studyapp", "run", str(proto), "--participant", "P1", "--simulate", "--db",
            str(db), "--quiet", "--sim-delay", "0.05"] + (["--resume"] if resume else [])


def _state(db):
    if not db.exists():
        return False, {}, []
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        if "frames" not in {r[0] for r in con.execute("SELECT name FROM sqlite_master")}:
            return False, {}, []
        enrolled = con.execute("SELECT COUNT(*) FROM participants").fetchone()[0] == 1
        answers = {r[0]: r[1:] for r in con.execute("SELECT idx, answers, chosen FROM responses")}
        frames = con.execute("SELECT idx, frame, stimulus, gaze_x, gaze_y, pos_x, pos_y, pos_z, look_x, look_y, "
                             "look_z FROM frames ORDER BY idx, frame").fetchall()
        return enrolled, answers, frames
    finally:
        con.close()


def test_sigkill_during_live_trials_then_resume(tmp_path):
    proto = tmp_path / "kill_live.yaml"
    proto.write_text(PROTOCOL)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    rng = random.Random(7)
    db = tmp_path / "study.db"
    seen_answers, seen_frames, kills = {}, [], 0
    while kills < KILLS:
        enrolled, _, _ = _state(db)
        killed, code = start_and_kill(_cmd(proto, db, enrolled), tmp_path, env, rng, 0.6)
        kills += killed
        _, answers, frames = _state(db)
        for i, v in seen_answers.items():  # nothing committed is lost or changed
            assert answers.get(i) == v
        answered = set(answers)
        assert {f[0] for f in frames} <= answered  # frames only of answered trials
        assert [f for f in frames if f[0] in seen_answers] == [f for f in seen_frames]
        seen_answers, seen_frames = answers, frames
        if code == 0 or len(answers) == 8:
            break
    res = subprocess.run(_cmd(proto, db, True), cwd=tmp_path, env=env, capture_output=True, text=True)
    assert res.returncode == 0 or "already answered every trial" in res.stderr, res.stderr
    full = tmp_path / "full.db"
    assert subprocess.run(_cmd(proto, full, False), cwd=tmp_path, env=env, capture_output=True).returncode == 0
    _, a1, f1 = _state(db)
    _, a2, f2 = _state(full)
    assert kills >= 3 and len(a1) == 8
    assert {i: v[1] for i, v in a1.items()} == {i: v[1] for i, v in a2.items()}
    assert f1 == f2
