"""``studyapp export --format frames`` streams (issue 25, item 9): the same file as a whole-table export, in
memory that does not grow with the frames table."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pandas as pd
import pyarrow.parquet as pq
import pytest

from benchmarks.bench_export import synthetic_frames_study
from data_schema import store
from data_schema.store import PlannedRow, frames_export, open_store

ROOT = Path(__file__).resolve().parents[1]
BLOCK = store.FRAMES_BLOCK_ROWS


def whole_table_export(db, out: Path) -> None:
    """The export as it was before streaming: every frame in one DataFrame (the reference)."""
    with open_store(db) as st:
        rows = st.frames()
    df = pd.DataFrame(rows).rename(columns={"idx": "trial"})
    df["gaze_age_ms"] = (df["flip_s"] - df["gaze_t"]) * 1000.0
    if out.suffix == ".csv":
        df.to_csv(out, index=False, lineterminator="\n")
    else:
        df.to_parquet(out, index=False)


@pytest.fixture(scope="module")
def crafted_db(tmp_path_factory):
    """Synthetic live trials, and a participant whose frames hold awkward reals (within what studyapp logs):
    tiny, subnormal, many digits, 0.1 + 0.2, a render time of 0, gaze on one flip only, an id CSV must quote.
    (Not -0.0: SQLite stores it as 0.0, and the row then fails its checksum; a bug of the insert path.)"""
    db = synthetic_frames_study(tmp_path_factory.mktemp("frames") / "study.db", 1000, per_trial=300,
                                trials_per_participant=3)
    reals = [1e-300, 999999999.9999999, 0.0, 123456789.12345679, 0.1 + 0.2, 5e-324, 1e8, 2.5e-7]
    with open_store(db, "write") as st:
        st.enrol('Z,"9"', 0, 0, "0" * 64, [PlannedRow(0, "trial", "2afc", "hall", "", ("A", "B"), "", False)])
        sid = st.start_session('Z,"9"', "0" * 64, 0, {}, {}, {}, "synthetic")
        flips = [SimpleNamespace(frame=k, stimulus=k % 2, flip_s=x, render_s=0.0 if k == 3 else x * 0.5,
                                 gaze_t=x - 0.004 if k == 5 else None, gaze_x=960.5 if k == 5 else None,
                                 gaze_y=540.25 if k == 5 else None, position=(x, 1.6, 1.0),
                                 look_at=(0.0, 0.0, 2.0), dropped=k == 7) for k, x in enumerate(reals)]
        st.commit_response('Z,"9"', 0, sid, ["A"], chosen="LaFR", rt_s=0.8, onset_s=1.0, frames=flips)
    return db


@pytest.mark.parametrize("block", [BLOCK, 7])
def test_streamed_frames_export_is_the_whole_table_export(crafted_db, tmp_path, monkeypatch, block):
    monkeypatch.setattr(frames_export, "FRAMES_BLOCK_ROWS", block)
    if block == 7:  # row groups of 3 blocks
        monkeypatch.setattr(frames_export, "FRAMES_ROW_GROUP_ROWS", 20)
    for suffix in (".csv", ".parquet"):
        old, new = tmp_path / f"old{suffix}", tmp_path / f"new{suffix}"
        whole_table_export(crafted_db, old)
        assert store.export_frames(crafted_db, new) == new
        if suffix == ".csv" or block == BLOCK:  # one block: one row group, the same bytes
            assert new.read_bytes() == old.read_bytes()
        if suffix == ".parquet":  # blocks of 7: row groups of 21 rows, the same schema and values
            a, b = pq.read_table(old), pq.read_table(new)
            assert b.schema.equals(a.schema, check_metadata=True) and b.equals(a)
            assert pq.ParquetFile(new).metadata.num_row_groups == (1 if block == BLOCK else 1008 // 21)
            pd.testing.assert_frame_equal(pd.read_parquet(new), pd.read_parquet(old))
    df = pd.read_parquet(tmp_path / "new.parquet")
    assert len(df) == 1008 and list(df.columns[:3]) == ["participant", "trial", "frame"]
    z = df[df["participant"] == 'Z,"9"']
    assert z["pos_x"].tolist()[:3] == [1e-300, 999999999.9999999, 0.0]
    assert z["gaze_age_ms"].notna().sum() == 1 and z["gaze_age_ms"].dropna().iloc[0] == pytest.approx(4.0)


def test_a_frame_value_studyapp_never_logs_is_one_line_and_nothing_is_written(crafted_db, tmp_path):
    import shutil
    import sqlite3

    db = tmp_path / "bad.db"
    shutil.copyfile(crafted_db, db)
    with sqlite3.connect(db) as conn:  # a text stimulus index with a valid checksum: crafted, not damaged
        row = conn.execute(f"SELECT {', '.join(store.COLUMNS['frames'])} FROM frames LIMIT 1").fetchone()
        new = (*row[:3], "one", *row[4:])
        conn.execute("UPDATE frames SET stimulus = ?, crc = ? WHERE participant = ? AND idx = ? AND frame = ?",
                     ("one", store.row_crc("frames", new), *row[:3]))
    with pytest.raises(store.StoreError, match=r"bad\.db: .*stimulus='one'"):
        store.export_frames(db, tmp_path / "out.parquet")
    assert [f for f in os.listdir(tmp_path) if not f.startswith("bad.db")] == []  # no output, no temporary


CHILD = """
import resource, sys
from data_schema.store import frames_export
frames_export.FRAMES_BLOCK_ROWS, frames_export.FRAMES_ROW_GROUP_ROWS = 4096, 8192
frames_export.export_frames(sys.argv[1], sys.argv[2])
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def test_frames_export_memory_does_not_grow_with_the_rows(tmp_path):
    """Peak RSS of a child exporting 20,000 and 80,000 frames in blocks of 4,096 and row groups of 8,192: the
    same within 15 MB (the whole-table export grows by ~75 MB between the two; the CSV path streams the same
    blocks)."""
    peaks = {}
    for n in (20_000, 80_000):
        db = synthetic_frames_study(tmp_path / f"{n}.db", n)
        out = tmp_path / f"out{n}.parquet"
        r = subprocess.run([sys.executable, "-c", CHILD, str(db), str(out)], capture_output=True, text=True,
                           timeout=120, check=False, env={**os.environ, "PYTHONPATH": str(ROOT)})
        assert r.returncode == 0, r.stderr
        peaks[n] = int(r.stdout.split()[-1]) / 1024  # ru_maxrss: KiB on Linux
        assert len(pq.read_table(out)) == n
    assert peaks[80_000] - peaks[20_000] < 15, peaks
