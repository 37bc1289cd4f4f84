"""Fuzzing crafted frame rows (issue 25, item 10): values of every type with valid checksums.

Hypothesis changes one to three fields of a frame row of a small live database (tests/crafted_db.py) to None,
text, bytes, negative, huge or non-finite numbers, recomputes the row's checksum so that the file passes every
integrity check, and runs ``export --format frames``, ``sessions`` and ``replay`` (in process, --serial, the
first rendered frame only: every row of the trial is still read and checked). Each must end with exit 0 and
nothing on stderr but the progress bar, or exit 2 and exactly one ``studyapp: error:`` line naming the
database; an exception escaping ``main`` fails the test with its traceback. Bounded to a few seconds.
"""

from __future__ import annotations

import shutil

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from crafted_db import craft, live_db, live_protocol
from data_schema.store import COLUMNS
from studyapp.cli import main

VALUES = st.one_of(
    st.none(), st.text(max_size=8), st.binary(max_size=4), st.booleans(),
    st.integers(-(2 ** 63), 2 ** 63 - 1), st.sampled_from([-1, 0, 1, 2, 3, 2 ** 31, -(2 ** 63)]),
    st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([float("nan"), float("inf"), -1e300, 1e300,
                                                                     -0.5, 0.5, 1e9, 1e6 + 1]))
FIELDS = st.lists(st.sampled_from([c for c in COLUMNS["frames"] if c != "participant"]), min_size=1, max_size=3,
                  unique=True)


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz_frames")
    return live_db(live_protocol(folder / "proto"), folder / "base.db")


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                 HealthCheck.too_slow])
@given(frame=st.integers(0, 5), fields=FIELDS, data=st.data())
def test_crafted_frame_rows_give_exit_0_or_one_line(base, tmp_path_factory, capsys, frame, fields, data):
    work = tmp_path_factory.mktemp("ex")
    db = work / "s.db"
    shutil.copy(base, db)
    changes = {f: data.draw(VALUES, label=f) for f in fields}
    try:
        craft(db, "frames", {"idx": 0, "frame": frame}, changes)
    except Exception:  # noqa: BLE001 - SQLite refused the value itself (a constraint): nothing to read back
        return
    for argv in (["export", "--db", db, "--format", "frames", "--out", work / "f.csv"], ["sessions", "--db", db],
                 ["replay", "--db", db, "--participant", "P1", "--trial", "0", "--out", work / "rep", "--serial",
                  "--every", "1000", "--cache", base.parent / "cache"]):
        capsys.readouterr()
        code = main([str(a) for a in argv])
        err = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("frames:")]
        if code == 0:
            assert err == [], (argv[0], changes, err)
        else:
            assert code == 2 and len(err) == 1 and err[0].startswith(f"studyapp: error: {db}"), (argv[0], changes,
                                                                                                  err)
