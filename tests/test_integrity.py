"""Study data survives hostile and damaged input (issue 10): one case per test, small inputs.

Every refusal is exit status 2 with exactly one stderr line and no traceback, and leaves every file it was
given byte-identical (no schema created, no switch to WAL, no -wal/-shm left).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from data_schema import store as S
from studyapp.cli import main

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def _run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _refused(code: int, err: str, *words: str) -> None:
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("studyapp: error: "), err
    assert "Traceback" not in err
    for w in words:
        assert w in err, err


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _files(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): _digest(p) for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def study_db(tmp_path_factory) -> Path:
    """A two-participant seed003_task1 database (the issue's example), built once."""
    d = tmp_path_factory.mktemp("study")
    db = d / "study.db"
    for pid in ("P1", "P2"):
        assert main(["run", "seed003_task1", "--participant", pid, "--simulate", "--db", str(db), "--quiet",
                     "--stimuli", str(d / "none")]) == 0
    return db


@pytest.fixture
def db(study_db, tmp_path) -> Path:
    copy = tmp_path / "study.db"
    shutil.copyfile(study_db, copy)
    return copy


# -- 1. never overwrite a database ---------------------------------------------------------------------------
def test_export_onto_the_database_itself_is_refused(db, tmp_path, capsys):
    before = _digest(db)
    code, _, err = _run(capsys, "export", "--db", db, "--out", db)
    _refused(code, err, "refusing to overwrite")
    os.link(db, tmp_path / "same.csv")  # the same file by inode under another name
    code, _, err = _run(capsys, "export", "--db", db, "--out", tmp_path / "same.csv")
    _refused(code, err, "refusing to overwrite")
    other = tmp_path / "other.sqlite"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE t (x)")
    con.close()
    other_before = _digest(other)
    code, _, err = _run(capsys, "export", "--db", db, "--out", other, "--format", "parquet")
    _refused(code, err, "is an SQLite database")
    assert _digest(db) == before and _digest(other) == other_before


def test_exports_are_atomic_and_get_the_usual_permissions(db, tmp_path, capsys):
    old = os.umask(0o022)
    try:
        code, _, _ = _run(capsys, "export", "--db", db, "--out", tmp_path / "t.csv")
    finally:
        os.umask(old)
    assert code == 0
    assert (tmp_path / "t.csv").stat().st_mode & 0o777 == 0o644
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


# -- 2. never read a damaged database silently ---------------------------------------------------------------
def _overwrite(src: Path, dst: Path, offset: int, n: int = 256) -> None:
    shutil.copyfile(src, dst)
    with open(dst, "r+b") as fh:
        fh.seek(offset)
        fh.write(bytes([0xAB]) * n)


def test_the_issues_damaged_database_is_refused_with_a_way_out(study_db, tmp_path, capsys):
    bad = tmp_path / "bad.db"
    _overwrite(study_db, bad, 45100)
    before = _digest(bad)
    for argv in (["sessions", "--db", bad], ["export", "--db", bad, "--out", tmp_path / "t.csv"],
                 ["analyze", bad, "--out", tmp_path / "rep", "--n-boot", "0", "--no-figures"],
                 ["run", "seed003_task1", "--participant", "P1", "--simulate", "--db", bad, "--resume",
                  "--stimuli", tmp_path / "none"]):
        code, _, err = _run(capsys, *argv)
        _refused(code, err, "damaged", str(bad), "sqlite3", ".recover")
    assert _digest(bad) == before
    assert not (tmp_path / "t.csv").exists() and not (tmp_path / "rep").exists()


def test_every_damaged_page_is_refused_or_reads_back_exactly(study_db, tmp_path, capsys):
    """256 overwritten bytes anywhere: the export is refused, or identical to the undamaged one (damage in
    unused space). Never a shorter or altered log."""
    want = tmp_path / "want.csv"
    assert main(["export", "--db", str(study_db), "--out", str(want)]) == 0
    size = study_db.stat().st_size
    refused = same = 0
    for offset in range(0, size - 256, 512):
        bad = tmp_path / "bad.db"
        _overwrite(study_db, bad, offset)
        got = tmp_path / "got.csv"
        got.unlink(missing_ok=True)
        code, _, err = _run(capsys, "export", "--db", bad, "--out", got)
        if code == 0:
            assert got.read_bytes() == want.read_bytes(), f"offset {offset}: a damaged file read back altered"
            same += 1
        else:
            _refused(code, err)
            assert not got.exists()
            refused += 1
        for side in ("-wal", "-shm"):
            Path(str(bad) + side).unlink(missing_ok=True)
    assert refused > 0 and refused + same == len(range(0, size - 256, 512))


# -- 3. never write into a file that is not ours ------------------------------------------------------------
def _foreign_files(tmp_path: Path, study_db: Path) -> dict[str, Path]:
    empty = tmp_path / "empty.db"
    empty.write_bytes(b"")
    foreign = tmp_path / "foreign.db"
    con = sqlite3.connect(foreign)
    con.execute("CREATE TABLE notes (x)")
    con.execute("INSERT INTO notes VALUES (1)")
    con.commit()
    con.close()
    incomplete = tmp_path / "incomplete.db"
    shutil.copyfile(study_db, incomplete)
    con = sqlite3.connect(f"file:{incomplete}?mode=rw", uri=True)
    con.execute("PRAGMA journal_mode=DELETE")
    con.execute("DROP TABLE events")
    con.commit()
    con.close()
    text = tmp_path / "text.db"
    text.write_text("participant,response\nP1,1\n")
    return {"empty": empty, "foreign": foreign, "incomplete": incomplete, "text": text}


@pytest.mark.parametrize("kind,words", [("empty", "empty file"), ("foreign", "another application"),
                                        ("incomplete", "missing tables: events"), ("text", "not an SQLite")])
def test_files_that_are_not_our_databases_are_refused_untouched(study_db, tmp_path, capsys, kind, words):
    path = _foreign_files(tmp_path, study_db)[kind]
    before = _digest(path)
    for argv in (["sessions", "--db", path], ["export", "--db", path, "--out", tmp_path / "t.csv"],
                 ["analyze", path, "--out", tmp_path / "rep"],
                 ["run", "seed003_task1", "--participant", "P9", "--simulate", "--db", path,
                  "--stimuli", tmp_path / "none"],
                 ["run", "seed003_task1", "--participant", "P1", "--simulate", "--db", path, "--resume",
                  "--stimuli", tmp_path / "none"]):
        code, _, err = _run(capsys, *argv)
        _refused(code, err, words)
        assert _digest(path) == before
        assert not Path(str(path) + "-wal").exists() and not Path(str(path) + "-shm").exists()
        assert not (tmp_path / "t.csv").exists() and not (tmp_path / "rep").exists()


def test_only_run_creates_a_database_and_only_at_a_new_path(tmp_path, capsys):
    missing = tmp_path / "nothing.db"
    for argv in (["sessions", "--db", missing], ["export", "--db", missing, "--out", tmp_path / "t.csv"],
                 ["run", "seed003_task1", "--participant", "P1", "--simulate", "--db", missing, "--resume",
                  "--stimuli", tmp_path / "none"]):
        code, _, err = _run(capsys, *argv)
        _refused(code, err, "no such study database")
        assert not missing.exists()
    code, _, _ = _run(capsys, "run", "seed003_task2", "--participant", "P1", "--simulate", "--db", missing,
                      "--quiet", "--stimuli", tmp_path / "none")
    assert code == 0
    head = missing.read_bytes()[:100]
    assert int.from_bytes(head[68:72], "big") == S.APPLICATION_ID
    assert int.from_bytes(head[60:64], "big") == S.STORE_FORMAT


# -- 4. read-only media ------------------------------------------------------------------------------------
def test_read_commands_work_on_a_read_only_mount(db, tmp_path):
    """The database's folder bind-mounted read-only in a private mount namespace (root, as in CI)."""
    src, ro, out = db.parent, tmp_path / "ro", tmp_path / "out"
    ro.mkdir()
    out.mkdir()
    py = sys.executable
    script = (f"set -e; mount --bind {src} {ro}; mount -o remount,bind,ro {ro}; "
              f"! touch {ro}/probe 2>/dev/null; "
              f"{py} -m studyapp sessions --db {ro}/study.db > {out}/sessions.txt; "
              f"{py} -m studyapp export --db {ro}/study.db --out {out}/t.csv; "
              f"{py} -m studyapp analyze {ro}/study.db --out {out}/rep --n-boot 0 --no-figures")
    res = subprocess.run(["unshare", "-m", "sh", "-c", script], env=ENV, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    assert "P2-s1" in (out / "sessions.txt").read_text()
    assert len((out / "t.csv").read_text().splitlines()) == 1 + 114  # the issue's 114 rows
    assert (out / "rep" / "report.md").is_file()


# -- 5. resource bombs --------------------------------------------------------------------------------------
BOMB = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n"
    for p, c in zip("abcdefgh", "bcdefghi"))


@pytest.mark.parametrize("kind,text,words", [
    ("alias bomb", BOMB, "too many YAML nodes"),
    ("deep nesting", "x: " + "[" * 10000 + "]" * 10000 + "\n", "nested deeper than"),
    ("huge file", "# padding\n" + "unknown_key_0000000: 1\n" * 60000, "more than the 1 MB allowed"),
])
@pytest.mark.parametrize("what", ["protocol", "scene", "plan"])
def test_yaml_bombs_are_refused_in_under_a_second(tmp_path, capsys, kind, text, words, what):
    f = tmp_path / "bomb.yaml"
    f.write_text(text)
    argv = {"protocol": ["validate", f],
            "scene": ["render", "--scene", f, "--renderer", "gt", "--width", 8, "--height", 6,
                      "--out", tmp_path / "x.png"],
            "plan": ["analyze", ROOT / "tests" / "data" / "tiny_log.csv", "--plan", f, "--out", tmp_path / "r"]}[what]
    t0 = time.perf_counter()
    code, _, err = _run(capsys, *argv)
    assert time.perf_counter() - t0 < 1.0
    _refused(code, err, words, str(f))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bomb.yaml"]


# -- 6. options and values range-checked before anything is created ----------------------------------------
@pytest.mark.parametrize("argv,words", [
    (["run", "seed003_task2", "--participant", "P1", "--simulate", "--seed", str(2 ** 63)], "--seed=9223372036854775808 is out of range"),
    (["run", "seed003_task2", "--participant", "P1", "--simulate", "--seed", "-1"], "--seed=-1 is out of range"),
    (["run", "seed003_task2", "--participant", "P1", "--simulate", "--scale", "nan"], "--scale=nan is invalid"),
    (["prepare", "seed003_task2", "--scale", "inf"], "--scale=inf is invalid"),
    (["prepare", "seed003_task2", "--scale", "0"], "--scale=0 is out of range"),
    (["foveation", "table", "--fov-y", "nan"], "--fov-y=nan is invalid"),
])
def test_options_out_of_range_create_nothing(tmp_path, capsys, monkeypatch, argv, words):
    monkeypatch.chdir(tmp_path)
    code, _, err = _run(capsys, *argv, *(["--db", tmp_path / "s.db"] if argv[0] == "run" else []))
    _refused(code, err, words)
    assert list(tmp_path.iterdir()) == []


def test_quality_gaze_outside_the_image_is_refused(tmp_path, capsys):
    import numpy as np
    from PIL import Image

    img = tmp_path / "gt.png"
    Image.fromarray(np.zeros((20, 30, 3), np.uint8)).save(img)
    code, _, err = _run(capsys, "quality", "--gt", img, "--fov-y", "60", "--gaze=40,5", img)
    _refused(code, err, "outside the display")


def test_validate_checks_that_every_scene_exists(tmp_path, capsys):
    text = (ROOT / "protocols" / "seed001_2afc.yaml").read_text().replace(
        "scenes: [street_night, interior, temple]", "scenes: [street_night, interiour, temple]")
    f = tmp_path / "p.yaml"
    f.write_text(text)
    code, _, err = _run(capsys, "validate", f)
    _refused(code, err, "scenes[1]: unknown scene 'interiour'")
    (tmp_path / "interiour.yaml").write_text("not used: the scene file exists")
    code, out, _ = _run(capsys, "validate", f)
    assert code == 0 and "valid" in out


# -- 7. nothing half-written or left behind -----------------------------------------------------------------
def test_render_writes_the_png_and_the_linear_image_as_a_pair(tmp_path, capsys, monkeypatch):
    from renderers import stimuli

    def failing_png(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(stimuli, "save_png", failing_png)
    out = tmp_path / "x.png"
    code, _, err = _run(capsys, "render", "--scene", "cornell", "--renderer", "gt", "--width", 16,
                        "--height", 12, "--out", out)
    _refused(code, err, f"{out}: cannot write: no space left on device")
    assert list(tmp_path.iterdir()) == []

    def interrupted_png(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(stimuli, "save_png", interrupted_png)
    assert main(["render", "--scene", "cornell", "--renderer", "gt", "--width", "16", "--height", "12",
                 "--out", str(out)]) == 130
    assert list(tmp_path.iterdir()) == []


def test_refused_or_interrupted_runs_leave_no_database(tmp_path, capsys, monkeypatch):
    db = tmp_path / "s.db"
    code, _, err = _run(capsys, "run", "seed003_task2", "--participant", "bad id!", "--simulate", "--db", db)
    _refused(code, err, "--participant")
    from studyapp.runner import observer

    def ctrl_c(self, trial):
        raise KeyboardInterrupt

    monkeypatch.setattr(observer.SimulatedObserver, "instructions", ctrl_c)
    assert main(["run", "seed003_task2", "--participant", "P1", "--simulate", "--db", str(db), "--quiet",
                 "--stimuli", str(tmp_path / "none")]) == 130
    assert list(tmp_path.iterdir()) == []


def test_analyze_onto_a_full_disk_leaves_no_partial_report(db, tmp_path):
    """A real full disk: a 64 KB tmpfs mounted in a private mount namespace."""
    mnt = tmp_path / "small"
    mnt.mkdir()
    script = (f"mount -t tmpfs -o size=64k tmpfs {mnt} || exit 9; "
              f"if {sys.executable} -m studyapp analyze {db} --out {mnt}/report --n-boot 0; then echo unreachable; fi; "
              f"ls -A {mnt} > {tmp_path}/left.txt")
    res = subprocess.run(["unshare", "-m", "sh", "-c", script], env=ENV, capture_output=True, text=True,
                         timeout=300)
    assert "unreachable" not in res.stdout
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "no space left on device" in lines[0], res.stderr
    assert f"{mnt}/report" in lines[0] and ".tmp" not in lines[0]
    assert (tmp_path / "left.txt").read_text() == ""


# -- 8. sessions -------------------------------------------------------------------------------------------
def _start_slow_run(db: Path, tmp_path: Path, resume: bool) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "studyapp", "run", "seed001_2afc", "--participant", "P1", "--simulate",
           "--db", str(db), "--quiet", "--stimuli", str(tmp_path / "none"), "--sim-delay", "0.2"]
    return subprocess.Popen(cmd + (["--resume"] if resume else []), env=ENV, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _wait_answers(db: Path, n: int, timeout: float = 60.0) -> None:
    t0 = time.time()
    while time.time() - t0 < timeout:
        if db.exists():
            with S.open_store(db) as st:
                if st.participant("P1") and len(st.answered("P1")) >= n:
                    return
        time.sleep(0.1)
    raise AssertionError("the run did not answer in time")


def test_a_second_resume_is_refused_a_dead_session_shows_interrupted_and_sigterm_is_clean(tmp_path, capsys):
    db = tmp_path / "s.db"
    first = _start_slow_run(db, tmp_path, resume=False)
    try:
        _wait_answers(db, 2)
        with S.open_store(db) as st:
            n_sessions = len(st.sessions())
        second = subprocess.run([sys.executable, "-m", "studyapp", "run", "seed001_2afc", "--participant", "P1",
                                 "--simulate", "--db", str(db), "--resume", "--stimuli", str(tmp_path / "none")],
                                env=ENV, capture_output=True, text=True, timeout=120)
        _refused(second.returncode, second.stderr, "still running")
        with S.open_store(db) as st:
            assert len(st.sessions()) == n_sessions
            assert [s["status"] for s in st.sessions()] == ["running"]
    finally:
        first.kill()
        first.wait()
    with S.open_store(db) as st:  # killed: shown as interrupted, though the file still says running
        assert [s["status"] for s in st.sessions()] == ["interrupted"]
    code, out, _ = _run(capsys, "sessions", "--db", db)
    assert code == 0 and "interrupted" in out and "running" not in out
    # SIGTERM is handled like Ctrl-C: one line, the session marked, the database consistent.
    third = _start_slow_run(db, tmp_path, resume=True)
    answered = len(S.open_store(db).answered("P1"))
    _wait_answers(db, answered + 1)
    third.send_signal(signal.SIGTERM)
    _, err = third.communicate(timeout=60)
    assert third.returncode == 143
    assert err.strip().splitlines()[-1].startswith("studyapp: terminated") and "Traceback" not in err, err
    with S.open_store(db) as st:
        sessions = st.sessions()
    assert [s["status"] for s in sessions] == ["interrupted", "interrupted"]
    raw = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    assert [r[0] for r in raw.execute("SELECT status FROM sessions ORDER BY rowid")] == ["interrupted"] * 2
    raw.close()


# -- 10. mesh errors are one line -------------------------------------------------------------------------
@pytest.mark.parametrize("content", [b"", b"solid x\nfacet normal 0 0\nouter loop\nvertex 1 2\n"])
def test_a_corrupt_mesh_file_gives_one_line_without_vtk_noise(tmp_path, content):
    (tmp_path / "m.stl").write_bytes(content)
    (tmp_path / "s.yaml").write_text("meshes: [{file: m.stl}]\nlights: [{type: point, position: [0, 1, 0], "
                                     "intensity: [1, 1, 1]}]\ncamera: {position: [0, 0, -3], look_at: [0, 0, 0]}\n")
    res = subprocess.run([sys.executable, "-m", "studyapp", "render", "--scene", str(tmp_path / "s.yaml"),
                          "--renderer", "gt", "--width", "8", "--height", "6", "--out", str(tmp_path / "x.png")],
                         env=ENV, capture_output=True, text=True, timeout=120)
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and "meshes[0].file" in res.stderr, res.stderr
    assert not (tmp_path / "x.png").exists()
