"""Sessions end to end with the simulated observer: every shipped protocol, resume, Escape, bad input."""

import csv
import re
from pathlib import Path

import pytest

from data_schema import store as S
from data_schema.store import open_store
from data_schema.trial_log import ALL_COLUMNS
from studyapp.commands.study import demo_step, main
from studyapp.runner.observer import SimulatedObserver
from studyapp.runner.protocol import load_protocol, protocol_from_data
from studyapp.runner.schedule import build_schedule
from studyapp.runner.session import ground_truth_stimuli, run_session
from studyapp.runner.stimuli import write_synthetic_stimuli

PROTOCOLS = Path(__file__).resolve().parents[1] / "protocols"
SHIPPED = sorted(PROTOCOLS.glob("seed*.yaml"))


def _sim(p, pid, seed=0, script=None):
    def make(stimuli, display):
        obs = SimulatedObserver(p, pid, seed, ground_truth_stimuli(p, stimuli))
        return obs if script is None else script(obs)
    return make


def _log(db):
    """Tidy rows without the session id (a resumed run has more sessions than an uninterrupted one)."""
    return [{k: v for k, v in r.items() if k != "session"} for r in open_store(db).tidy_rows()]


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_every_shipped_protocol_runs_end_to_end_with_declared_qualities(tmp_path, path, capsys):
    db = tmp_path / "study.db"
    for pid in ("P1", "P2"):
        assert main(["run", str(path), "--participant", pid, "--simulate", "--db", str(db), "--quiet",
                     "--stimuli", str(tmp_path / "none")]) == 0
    out = capsys.readouterr().out
    assert "completed" in out
    p = load_protocol(path, check_renderers=False)
    df = S.read_trials(db)
    assert tuple(df.columns) == ALL_COLUMNS
    n = sum(t.kind != "reference" for t in build_schedule(p, "P1", 0))
    assert len(df) == 2 * n
    main_trials = df[(df.practice == 0) & (df["catch"] == 0)]
    per = {"seed001_pilot": 3, "seed001_2afc": 90, "seed003_task1": 50, "seed003_task2": 40,
           "seed003_alpha_threshold": 80}[p.name.removesuffix("_live")]
    assert len(main_trials) == 2 * per
    if p.family == "yes_no":
        assert set(df.response.unique()) <= {0.0, 1.0}
    elif p.family == "2afc":
        assert (df.chosen.eq(df.condition_a) | df.chosen.eq(df.condition_b)).all()
    else:
        assert all(c in r.split("|") for c, r in zip(df.chosen, df.conditions))
    assert (df.rt_s > 0).all()
    assert main(["export", "--db", str(db), "--format", "csv", "--out", str(tmp_path / "t.csv")]) == 0
    with open(tmp_path / "t.csv") as fh:
        assert tuple(next(csv.reader(fh))) == ALL_COLUMNS


def test_simulated_observer_uses_synthetic_images(tmp_path):
    p = load_protocol(PROTOCOLS / "seed001_2afc.yaml", stimuli_dir=tmp_path / "stim", check_renderers=False)
    write_synthetic_stimuli(p, 0.1, max_frames=2)
    db = tmp_path / "s.db"
    observers = []

    def keep(obs):
        observers.append(obs)
        return obs
    s = run_session(p, "P1", db, _sim(p, "P1", script=keep), seed=0, scale=0.1)
    assert s.status == "completed" and s.answered == s.planned == 98 and s.catch_passed is True
    obs = observers[0]
    imp = {k[0]: v for k, v in obs._impairment.items() if k[1] == "temple"}
    assert imp["GT"] == 0.0
    assert imp["DEGRADED"] > imp["LaFR(2.2)"] > imp["VaFR_Rep"] > 0.0  # ordered by the synthetic quality
    assert all(len(k[2]) == p.n_frames for k in obs._impairment)  # frames found on disk, not declared


def test_existing_participant_without_resume_is_refused_and_nothing_changes(tmp_path, capsys):
    db = tmp_path / "s.db"
    args = ["run", "seed003_task2", "--participant", "P1", "--simulate", "--db", str(db), "--quiet",
            "--stimuli", str(tmp_path / "none")]
    assert main(args) == 0
    before = _log(db)
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "participant 'P1' already exists" in err and "--resume" in err
    assert _log(db) == before
    assert main(args + ["--resume"]) == 2
    assert "already answered every trial" in capsys.readouterr().err
    assert main(["run", "seed003_task2", "--participant", "P9", "--simulate", "--db", str(db), "--resume"]) == 2
    assert "no session to resume" in capsys.readouterr().err


