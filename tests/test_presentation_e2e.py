"""End to end under Xvfb: `studyapp run PROTOCOL --participant p1 --db FILE` with a real PsychoPy window,
answers
given as real key presses (xdotool), then `studyapp export` must hold exactly those answers.

The CLI has no event hook, so the test watches the study database (WAL, readable while the runner writes): the
session row says the window is open; each committed response says the next trial is coming. A key pressed
during a black interval is discarded at stimulus onset, so an answer that did not arrive is pressed again.
"""

from __future__ import annotations

import csv
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent / "gui"))
import psychopy  # noqa: E402,F401 - the GUI tests need it: a missing install is a failure, not a skip
from xvfb import ROOT, Xvfb, missing_tools  # noqa: E402


@pytest.fixture(autouse=True)
def _gui_tools_installed():
    assert not missing_tools(), f"GUI tests need {missing_tools()} (Debian: xvfb, xdotool; ./run installs them)"

PROTOCOL = """\
schema_version: 1
name: gui_e2e
version: "1.0"
family: 2afc
instructions: "Press any key to start."
question: "Which one do you prefer? 1 = A, 2 = B"
display: {{width_px: 320, height_px: 240, width_cm: 30.0, distance_cm: 60.0, refresh_hz: 60}}
fixation: {{x: 0.5, y: 0.5}}
scenes: [room]
conditions:
  GT: {{folder: GT}}
  LOW: {{folder: LOW}}
  MID: {{folder: MID}}
stimulus: {{kind: image}}
timing: {{black_s: 0.2}}
design: {{conditions: [GT, LOW, MID], repetitions: 1, scene_order: fixed, trial_order: blocked}}
analysis: {{dv: chosen, unit: participant, test: bradley_terry}}
"""


def _count(db: Path, sql: str) -> int:
    if not db.exists():
        return 0
    try:
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1.0)
        try:
            return con.execute(sql).fetchone()[0]
        finally:
            con.close()
    except sqlite3.OperationalError:  # tables not created yet
        return 0


def _wait(pred, timeout_s: float, proc) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if pred():
            return True
        if proc.poll() is not None:
            return pred()
        time.sleep(0.05)
    return False


class StudyRun:
    """``studyapp run PROTOCOL --participant p1 --db DB`` under a private Xvfb, watched through its database.

    Entering waits for the session row (the window is open) and leaves the instructions with a space."""

    def __init__(self, proto: Path, db: Path, log: Path):
        self.proto, self.db, self.log = proto, db, log

    def __enter__(self) -> "StudyRun":
        self.x = Xvfb().__enter__()
        self.out = open(self.log, "w")
        self.proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "studyapp",
                "run",
                str(self.proto),
                "--participant",
                "p1",
                "--db",
                str(self.db),
            ],
            env=self.x.env,
            cwd=str(ROOT),
            stdout=self.out,
            stderr=subprocess.STDOUT,
        )
        try:
            assert self.reaches("SELECT count(*) FROM sessions", 1, 60), self.tail()
            time.sleep(1.0)
            self.x.key("space")  # leaves the instructions
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self.out.close()
        self.x.__exit__(None, None, None)

    def tail(self) -> str:
        return self.log.read_text()[-3000:]

    def reaches(self, sql: str, n: int, timeout_s: float) -> bool:
        return _wait(lambda: _count(self.db, sql) >= n, timeout_s, self.proc)

    def press_until(self, keys: list[str], sql: str, n: int, delay_s: float, what: str) -> None:
        """Press ``keys`` after ``delay_s`` until ``sql`` counts ``n`` (a key pressed in a black interval or
        before a screen is up is discarded, so pressing again is safe); at most 3 attempts."""
        for _ in range(3):
            time.sleep(delay_s)
            self.x.key(*keys)
            if self.reaches(sql, n, 4):
                return
        raise AssertionError(f"{what}:\n{self.tail()}")

    def finish(self) -> None:
        self.proc.wait(timeout=30)
        assert self.proc.returncode == 0, self.tail()


RESPONSES = "SELECT count(*) FROM responses"


