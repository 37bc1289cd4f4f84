"""SIGKILL at random points of a simulated session, resume each time: nothing lost, nothing twice.

The runner is a real subprocess (``python -m studyapp.commands.study run ... --simulate``) killed with
``kill -9`` at KILLS random moments: mostly while trials are being answered and committed (a random delay
after the session has started), some during start-up (import, schedule, enrolment). After every kill the
committed responses are read back: every response seen committed before stays (none lost), none appears twice,
the database passes ``PRAGMA integrity_check``. At the end the log equals an uninterrupted run's.
"""

import os
import random
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

from data_schema.store import open_store

ROOT = Path(__file__).resolve().parents[1]
KILLS = 50
TRIAL_DELAY_S = 0.003  # simulated think time per trial, so a session lasts long enough to be hit


def _cmd(db, pid, resume):
    cmd = [sys.executable, "-m", "studyapp.commands.study", "run", "seed001_2afc", "--participant", pid,
           "--simulate", "--db", str(db), "--quiet", "--stimuli", str(db.parent / "none"),
           "--sim-delay", str(TRIAL_DELAY_S), "--seed", "4"]
    return cmd + (["--resume"] if resume else [])


def _state(db, pid):
    if not db.exists():
        return False, []
    con = sqlite3.connect(db)
    try:
        tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if "participants" not in tables:
            return False, []
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        enrolled = con.execute("SELECT COUNT(*) FROM participants WHERE id=?", (pid,)).fetchone()[0] == 1
        rows = con.execute("SELECT idx, answers, chosen FROM responses WHERE participant=? ORDER BY idx",
                           (pid,)).fetchall()
        return enrolled, rows
    finally:
        con.close()


def _tidy(db):
    with open_store(db) as st:
        return [{k: v for k, v in r.items() if k != "session"} for r in st.tidy_rows()]


def test_sigkill_at_random_points_then_resume(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    rng = random.Random(20261201)
    db = tmp_path / "study.db"
    seen: dict[int, tuple] = {}
    kills, hit_during_trials, participants = 0, 0, ["P1"]
    while kills < KILLS:
        pid = participants[-1]
        enrolled, _ = _state(db, pid)
        proc = subprocess.Popen(_cmd(db, pid, enrolled), cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        if rng.random() < 0.15:  # during start-up: imports, schedule, enrolment, session row
            time.sleep(rng.uniform(0.0, 0.4))
        else:
            line = proc.stdout.readline()
            if "started" in line:
                time.sleep(rng.uniform(0.0, 0.03))
                hit_during_trials += 1
            elif proc.wait() != 0:  # (0: the previous kill hit after the last answer; the run closed it)
                raise AssertionError(f"runner did not start: {line!r} {proc.stderr.read()!r}")
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
            kills += 1
        proc.wait()
        proc.stdout.close()
        proc.stderr.close()
        if proc.returncode == 0:  # finished before it was hit: go on with the next participant
            _, rows = _state(db, pid)
            assert [r[0] for r in rows] == sorted({r[0] for r in rows}) and len(rows) == 98
            participants.append(f"P{len(participants) + 1}")
            seen = {}
            continue
        assert proc.returncode == -signal.SIGKILL, proc.returncode
        _, rows = _state(db, pid)
        idx = [r[0] for r in rows]
        assert len(idx) == len(set(idx))  # nothing twice
        now = {r[0]: r[1:] for r in rows}
        for i, value in seen.items():  # nothing committed is lost or changed
            assert now.get(i) == value
        seen = now
        if len(rows) == 98:  # killed after the last answer: a resume closes the session if it was still open
            res = subprocess.run(_cmd(db, pid, True), cwd=tmp_path, env=env, capture_output=True, text=True,
                                 check=False)
            assert res.returncode == 0 or "already answered every trial" in res.stderr, res.stderr
            participants.append(f"P{len(participants) + 1}")
            seen = {}
    # Finish the last participant without interruption.
    enrolled, _ = _state(db, participants[-1])
    res = subprocess.run(_cmd(db, participants[-1], enrolled), cwd=tmp_path, env=env, capture_output=True,
                         text=True, check=False)
    assert res.returncode == 0, res.stderr
    full = tmp_path / "full.db"
    for pid in participants:
        res = subprocess.run(_cmd(full, pid, False), cwd=tmp_path, env=env, capture_output=True, text=True,
                             check=False)
        assert res.returncode == 0, res.stderr
    assert kills == KILLS and hit_during_trials >= KILLS // 2
    got, want = _tidy(db), _tidy(full)
    assert len(want) == 98 * len(participants)
    assert got == want
    with open_store(db) as st:
        sessions = st.sessions()
    last = [s for s in sessions if s["participant"] == participants[-1]]
    assert len(sessions) >= 2 and last[-1]["status"] == "completed"
    assert all(s["status"] in ("interrupted", "completed") for s in sessions)  # none left 'running'
    assert sum(s["status"] == "completed" for s in sessions) == len(participants)
