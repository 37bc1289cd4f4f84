"""The tables of a study database and how a row is written: the schema, every row's checksum, the rows the
session store commits (:class:`PlannedRow`, :class:`AdaptiveRow`) and its one-line error (:class:`StoreError`)."""

from __future__ import annotations

import errno
import hashlib
import json
import math
import sqlite3
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

from ..errors import UserError

STORE_FORMAT = 2
#: SQLite ``application_id`` of a study database ("stdy"): the marker that tells our files from any other.
APPLICATION_ID = int.from_bytes(b"stdy", "big")
WAL_AUTOCHECKPOINT_PAGES = 10000
SQLITE_MAGIC = b"SQLite format 3\x00"

#: Columns of every table, in storage order; each table also has a ``crc`` column (see :func:`row_crc`).
COLUMNS = {
    "study": ("key", "value"),
    "participants": ("id", "counterbalance", "seed", "schedule_hash", "n_planned", "created_utc", "enrol_order",
                     "n_answered", "n_frames"),
    "sessions": ("id", "participant", "protocol_hash", "software", "display", "measured_refresh_hz",
                 "keyboard_backend", "presenter", "seed", "started_utc", "ended_utc", "status", "resumed_from",
                 "process", "validation_deg"),
    "planned_trials": ("participant", "idx", "kind", "family", "scene", "block", "conditions", "expected",
                       "break_before"),
    "responses": ("participant", "idx", "session", "answers", "chosen", "chosen_2", "response", "rt_s",
                  "onset_s", "dropped_frames", "switches", "gaze_left_fovea", "correct", "committed_utc"),
    "events": ("id", "session", "t_utc", "kind", "detail"),
    "adaptive": ("participant", "idx", "procedure", "varied", "level", "intensity", "correct", "estimate_mean",
                 "estimate_sd", "state", "skipped"),
    "frames": ("participant", "idx", "frame", "stimulus", "flip_s", "render_s", "gaze_t", "gaze_x", "gaze_y",
               "pos_x", "pos_y", "pos_z", "look_x", "look_y", "look_z", "dropped"),
}
PRIMARY_KEYS = {"study": ("key",), "participants": ("id",), "sessions": ("id",), "planned_trials": ("participant", "idx"),
                "responses": ("participant", "idx"), "events": ("id",), "adaptive": ("participant", "idx"),
                "frames": ("participant", "idx", "frame")}

SCHEMA = """
CREATE TABLE study (key TEXT PRIMARY KEY, value TEXT NOT NULL, crc TEXT NOT NULL);
CREATE TABLE participants (
    id TEXT PRIMARY KEY, counterbalance INTEGER NOT NULL, seed INTEGER NOT NULL, schedule_hash TEXT NOT NULL,
    n_planned INTEGER NOT NULL, created_utc TEXT NOT NULL, enrol_order INTEGER NOT NULL,
    n_answered INTEGER NOT NULL, n_frames INTEGER NOT NULL, crc TEXT NOT NULL);
CREATE TABLE sessions (
    id TEXT PRIMARY KEY, participant TEXT NOT NULL REFERENCES participants(id), protocol_hash TEXT NOT NULL,
    software TEXT NOT NULL, display TEXT NOT NULL, measured_refresh_hz REAL, keyboard_backend TEXT,
    presenter TEXT NOT NULL, seed INTEGER NOT NULL, started_utc TEXT NOT NULL, ended_utc TEXT,
    status TEXT NOT NULL, resumed_from TEXT REFERENCES sessions(id), process TEXT NOT NULL, validation_deg REAL,
    crc TEXT NOT NULL);
CREATE TABLE planned_trials (
    participant TEXT NOT NULL REFERENCES participants(id), idx INTEGER NOT NULL, kind TEXT NOT NULL,
    family TEXT NOT NULL, scene TEXT NOT NULL, block TEXT NOT NULL, conditions TEXT NOT NULL,
    expected TEXT NOT NULL, break_before INTEGER NOT NULL, crc TEXT NOT NULL,
    PRIMARY KEY (participant, idx)) WITHOUT ROWID;
CREATE TABLE responses (
    participant TEXT NOT NULL, idx INTEGER NOT NULL, session TEXT NOT NULL REFERENCES sessions(id),
    answers TEXT NOT NULL, chosen TEXT NOT NULL, chosen_2 TEXT NOT NULL, response INTEGER,
    rt_s REAL, onset_s REAL, dropped_frames INTEGER NOT NULL, switches INTEGER NOT NULL,
    gaze_left_fovea INTEGER, correct INTEGER, committed_utc TEXT NOT NULL, crc TEXT NOT NULL,
    PRIMARY KEY (participant, idx),
    FOREIGN KEY (participant, idx) REFERENCES planned_trials(participant, idx)) WITHOUT ROWID;
CREATE TABLE events (
    id INTEGER PRIMARY KEY, session TEXT NOT NULL REFERENCES sessions(id), t_utc TEXT NOT NULL,
    kind TEXT NOT NULL, detail TEXT NOT NULL, crc TEXT NOT NULL);
CREATE TABLE frames (
    participant TEXT NOT NULL, idx INTEGER NOT NULL, frame INTEGER NOT NULL, stimulus INTEGER NOT NULL,
    flip_s REAL NOT NULL, render_s REAL, gaze_t REAL, gaze_x REAL, gaze_y REAL, pos_x REAL, pos_y REAL,
    pos_z REAL, look_x REAL, look_y REAL, look_z REAL, dropped INTEGER NOT NULL, crc TEXT NOT NULL,
    PRIMARY KEY (participant, idx, frame),
    FOREIGN KEY (participant, idx) REFERENCES responses(participant, idx)) WITHOUT ROWID;
"""


