"""Session store: durability settings, no duplicates, protocol binding, full disk, exports in the contract."""

import csv
import sqlite3

import pandas as pd
import pytest

from data_schema import store as S
from data_schema.store import PlannedRow, StoreError, open_store
from data_schema.trial_log import ALL_COLUMNS

H = "a" * 64


def _study(path, n=6, family="2afc"):
    st = open_store(path, "create")
    st.bind_protocol("p", "1.0", H, {"name": "p", "family": family,
                                      "analysis": {"dv": "chosen", "unit": "participant", "test": "thurstone"}})
    rows = [PlannedRow(i, "catch" if i == n - 1 else "trial", family, f"s{i % 2}", "hmd",
                       ("x", "y") if family == "2afc" else ("x",), "A" if i == n - 1 else "", False)
            for i in range(n)]
    st.enrol("P1", 1, 0, "b" * 64, rows)
    sid = st.start_session("P1", H, 0, {"studyapp": "t"}, {"width_px": 10}, {"refresh_hz": 60.0}, "test")
    return st, sid


def test_wal_and_synchronous_full(tmp_path):
    st, _ = _study(tmp_path / "s.db")
    assert st.conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert st.conn.execute("PRAGMA synchronous").fetchone()[0] == 2  # FULL
    st.close()


def test_responses_are_unique_and_survive_reopening(tmp_path):
    db = tmp_path / "s.db"
    st, sid = _study(db)
    st.commit_response("P1", 0, sid, ["A"], chosen="x", rt_s=0.7, onset_s=1.0)
    with pytest.raises(StoreError, match="could not save the response to trial 0 of participant 'P1'"):
        st.commit_response("P1", 0, sid, ["B"], chosen="y", rt_s=0.5, onset_s=2.0)
    st.close()
    with open_store(db) as st2:
        rows = st2.conn.execute("SELECT idx, chosen, rt_s FROM responses").fetchall()
        assert rows == [(0, "x", 0.7)]
        assert st2.first_unanswered("P1") == 1
        assert st2.answered("P1") == {0}


def test_a_response_needs_a_planned_trial(tmp_path):
    st, sid = _study(tmp_path / "s.db")
    with pytest.raises(StoreError, match="FOREIGN KEY"):
        st.commit_response("P1", 99, sid, ["A"], chosen="x")
    st.close()


def test_different_protocol_is_refused(tmp_path):
    db = tmp_path / "s.db"
    st, _ = _study(db)
    st.close()
    with open_store(db, "write") as st2:
        st2.bind_protocol("p", "1.0", H, {})  # same hash: fine
        with pytest.raises(StoreError) as info:
            st2.bind_protocol("p", "1.1", "c" * 64, {})
    msg = str(info.value)
    assert "written by protocol 'p' version '1.0' (sha256 aaaaaaaaaaaa)" in msg and "'1.1'" in msg


def test_foreign_file_and_missing_db(tmp_path):
    other = tmp_path / "other.db"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE t (x)")
    con.commit()
    con.close()
    with pytest.raises(StoreError, match="another application"):
        open_store(other)
    junk = tmp_path / "junk.db"
    junk.write_bytes(b"hello, not sqlite at all" * 100)
    with pytest.raises(StoreError, match="not an SQLite file"):
        open_store(junk)
    with pytest.raises(StoreError, match="no such study database"):
        S.read_trials(tmp_path / "none.db")


def test_full_disk_rolls_back_and_keeps_what_was_recorded(tmp_path):
    db = tmp_path / "s.db"
    st, sid = _study(db, n=400)
    st.commit_response("P1", 0, sid, ["A"], chosen="x", rt_s=0.5)
    pages = st.conn.execute("PRAGMA page_count").fetchone()[0]
    st.conn.execute(f"PRAGMA max_page_count = {pages}")  # the 'disk' is now full
    with pytest.raises(StoreError) as info:
        for i in range(1, 400):
            st.commit_response("P1", i, sid, ["B"], chosen="y" * 500, rt_s=0.5)
    assert "no space left on device" in str(info.value) and "\n" not in str(info.value)
    st.close()
    with open_store(db) as st2:
        n = st2.conn.execute("SELECT COUNT(*) FROM responses").fetchone()[0]
        assert st2.conn.execute("SELECT chosen FROM responses WHERE idx = 0").fetchone()[0] == "x"
        assert 1 <= n < 400
        assert st2.conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"


def test_enospc_from_the_os_is_reported_as_disk_full(tmp_path, monkeypatch):
    import errno

    st, sid = _study(tmp_path / "s.db")

    class Boom:
        def __init__(self, conn):
            self.conn = conn

        def execute(self, sql, *a):
            if sql.startswith("INSERT INTO responses"):
                raise OSError(errno.ENOSPC, "No space left on device")
            return self.conn.execute(sql, *a)

    st.conn = Boom(st.conn)
    with pytest.raises(StoreError, match="no space left on device: could not save the response to trial 1"):
        st.commit_response("P1", 1, sid, ["A"], chosen="x")
    assert st.conn.conn.execute("SELECT COUNT(*) FROM responses").fetchone()[0] == 0
    st.conn.conn.close()


def _filled(tmp_path, family="2afc"):
    db = tmp_path / f"{family}.db"
    st, sid = _study(db, family=family)
    for i in range(6):
        if family == "2afc":
            st.commit_response("P1", i, sid, ["A" if i % 3 else "B"], chosen="x" if i % 3 else "y", rt_s=0.25 * i,
                               correct=(i % 3 > 0) if i == 5 else None)
        else:
            st.commit_response("P1", i, sid, ["yes" if i % 2 else "no"], response=i % 2, rt_s=None)
    st.end_session(sid, "completed")
    st.close()
    return db