def test_escape_end_then_resume_equals_an_uninterrupted_run(tmp_path):
    p = load_protocol(PROTOCOLS / "seed003_task1.yaml", check_renderers=False)

    class EscapeAt:
        def __init__(self, obs, at, choice):
            self.obs, self.at, self.choice, self.paused = obs, at, choice, 0

        def __getattr__(self, name):
            return getattr(self.obs, name)

        def present(self, trial):
            if trial.index == self.at and not self.paused:
                from studyapp.presentation.base import TrialResult
                return TrialResult([], float("nan"), 0.0, escaped=True)
            return self.obs.present(trial)

        def pause(self):
            self.paused += 1
            return self.choice

    full = tmp_path / "full.db"
    run_session(p, "P1", full, _sim(p, "P1"), allow_declared=True)
    db = tmp_path / "cut.db"
    s1 = run_session(p, "P1", db, _sim(p, "P1", script=lambda o: EscapeAt(o, 20, "end")), allow_declared=True)
    assert s1.status == "ended" and s1.answered < s1.planned
    with open_store(db) as st:
        assert st.first_unanswered("P1") == 20
        events = [r[0] for r in st.conn.execute("SELECT kind FROM events ORDER BY id")]
        assert events == ["pause", "end"]
    s2 = run_session(p, "P1", db, _sim(p, "P1"), resume=True, allow_declared=True)
    assert s2.status == "completed" and s2.answered == s2.planned
    assert _log(db) == _log(full)
    s3 = run_session(p, "P2", db, _sim(p, "P2", script=lambda o: EscapeAt(o, 5, "resume")), allow_declared=True)
    assert s3.status == "completed"
    with open_store(db) as st:
        sessions = st.sessions()
    assert [(s["id"], s["status"], s["resumed_from"]) for s in sessions] == [
        ("P1-s1", "ended", None), ("P1-s2", "completed", "P1-s1"), ("P2-s1", "completed", None)]


def test_full_disk_mid_session_is_one_line_and_resume_completes(tmp_path, monkeypatch, capsys):
    db = tmp_path / "s.db"
    args = ["run", "seed001_2afc", "--participant", "P1", "--simulate", "--db", str(db), "--quiet",
            "--stimuli", str(tmp_path / "none")]
    real_commit = S.Store.commit_response

    def filling_disk(self, *a, **kw):  # after the schedule is written the 'disk' has one page left
        if not getattr(self, "_limited", False):
            self._limited = True
            pages = self.conn.execute("PRAGMA page_count").fetchone()[0]
            self.conn.execute(f"PRAGMA max_page_count = {pages + 1}")
        return real_commit(self, *a, **kw)
    monkeypatch.setattr(S.Store, "commit_response", filling_disk)
    assert main(args) == 2
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("studyapp: error:")]
    assert len(errors) == 1 and "no space left on device: could not save the response to trial" in errors[0]
    assert err.endswith(errors[0] + "\n")
    monkeypatch.setattr(S.Store, "commit_response", real_commit)
    with open_store(db) as st:
        kept = st.answered("P1")
        assert st.conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    assert main(args + ["--resume"]) == 0
    full = tmp_path / "full.db"
    assert main(args[:6] + [str(full)] + args[7:]) == 0
    assert 0 < len(kept) < 98
    assert _log(db) == _log(full)


def test_bad_input_exits_2_with_one_line(tmp_path, capsys):
    text = (PROTOCOLS / "seed001_2afc.yaml").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("  conditions: [VaFR_Rep,", "  conditions: [VaFR_X,"))
    cases = [
        (["run", str(bad), "--participant", "P1", "--simulate", "--db", str(tmp_path / "a.db")],
         "design.conditions[0]: unknown condition 'VaFR_X'"),
        (["run", "seed001_2afc", "--participant", "P1", "--simulate", "--db", str(tmp_path / "a.db"),
          "--scale", "2"], "--scale=2 is out of range"),
        (["run", "seed001_2afc", "--participant", "P 1", "--simulate", "--db", str(tmp_path / "a.db")],
         "--participant='P 1' is invalid"),
        (["run", "seed001_2afc", "--participant", "ann@example.org", "--simulate", "--db", str(tmp_path / "a.db")],
         "no names or e-mail addresses"),
        (["sessions", "--db", str(tmp_path / "none.db")], "no such study database"),
        (["export", "--db", str(tmp_path / "none.db"), "--format", "csv", "--out", str(tmp_path / "x.csv")],
         "no such study database"),
        (["validate", str(tmp_path / "none.yaml")], "no such protocol file"),
    ]
    for args, words in cases:
        assert main(args) == 2, args
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err, err
    assert not (tmp_path / "a.db").exists()