#: The ``adaptive`` table, created by the first adaptive trial's commit (a study without adaptive trials keeps the
#: file layout it had before the table existed).
ADAPTIVE_SCHEMA = """
CREATE TABLE IF NOT EXISTS adaptive (
    participant TEXT NOT NULL, idx INTEGER NOT NULL, procedure TEXT NOT NULL, varied TEXT NOT NULL,
    level REAL NOT NULL, intensity REAL NOT NULL, correct INTEGER, estimate_mean REAL, estimate_sd REAL,
    state TEXT NOT NULL,
    skipped INTEGER NOT NULL, crc TEXT NOT NULL,
    PRIMARY KEY (participant, idx),
    FOREIGN KEY (participant, idx) REFERENCES responses(participant, idx)) WITHOUT ROWID;
"""

#: Tables a database may lack (written before them, or without adaptive trials): read as empty.
OPTIONAL_TABLES = ("adaptive",)



@dataclass(frozen=True)
class AdaptiveRow:
    """What an adaptive trial adds to its response (:meth:`Store.commit_response`; the ``adaptive`` table)."""

    procedure: str
    varied: str
    level: float
    intensity: float  # the level on the procedure's axis (data_schema.intensity.Axis.to_intensity)
    correct: bool | None  # None: skipped (the procedure had stopped)
    estimate_mean: float | None
    estimate_sd: float | None
    state: str  # JSON: the procedure's state after this trial
    skipped: bool = False


class StoreError(UserError):
    """The store cannot do what was asked; one line naming the file and the problem."""


def utc_now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def row_crc(table: str, values: Sequence) -> str:
    """Checksum of one row: the first 16 hex digits of SHA-256 over the canonical JSON of ``[table, *values]``.

    SQLite's own checks (``quick_check``) see the structure of the file, not the bytes of a record: 256
    overwritten bytes inside a page of answers pass them and change what is read. Every row carries this
    checksum, and every read verifies it (:func:`verify`), so damaged data is refused instead of analysed.
    """
    # SQLite stores -0.0 as 0.0 (a REAL zero keeps no sign): the sum is over what is read back, so -0.0 counts
    # as 0.0, else a row logged with -0.0 (a camera coordinate) would read back as damaged.
    values = [0.0 if isinstance(v, float) and v == 0.0 else v for v in values]
    text = json.dumps([table, *values], separators=(",", ":"), ensure_ascii=True, allow_nan=True)
    return hashlib.sha256(text.encode("ascii")).hexdigest()[:16]


def _insert(conn, table: str, values: Sequence) -> None:
    cols = COLUMNS[table]
    if len(values) != len(cols):
        raise ValueError(f"{table}: {len(values)} values for {len(cols)} columns")
    conn.execute(f"INSERT INTO {table} ({', '.join(cols)}, crc) VALUES ({', '.join('?' * (len(cols) + 1))})",
                 (*values, row_crc(table, values)))


def _update(conn, table: str, key: dict, changes: dict) -> int:
    """Update the rows matching ``key`` (column -> value) with ``changes``, re-computing their checksums."""
    cols = COLUMNS[table]
    pk = PRIMARY_KEYS[table]
    where = " AND ".join(f"{k} = ?" for k in key)
    rows = conn.execute(f"SELECT {', '.join(cols)} FROM {table} WHERE {where}", tuple(key.values())).fetchall()
    for row in rows:
        old = dict(zip(cols, row))
        new = tuple(changes.get(c, old[c]) for c in cols)
        conn.execute(f"UPDATE {table} SET {', '.join(f'{c} = ?' for c in cols)}, crc = ? WHERE "
                     + " AND ".join(f"{k} = ?" for k in pk), (*new, row_crc(table, new), *(old[k] for k in pk)))
    return len(rows)


@dataclass(frozen=True)
class PlannedRow:
    """A planned trial as stored (mirrors :class:`studyapp.runner.schedule.PlannedTrial`)."""

    idx: int
    kind: str
    family: str
    scene: str
    block: str
    conditions: tuple[str, ...]
    expected: str
    break_before: bool


def _real(x) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else float(x)


def _frame_values(f) -> tuple:
    """A logged flip (:class:`studyapp.runner.live.FrameRecord`-like) as the frames table's columns after
    ``participant`` and ``idx``."""
    return (int(f.frame), int(f.stimulus), float(f.flip_s), _real(f.render_s), _real(f.gaze_t), _real(f.gaze_x),
            _real(f.gaze_y), *map(float, f.position), *map(float, f.look_at), int(bool(f.dropped)))


def _is_full(exc: BaseException) -> bool:
    if isinstance(exc, OSError) and exc.errno == errno.ENOSPC:
        return True
    code = getattr(exc, "sqlite_errorcode", None)
    return code == getattr(sqlite3, "SQLITE_FULL", 13) or "disk is full" in str(exc) or \
        "No space left" in str(exc)


#: The end of the refusal of a row studyapp cannot have written (its checksum is valid: it was made so).
_NOT_OURS = ": the database was not written by studyapp (restore its last good copy)"


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _json(text: str):
    """``json.loads``, None for text that is not JSON (or nests too deep to read)."""
    try:
        return json.loads(text)
    except (ValueError, RecursionError):
        return None