def test_tidy_csv_has_exactly_the_contract_columns(tmp_path):
    db = _filled(tmp_path)
    out = S.export_csv(db, tmp_path / "t.csv")
    rows = list(csv.reader(out.open()))
    assert tuple(rows[0]) == ALL_COLUMNS
    assert len(rows) == 7
    r1 = dict(zip(rows[0], rows[2]))
    assert (r1["participant"], r1["session"], r1["block"], r1["trial"], r1["family"]) == ("P1", "P1-s1", "hmd", "1", "2afc")
    assert (r1["condition_a"], r1["condition_b"], r1["chosen"], r1["response"], r1["rt_s"]) == ("x", "y", "x", "", "0.25")
    assert dict(zip(rows[0], rows[6]))["catch"] == "1"
    assert out.read_bytes() == S.export_csv(db, tmp_path / "t2.csv").read_bytes()


def test_read_trials_parquet_and_yes_no(tmp_path):
    db = _filled(tmp_path, "yes_no")
    df = S.read_trials(db)
    assert tuple(df.columns) == ALL_COLUMNS
    assert df["response"].tolist() == [0.0, 1.0, 0.0, 1.0, 0.0, 1.0]
    assert df["rt_s"].isna().all() and df["condition"].eq("x").all() and df["chosen"].eq("").all()
    assert df["trial"].dtype == "int64" and df["catch"].tolist() == [0, 0, 0, 0, 0, 1]
    out = S.export_parquet(db, tmp_path / "t.parquet")
    back = pd.read_parquet(out)
    pd.testing.assert_frame_equal(back, df)


def test_pwcmp_layout(tmp_path):
    db = _filled(tmp_path)
    out = S.export_pwcmp(db, tmp_path / "pw.csv")
    rows = list(csv.reader(out.open()))
    assert rows[0] == ["observer", "session", "scene", "condition_1", "condition_2", "selection"]
    # catch trial 5 is left out; trial 0 chose y = condition_2.
    assert [r[5] for r in rows[1:]] == ["2", "1", "1", "2", "1"]
    with pytest.raises(StoreError, match="no 2afc trials"):
        S.export_pwcmp(_filled(tmp_path, "yes_no"), tmp_path / "pw2.csv")


def test_pwcmp_takes_its_columns_from_the_family(tmp_path, monkeypatch):
    """The exporter asks the family which tidy columns are the pair and the pick (``export_columns``): declared
    the other way round, condition_1 and condition_2 swap and the selection follows; a family that declares no
    pwcmp layout has no trials to export."""
    from data_schema import families

    db = _filled(tmp_path)
    two = type(families.get("2afc"))
    monkeypatch.setattr(two, "export_columns", {"pwcmp": ("condition_b", "condition_a", "chosen")})
    rows = list(csv.reader(S.export_pwcmp(db, tmp_path / "swapped.csv").open()))
    assert [r[3:] for r in rows[1:3]] == [["y", "x", "1"], ["y", "x", "2"]]
    monkeypatch.setattr(two, "export_columns", {})
    with pytest.raises(StoreError, match=r"no paired-comparison trials to export in the pwcmp layout"):
        S.export_pwcmp(db, tmp_path / "none.csv")


def test_analysis_plan_and_sessions(tmp_path):
    db = _filled(tmp_path)
    plan = S.read_analysis_plan(db)
    assert plan["dv"] == "chosen" and plan["test"] == "thurstone" and plan["family"] == "2afc"
    assert "conditions" not in plan  # the test protocol has no conditions block
    with open_store(db) as st:
        [s] = st.sessions()
        assert (s["id"], s["status"], s["responses"]) == ("P1-s1", "completed", 6)
        assert st.progress() == [{"participant": "P1", "planned": 6, "answered": 6, "catch_planned": 1,
                                  "catch_correct": 1}]


def test_commit_latency_helper_commits_every_response(tmp_path):
    from benchmarks.bench_runner import timed_commit_latencies

    lat = timed_commit_latencies(tmp_path / "b.db", n=20)
    assert len(lat) == 20 and min(lat) > 0
    with open_store(tmp_path / "b.db") as st:
        assert st.conn.execute("SELECT COUNT(*) FROM responses").fetchone()[0] == 20


def test_a_negative_zero_logged_reads_back_undamaged(tmp_path):
    """SQLite keeps no sign on a REAL zero: a frame logged with -0.0 (a gaze at the window's left edge, a camera
    coordinate) reads back as 0.0, and its row checksum must still hold, else the whole study is refused."""
    import math

    from tests.crafted_db import live_db, live_protocol

    db = live_db(live_protocol(tmp_path / "p"), tmp_path / "z.db", frames_per_stimulus=2, gaze=(-0.0, -0.0))
    with open_store(db) as st:
        frames = st.frames("P1")
        rows = st.tidy_rows()
    assert frames and all(f["gaze_x"] == 0.0 and math.copysign(1.0, f["gaze_x"]) == 1.0 for f in frames)
    assert len(rows) == len({f["idx"] for f in frames})


def test_the_store_names_no_trial_family():
    """The store asks the family (``families.get(name)``) and never branches on a family's name: no string in
    data_schema/store/ (docstrings included) holds one."""
    import ast
    import re
    from pathlib import Path

    from data_schema import families

    names = re.compile(r"\b(" + "|".join(map(re.escape, families.NAMES)) + r")\b", re.IGNORECASE)
    found = [f"{path.name}:{node.lineno}: {node.value[:60]!r}"
             for path in sorted((Path(S.__file__).parent).glob("*.py"))
             for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
             if isinstance(node, ast.Constant) and isinstance(node.value, str) and names.search(node.value)]
    assert found == []