def test_missing_stimulus_file_of_a_folder_condition(tmp_path, capsys):
    folder = tmp_path / "lab"
    p = load_protocol(PROTOCOLS / "seed003_task2.yaml", check_renderers=False)
    text, n = re.subn(r"CC3: \{renderer: sl_as[^}]*\}", "CC3: {folder: lab, quality: 0.6}",
                      (PROTOCOLS / "seed003_task2.yaml").read_text())
    assert n == 1
    f = tmp_path / "t2.yaml"
    f.write_text(text)
    for scene in p.scenes[:-1]:
        (folder / scene).mkdir(parents=True)
        (folder / scene / "f0.png").write_bytes(b"x")
    db = tmp_path / "s.db"
    assert main(["run", str(f), "--participant", "P1", "--simulate", "--db", str(db),
                 "--stimuli", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    # the folder and the files it lacks (not `prepare`, which renders no folder condition)
    assert (f"1 stimulus set(s) of folder conditions missing (CC3/sponza_vpl): condition CC3 reads a lab's own "
            f"images from {folder}: put sponza_vpl/frame_00000.png ... sponza_vpl/frame_{p.n_frames - 1:05d}.png "
            f"({p.n_frames} PNG frames per scene, read in name order) there") in err
    assert err.count("\n") == 1
    assert not db.exists()  # a refused first run leaves no database behind
    # Fixing the protocol (a new content hash) then works with the same --db.
    (folder / p.scenes[-1]).mkdir(parents=True)
    (folder / p.scenes[-1] / "f0.png").write_bytes(b"x")
    assert main(["run", str(f), "--participant", "P1", "--simulate", "--db", str(db), "--quiet",
                 "--stimuli", str(tmp_path / "none")]) == 0


def test_protocol_of_another_version_is_refused(tmp_path, capsys):
    db = tmp_path / "s.db"
    base = ["--participant", "P1", "--simulate", "--db", str(db), "--quiet", "--stimuli", str(tmp_path / "n")]
    assert main(["run", "seed003_task2"] + base) == 0
    before = _log(db)
    v2 = tmp_path / "t2.yaml"
    v2.write_text((PROTOCOLS / "seed003_task2.yaml").read_text().replace('version: "1.1"', 'version: "1.2"'))
    capsys.readouterr()
    assert main(["run", str(v2)] + base[:1] + ["P2"] + base[2:]) == 2
    err = capsys.readouterr().err
    assert "written by protocol 'seed003_task2' version '1.1'" in err and "'1.2'" in err
    assert _log(db) == before


def test_sessions_command_lists_progress_and_catch(tmp_path, capsys):
    db = tmp_path / "s.db"
    assert main(["run", "seed003_task1", "--participant", "P1", "--simulate", "--db", str(db), "--quiet",
                 "--stimuli", str(tmp_path / "n")]) == 0
    capsys.readouterr()
    assert main(["sessions", "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert "P1-s1" in out and "completed" in out and "/4 passed" in out


def test_demo_step_writes_databases_and_tidy_csvs(tmp_path):
    msgs = []
    paths = demo_step(tmp_path, msgs.append)
    names = sorted(p.name for p in paths)
    assert names == ["seed001_2afc.db", "seed001_2afc_pwcmp.csv", "seed001_2afc_trials.csv", "seed001_pilot_live.db",
                     "seed001_pilot_live_trials.csv", "seed003_task1.db", "seed003_task1_trials.csv"]
    df = S.read_trials(tmp_path / "study" / "seed003_task1.db")
    assert df.participant.nunique() == 5
    means = df[(df.practice == 0) & (df["catch"] == 0)].groupby("condition").response.mean()
    assert means["CC1"] > means["CC2"]  # the synthetic GT looks like GT more often than the worst condition
    assert msgs


def test_in_memory_simulation_matches_a_recorded_simulated_session(tmp_path):
    from studyapp.runner.simulate import simulate_log

    p = load_protocol(PROTOCOLS / "seed003_task1.yaml", stimuli_dir=tmp_path / "none", check_renderers=False)
    db = tmp_path / "s.db"
    for pid in ("P01", "P02"):
        run_session(p, pid, db, _sim(p, pid, seed=3), seed=3, allow_declared=True)
    recorded = S.read_trials(db).drop(columns="session")
    mem = simulate_log(p, 2, seed=3).drop(columns="session")
    import pandas as pd
    pd.testing.assert_frame_equal(mem, recorded)
    many = simulate_log(p, 12, seed=1)
    means = many[(many.practice == 0) & (many["catch"] == 0)].groupby("condition").response.mean()
    assert means["CC1"] > means["EC"] > means["CC2"]


def test_analysis_plan_of_a_study_follows_the_protocol(tmp_path):
    from analysis.plan import plan_from_mapping

    db = tmp_path / "s.db"
    assert main(["run", "seed003_task1", "--participant", "P1", "--simulate", "--db", str(db), "--quiet",
                 "--stimuli", str(tmp_path / "n")]) == 0
    plan = S.read_analysis_plan(db)
    assert plan["conditions"] == ["EC", "CC1", "CC2", "CC3", "CC4"] and plan["reference"] == "EC"
    ap = plan_from_mapping(plan)
    assert (ap.unit, ap.reference, ap.conditions) == ("trial", "EC", ("EC", "CC1", "CC2", "CC3", "CC4"))


def test_window_errors_are_one_line(tmp_path, monkeypatch, capsys):
    from studyapp.commands import study
    from studyapp.presentation.base import PresentationError

    class NoKeyboard:
        def open(self, display):
            raise PresentationError("keyboard backend is 'iohub', not psychtoolbox ('ptb'): refusing to run")

        def close(self):
            pass

    monkeypatch.setattr(study, "_presenter_factory", lambda args, p: (lambda st, d: NoKeyboard()))
    db = tmp_path / "s.db"
    assert main(["run", "seed003_task2", "--participant", "P1", "--simulate", "--db", str(db),
                 "--stimuli", str(tmp_path / "n")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not psychtoolbox" in err
    assert not db.exists()


def test_resume_after_a_stop_behind_the_last_answer_closes_the_session(tmp_path, capsys):
    p = load_protocol(PROTOCOLS / "seed001_pilot.yaml", stimuli_dir=tmp_path / "n", check_renderers=False)
    db = tmp_path / "s.db"
    run_session(p, "P1", db, _sim(p, "P1"), allow_declared=True)
    with open_store(db, "write") as st:  # as if killed after the last commit, before the session was closed
        with st.transaction("reopen") as c:
            S.tables._update(c, "sessions", {"id": "P1-s1"}, {"status": "running", "ended_utc": None})
    s = run_session(p, "P1", db, _sim(p, "P1"), resume=True, allow_declared=True)
    assert (s.session, s.status, s.answered, s.planned) == ("P1-s1", "completed", 4, 4)
    with open_store(db) as st:
        assert [(x["id"], x["status"]) for x in st.sessions()] == [("P1-s1", "completed")]
        assert [r[0] for r in st.conn.execute("SELECT kind FROM events")] == ["closed"]
    with pytest.raises(Exception, match="already answered every trial"):
        run_session(p, "P1", db, _sim(p, "P1"), resume=True, allow_declared=True)


class Watching:
    """The simulated observer, watched: records every trial shown (``seen``) and break text (``rests``);
    with ``stop_at`` Escape on that trial, then "end"."""

    def __init__(self, obs, stop_at=None, seen=None, rests=None):
        self.obs, self.stop_at = obs, stop_at
        self.seen = [] if seen is None else seen
        self.rests = [] if rests is None else rests

    def __getattr__(self, name):
        return getattr(self.obs, name)

    def rest(self, text, seconds):
        self.rests.append(text)

    def present(self, trial):
        self.seen.append(trial)
        if trial.index == self.stop_at:
            from studyapp.presentation.base import TrialResult
            return TrialResult([], float("nan"), 0.0, escaped=True)
        return self.obs.present(trial)

    def pause(self):
        return "end"


def _enrol_before_issue_26(monkeypatch, p, db, stop_at):
    """Run participant P1 under the schedule rules of before (``legacy``) until Escape + end at ``stop_at``."""
    from studyapp.runner import session as sess

    monkeypatch.setattr(sess, "build_schedule", lambda *a, **k: build_schedule(*a, **k, legacy=True))
    s = run_session(p, "P1", db, _sim(p, "P1", script=lambda o: Watching(o, stop_at)), allow_declared=True)
    monkeypatch.undo()
    assert s.status == "ended"


def test_a_schedule_stored_before_scene_change_breaks_resumes_with_its_breaks(tmp_path, monkeypatch):
    """seed001_2afc's breaks moved from answers 31/62/93 to the scene changes (34, 66): a participant enrolled
    under the old rule resumes with the stored breaks, each saying only that it is a break."""
    from studyapp.runner.schedule import BREAK_TEXT

    p = load_protocol(PROTOCOLS / "seed001_2afc.yaml", check_renderers=False)
    texts = []

    def watch(o):
        return Watching(o, rests=texts)

    db = tmp_path / "old.db"
    _enrol_before_issue_26(monkeypatch, p, db, 40)
    s = run_session(p, "P1", db, _sim(p, "P1", script=watch), resume=True, allow_declared=True)
    assert s.status == "completed" and s.answered == s.planned == 98
    with open_store(db) as st:
        assert [t.idx for t in st.planned("P1") if t.break_before] == [31, 62, 93]
        breaks = st.conn.execute("SELECT detail FROM events WHERE kind = 'break' ORDER BY id")
        assert [r[0] for r in breaks] == ["before trial 31", "before trial 62", "before trial 93"]
    assert texts == [BREAK_TEXT] * 2  # the resumed session's breaks (62, 93): no scene starts there
    # a new participant of the same study gets the breaks at the scene changes
    texts.clear()
    run_session(p, "P2", db, _sim(p, "P2", script=watch), allow_declared=True)
    with open_store(db) as st:
        planned = st.planned("P2")
    starts = [t.idx for t in planned[1:] if planned[t.idx - 1].kind != "practice"
              and t.scene != planned[t.idx - 1].scene]
    assert [t.idx for t in planned if t.break_before] == starts and len(starts) == 2
    assert texts == ["Take a short break. The next scene starts in 30 s."] * 2


def test_practice_is_marked_and_not_counted_in_the_progress(tmp_path):
    """The participant's "k / n" counts the answered trials of the design and catch trials only; a practice
    trial carries kind "practice" (the window says "practice" there) and no number; every trial screen gets
    the protocol's key reminder place (default bottom)."""
    p = load_protocol(PROTOCOLS / "seed003_task1.yaml", check_renderers=False)
    shown = []
    run_session(p, "P1", tmp_path / "s.db", _sim(p, "P1", script=lambda o: Watching(o, seen=shown)),
                allow_declared=True)
    seen = [(t.kind, t.progress, t.key_reminder) for t in shown]
    plan = build_schedule(p, "P1", 0)
    counted = [t for t in plan if t.kind not in ("practice", "reference")]
    assert [k for k, _, _ in seen] == [t.kind for t in plan]
    assert all(prog is None for k, prog, _ in seen if k in ("practice", "reference"))
    assert [prog for k, prog, _ in seen if k not in ("practice", "reference")] == [
        (i + 1, len(counted)) for i in range(len(counted))]
    assert {r for _, _, r in seen} == {"bottom"}
    off = protocol_from_data({**p.data, "presentation": {"key_reminder": "off"}}, "off",
                             check_renderers=False)
    assert off.key_reminder == "off"
    with pytest.raises(ValueError, match="presentation.key_reminder: 'left' is not one of bottom, top, off"):
        protocol_from_data({**p.data, "presentation": {"key_reminder": "left"}}, "left",
                           check_renderers=False)


def test_a_task1_participant_enrolled_before_the_practice_reference_resumes_without_it(tmp_path, monkeypatch):
    p = load_protocol(PROTOCOLS / "seed003_task1.yaml", check_renderers=False)
    db = tmp_path / "old.db"
    _enrol_before_issue_26(monkeypatch, p, db, 10)
    s = run_session(p, "P1", db, _sim(p, "P1"), resume=True, allow_declared=True)
    assert s.status == "completed" and s.answered == s.planned
    run_session(p, "P2", db, _sim(p, "P2"), allow_declared=True)
    with open_store(db) as st:
        assert st.planned("P1")[0].kind == "practice"  # as stored
        assert [t.kind for t in st.planned("P2")[:2]] == ["reference", "practice"]  # the GT first now
