"""Adaptive sessions: each trial's level comes from the committed history; the level, the answer and the
procedure's state are stored with the response; a resume after SIGKILL at random points proposes exactly the
levels of an uninterrupted run; procedures that stop early skip their remaining slots; the export's columns."""

import json
import os
import random
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from data_schema.store import open_store, read_trials
from studyapp.runner.adaptive import replay
from studyapp.runner.protocol import load_protocol
from studyapp.runner.simulate import simulate_log
from sigkill import start_and_kill

ROOT = Path(__file__).resolve().parents[1]
BASE = ROOT / "studyapp" / "protocols" / "threshold_foveation.yaml"


def _protocol(tmp_path, trials=6, procedure="procedure: {method: quest_plus, function: weibull}"):
    text = BASE.read_text().replace("stop: {trials: 40}", f"stop: {{trials: {trials}}}", 1)
    text = text.replace("procedure: {method: quest_plus, function: weibull}", procedure, 1)
    f = tmp_path / "thr.yaml"
    f.write_text(text)
    return f


def _run(args):
    from studyapp.commands.study import main

    return main(args)


def _adaptive(db):
    with open_store(db) as st:
        return [{k: v for k, v in r.items()} for r in st.adaptive_rows()]


def test_simulated_session_chooses_levels_from_the_history_and_exports_them(tmp_path, capsys):
    f = _protocol(tmp_path)
    db = tmp_path / "s.db"
    assert _run(["run", str(f), "--simulate", "--participant", "P1", "--db", str(db), "--seed", "3", "--quiet",
                 "--stimuli", str(tmp_path / "none")]) == 0
    rows = _adaptive(db)
    assert len(rows) == 3 * 2 * 6 and not any(r["skipped"] for r in rows)
    p = load_protocol(f)
    for pid in {r["procedure"] for r in rows}:  # every stored level is what the replayed procedure chose
        mine = [r for r in rows if r["procedure"] == pid]
        spec = p.adaptive.spec(pid.split("@")[0])
        for k, r in enumerate(mine):
            proc = replay(spec, 0, [(m["level"], m["correct"]) for m in mine[:k]])
            assert proc.next_level() == r["level"]
        last = replay(spec, 0, [(m["level"], m["correct"]) for m in mine])
        assert last.estimate()["mean"] == pytest.approx(mine[-1]["estimate_mean"])
        assert last.estimate()["sd"] == pytest.approx(mine[-1]["estimate_sd"])
    df = read_trials(db)
    assert {"procedure", "varied", "level", "intensity", "correct", "estimate_mean", "estimate_sd"} <= set(df)
    assert set(df["varied"]) == {"acuity_scale", "delta"} and set(df["condition"]) == {"VaFR", "LaFR", "LMFR"}
    # 2afc: correct means the original (GT) was picked
    assert ((df["chosen"] == "GT").astype(float) == df["correct"]).all()
    # the in-memory simulation (power analysis) records the same levels and answers
    sim = simulate_log(p, ["P1"], seed=3, stimuli_root=tmp_path / "none")
    cols = ["trial", "procedure", "level", "correct", "estimate_mean"]
    pd.testing.assert_frame_equal(sim[cols].reset_index(drop=True), df[cols].reset_index(drop=True))


def test_a_staircase_that_stops_early_skips_its_remaining_slots(tmp_path):
    f = _protocol(tmp_path, trials=30, procedure="procedure: {method: staircase, rule: 1-up-1-down}")
    f.write_text(f.read_text().replace("stop: {trials: 30}", "stop: {trials: 30, reversals: 2}"))
    db = tmp_path / "s.db"
    assert _run(["run", str(f), "--simulate", "--participant", "P1", "--db", str(db), "--seed", "1", "--quiet",
                 "--stimuli", str(tmp_path / "none")]) == 0
    rows = _adaptive(db)
    skipped = [r for r in rows if r["skipped"]]
    assert len(rows) == 180 and skipped
    df = read_trials(db)
    assert len(df) == 180 - len(skipped) and not set(df["trial"]) & {r["idx"] for r in skipped}
    for pid in {r["procedure"] for r in skipped}:  # a procedure skips only once it has its reversals
        mine = [r for r in rows if r["procedure"] == pid]
        first = next(i for i, r in enumerate(mine) if r["skipped"])
        assert all(r["skipped"] for r in mine[first:])
        assert len(json.loads(mine[first - 1]["state"])["reversal_intensities"]) == 2