def test_studyapp_run_with_a_window_records_the_pressed_keys(tmp_path):
    rng = np.random.default_rng(0)
    for cond in ("GT", "LOW", "MID"):
        (tmp_path / cond).mkdir()
        Image.fromarray(rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)).save(
            tmp_path / cond / "room.png"
        )
    proto = tmp_path / "gui_e2e.yaml"
    proto.write_text(PROTOCOL.format(root=tmp_path))
    db = tmp_path / "study.db"
    log = tmp_path / "run.log"
    # per trial: keys pressed before the answer (switches) and the answer key ("1" = A, "2" = B)
    plan = [(["Right"], "2"), ([], "1"), (["Right", "Left"], "1")]
    with StudyRun(proto, db, log) as run:
        for i, (switches, answer) in enumerate(plan):  # 0.8 s: past the 0.2 s black interval
            run.press_until([*switches, answer], RESPONSES, i + 1, 0.8, f"trial {i} got no answer")
        run.finish()
    out_csv = tmp_path / "log.csv"
    exp = subprocess.run(
        [
            sys.executable,
            "-m",
            "studyapp",
            "export",
            "--db",
            str(db),
            "--format",
            "csv",
            "--out",
            str(out_csv),
        ],
        cwd=str(ROOT),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert exp.returncode == 0, exp.stderr
    rows = sorted(csv.DictReader(out_csv.open()), key=lambda r: int(r["trial"]))
    assert len(rows) == 3
    for row, (_, answer) in zip(rows, plan):
        assert row["participant"] == "p1" and row["family"] == "2afc" and row["scene"] == "room"
        assert row["chosen"] == (row["condition_a"] if answer == "1" else row["condition_b"])
        assert float(row["rt_s"]) > 0
    assert {frozenset((r["condition_a"], r["condition_b"])) for r in rows} == {
        frozenset(p) for p in (("GT", "LOW"), ("GT", "MID"), ("LOW", "MID"))
    }
    con = sqlite3.connect(db)
    sess = con.execute("SELECT keyboard_backend, presenter, status FROM sessions").fetchall()
    switches = [r[0] for r in con.execute("SELECT switches FROM responses ORDER BY idx")]
    con.close()
    assert sess == [("ptb", "PsychoPyPresenter", "completed")]
    assert switches == [len(s) for s, _ in plan]


SEQ_PROTOCOL = """\
schema_version: 1
name: gui_e2e_seq
version: "1.0"
family: yes_no
instructions: "Press any key to start."
question: "Is this sequence the ground truth? Y = yes, N = no"
display: {{width_px: 320, height_px: 240, width_cm: 30.0, distance_cm: 60.0, refresh_hz: 60}}
fixation: {{x: 0.25, y: 0.5}}
scenes: [room]
conditions:
  GT: {{folder: GT}}
  LOW: {{folder: LOW}}
stimulus: {{kind: sequence, duration_s: 0.6, fps: 5}}
timing: {{black_s: 0.2}}
design: {{conditions: [GT, LOW], repetitions: 1, scene_order: fixed, trial_order: blocked,
          reference: {{condition: GT, label: "This is the ground truth"}}}}
analysis: {{dv: response, unit: trial, test: summary_table}}
"""


def test_studyapp_run_sequences_reference_and_escape_resume(tmp_path):
    """Seed 003 Task 1 in small: the labelled GT reference plays by itself, then yes/no sequences; Escape
    during
    the second one pauses, R resumes it; the export holds the pressed answers, the events the pause and
    resume."""
    rng = np.random.default_rng(1)
    for cond in ("GT", "LOW"):
        (tmp_path / cond / "room").mkdir(parents=True)
        for i in range(3):
            Image.fromarray(rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)).save(
                tmp_path / cond / "room" / f"f{i}.png"
            )
    proto = tmp_path / "gui_e2e_seq.yaml"
    proto.write_text(SEQ_PROTOCOL.format(root=tmp_path))
    db = tmp_path / "study.db"
    log = tmp_path / "run.log"
    with StudyRun(proto, db, log) as run:
        assert run.reaches(RESPONSES, 1, 10), "the reference did not end by itself"
        run.press_until(["y"], RESPONSES, 2, 1.0, "trial 1 got no answer")
        # Escape while the next sequence plays -> pause screen -> R (the pause screen clears the key queue)
        run.press_until(["Escape"], "SELECT count(*) FROM events WHERE kind = 'pause'", 1, 0.45, "no pause")
        run.press_until(["r"], "SELECT count(*) FROM events WHERE kind = 'resume'", 1, 0.3, "no resume")
        run.press_until(["n"], RESPONSES, 3, 1.0, "trial 2 got no answer")
        run.finish()
    con = sqlite3.connect(db)
    rows = con.execute(
        "SELECT r.idx, p.kind, p.conditions, r.response, r.rt_s FROM responses r JOIN planned_trials"
        " p ON p.participant = r.participant AND p.idx = r.idx ORDER BY r.idx"
    ).fetchall()
    kinds = [r[0] for r in con.execute("SELECT kind FROM events ORDER BY id")]
    con.close()
    assert [r[1] for r in rows] == ["reference", "trial", "trial"]
    assert "GT" in rows[0][2]
    assert [r[3] for r in rows[1:]] == [1, 0]  # y, then n
    assert all(r[4] > 0 for r in rows[1:])
    assert kinds.count("pause") == 1 and kinds.count("resume") == 1 and "end" not in kinds