KILLS = 6


def _cmd(proto, db, resume):
    cmd = [sys.executable, "-m", "studyapp.commands.study", "run", str(proto), "--participant", "P1", "--simulate",
           "--db", str(db), "--quiet", "--stimuli", str(db.parent / "none"), "--sim-delay", "0.01", "--seed", "5"]
    return cmd + (["--resume"] if resume else [])


def test_sigkill_at_random_points_then_resume_proposes_the_uninterrupted_levels(tmp_path):
    proto = _protocol(tmp_path, trials=8)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    rng = random.Random(28)
    db = tmp_path / "study.db"
    kills = 0
    while kills < KILLS:
        killed, code = start_and_kill(_cmd(proto, db, db.exists()), tmp_path, env, rng, 0.25)
        kills += killed
        if code == 0:
            break
    if db.exists():
        with open_store(db) as st:
            done = len(st.answered("P1")) == 48 and not st.running_sessions("P1")
    else:
        done = False
    if not done:
        res = subprocess.run(_cmd(proto, db, db.exists()), cwd=tmp_path, env=env, capture_output=True, text=True,
                             check=False)
        assert res.returncode == 0 or "already answered every trial" in res.stderr, res.stderr
    full = tmp_path / "full.db"
    res = subprocess.run(_cmd(proto, full, False), cwd=tmp_path, env=env, capture_output=True, text=True,
                         check=False)
    assert res.returncode == 0, res.stderr
    assert kills >= 3
    got, want = _adaptive(db), _adaptive(full)
    assert len(want) == 48
    assert got == want  # levels, answers, estimates and states
    with open_store(db) as st:
        assert len(st.sessions()) > 1


def _stopping_factory(protocol, stop_after):
    """The simulated observer, interrupted (as by Ctrl-C) when asked for trial number ``stop_after + 1``."""
    from studyapp.runner.observer import SimulatedObserver
    from studyapp.runner.session import ground_truth_stimuli

    def make(stimuli, display):
        obs = SimulatedObserver(protocol, "P1", 2, ground_truth_stimuli(protocol, stimuli))
        answer, asked = obs.present, []

        def present(d):
            asked.append(d.index)
            if stop_after is not None and len(asked) > stop_after:
                raise KeyboardInterrupt
            return answer(d)

        obs.present = present
        return obs
    return make


def test_resume_continues_each_procedure_and_refuses_a_lost_adaptive_record(tmp_path):
    import sqlite3

    from data_schema.store import StoreError
    from studyapp.runner.session import run_session

    p = load_protocol(_protocol(tmp_path), stimuli_dir=tmp_path / "none")
    kw = {"seed": 2, "allow_declared": True}
    run_session(p, "P1", tmp_path / "full.db", _stopping_factory(p, None), **kw)
    db = tmp_path / "s.db"
    for stop in (5, 7, 11):  # interrupted three times, then finished
        with pytest.raises(KeyboardInterrupt):
            run_session(p, "P1", db, _stopping_factory(p, stop), resume=db.exists(), **kw)
    run_session(p, "P1", db, _stopping_factory(p, None), resume=True, **kw)
    assert _adaptive(db) == _adaptive(tmp_path / "full.db")
    # an answered trial whose adaptive record vanished (a damaged file) is refused, not replayed short
    db2 = tmp_path / "s2.db"
    with pytest.raises(KeyboardInterrupt):
        run_session(p, "P1", db2, _stopping_factory(p, 9), **kw)
    con = sqlite3.connect(db2)
    con.execute("DELETE FROM adaptive WHERE idx = (SELECT MAX(idx) FROM adaptive)")
    con.commit()
    con.close()
    with pytest.raises(StoreError, match="is damaged .*an answered adaptive trial has no adaptive record"):
        run_session(p, "P1", db2, _stopping_factory(p, None), resume=True, **kw)
    with pytest.raises(StoreError, match="no adaptive record"):  # nor exported without its level
        read_trials(db2)
