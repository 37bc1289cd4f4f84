"""The session store: one SQLite file per study that loses no committed answer.

Durability
----------
The database runs in WAL mode with ``synchronous=FULL``: every commit is fsynced before it returns, so a
response committed before the next trial starts survives SIGKILL and power loss. The planned trials of a
participant are written in one transaction before the first trial is shown; each response is its own
transaction, and ``responses`` has the primary key ``(participant, idx)``, so a response can never be recorded
twice. Errors (full disk, locked or foreign file) roll the transaction back and raise :class:`StoreError`, a
one-line ``ValueError``; nothing already recorded is altered.

Tables
------
``study``          key/value: store format, protocol name, version, content hash and JSON, creation time
``participants``   pseudonymous id, counterbalancing index, seed, schedule hash, enrolment time
``sessions``       id ``<participant>-s<n>``, protocol hash, software versions, display and monitor settings,
                   measured refresh rate, keyboard backend, seed, start/end (UTC), status
                   (``running``, ``completed``, ``ended`` (Escape -> end), ``interrupted`` (found running at
                   resume)), resumed-from session
``planned_trials`` the schedule: kind (trial, practice, catch, reference), scene, block, family, conditions in
                   display order (JSON), expected answer of catch trials, break flag
``responses``      one row per answered trial: raw answers (JSON), the derived chosen/chosen_2/response, RT
                   from stimulus onset, onset time, dropped frames, switches, gaze flag, catch correctness
``adaptive``       one row per trial of an adaptive design, written with its response: the procedure
                   (``VaFR@temple``), the varied parameter, the level shown, whether the answer was correct
                   (detected), the procedure's running estimate and state (JSON) after it; ``skipped``: the
                   procedure had stopped early, nothing was shown (created by the first adaptive trial)
``events``         pause, resume, end, break and error events per session; ``scenes`` (live sessions, written
                   with the session): the protocol folder and each scene's content hash, for ``replay``
                   ``fps_check`` (live sessions in a window): the frame-rate check before the first trial
                   (:meth:`Store.fps_check`); ``refused``: the check stopped the session (status ``refused``)

Exports
-------
:func:`read_trials` gives the tidy trial log (:data:`data_schema.trial_log.ALL_COLUMNS`, one row per answered
trial; references are not trials); :func:`export_csv`, :func:`export_parquet` and :func:`export_pwcmp` write it
(pwcmp: ``observer, session, scene, condition_1, condition_2, selection`` with ``selection`` 1 when
``condition_1`` was chosen and 2 when ``condition_2`` was).
"""

from __future__ import annotations

import contextlib
import csv
import errno
import hashlib
import io
import itertools
import json
import math
import os
import socket
import sqlite3
import tempfile
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from . import families
from .atomic import atomic_path, current_umask, input_file, write_text
from .errors import UserError
from .trial_log import ADAPTIVE_COLUMNS, ALL_COLUMNS, TIMING_COLUMNS

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
    intensity: float  # the level on the procedure's axis (studyapp.runner.adaptive.intensity)
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


# -- the process that runs a session (is it still alive?) --------------------------------------------------
def _boot_id() -> str:
    try:
        return Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        return ""


def _start_ticks(pid: int) -> str:
    """Start time of process ``pid`` (clock ticks since boot), '' if it does not exist or is unknown."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return ""
    return stat.rsplit(")", 1)[-1].split()[19]


def process_identity(pid: int | None = None) -> str:
    """``host pid start boot``: identifies a running process across pid reuse and reboots."""
    pid = os.getpid() if pid is None else pid
    return json.dumps({"host": socket.gethostname(), "pid": pid, "start": _start_ticks(pid), "boot": _boot_id()},
                      sort_keys=True)


def process_state(identity: str) -> str:
    """``alive``, ``dead`` or ``elsewhere`` (another machine: cannot be checked from here).

    This process itself counts as dead: it is starting a new session, so an older one it ran has stopped."""
    if identity == process_identity():
        return "dead"
    try:
        ident = json.loads(identity)
    except ValueError:
        return "dead"
    if ident.get("host") != socket.gethostname() or ident.get("boot") != _boot_id():
        return "elsewhere" if ident.get("host") != socket.gethostname() else "dead"
    start = _start_ticks(int(ident.get("pid", -1))) if int(ident.get("pid", -1)) > 0 else ""
    return "alive" if start and start == ident.get("start") else "dead"


class Store:
    """An open study database. Use :func:`open_store`; close with :meth:`close` (or ``with``)."""

    def __init__(self, path: Path, conn: sqlite3.Connection, readonly: bool) -> None:
        self.path = path
        self.conn = conn
        self.readonly = readonly

    # -- plumbing ------------------------------------------------------------------------------------------
    def __enter__(self) -> Store:  # noqa: PYI034 - a final class
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()
        if self.readonly and isinstance(exc, (sqlite3.DatabaseError, UnicodeDecodeError)):  # damage met reading
            with damage_is_refused(self.path):
                raise exc

    def close(self) -> None:
        with contextlib.suppress(sqlite3.Error):
            self.conn.close()

    @contextlib.contextmanager
    def transaction(self, what: str):
        """``BEGIN IMMEDIATE`` ... ``COMMIT``; any error rolls back and becomes a one-line StoreError."""
        if self.readonly:
            raise StoreError(f"{self.path}: opened read-only: cannot {what}")
        try:
            self.conn.execute("BEGIN IMMEDIATE")
        except (sqlite3.Error, OSError) as exc:
            raise self._error(what, exc) from None
        try:
            yield self.conn
            self.conn.execute("COMMIT")
        except BaseException as exc:
            with contextlib.suppress(sqlite3.Error):
                self.conn.execute("ROLLBACK")
            if isinstance(exc, (sqlite3.Error, OSError)):
                raise self._error(what, exc) from None
            raise

    def _error(self, what: str, exc: BaseException) -> StoreError:
        if _is_full(exc):
            return StoreError(f"{self.path}: no space left on device: could not {what}; nothing already recorded "
                              "was changed (free some space, then run again with --resume)")
        if isinstance(exc, sqlite3.IntegrityError):
            return StoreError(f"{self.path}: could not {what}: {exc}")
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        return StoreError(f"{self.path}: could not {what}: {msg}")

    def meta(self) -> dict[str, str]:
        return dict(self.conn.execute("SELECT key, value FROM study").fetchall())

    # -- study / protocol ---------------------------------------------------------------------------------
    def bind_protocol(self, name: str, version: str, content_hash: str, protocol: dict,
                      record: bool = True) -> None:
        """Record the protocol of a new study, or refuse a protocol that differs from the recorded one.

        With ``record=False`` only the check is made (an empty study stays empty)."""
        meta = self.meta()
        if not meta and not record:
            return
        if not meta:
            rows = {"store_format": str(STORE_FORMAT), "protocol_name": name, "protocol_version": version,
                    "protocol_hash": content_hash, "created_utc": utc_now(),
                    "protocol_json": json.dumps(protocol, sort_keys=True, default=str)}
            with self.transaction("record the protocol") as c:
                for item in sorted(rows.items()):
                    _insert(c, "study", item)
            return
        if meta.get("protocol_hash") != content_hash:
            raise StoreError(
                f"{self.path}: written by protocol {meta.get('protocol_name')!r} version "
                f"{meta.get('protocol_version')!r} (sha256 {meta.get('protocol_hash', '')[:12]}), not by "
                f"{name!r} version {version!r} (sha256 {content_hash[:12]}): use another --db for a changed protocol")

    def protocol_json(self) -> dict | None:
        """The recorded protocol (None in an empty study); a record that is not a JSON object is refused."""
        text = self.meta().get("protocol_json")
        if not text:
            return None
        data = _json(text)
        if not isinstance(data, dict):
            raise StoreError(f"{self.path}: the recorded protocol is not a JSON object: the database was not "
                             "written by studyapp (restore its last good copy)")
        return data

    # -- participants and schedules -------------------------------------------------------------------------
    def participant(self, pid: str) -> dict | None:
        row = self.conn.execute("SELECT id, counterbalance, seed, schedule_hash, n_planned FROM participants "
                                "WHERE id = ?", (pid,)).fetchone()
        if row is None:
            return None
        return dict(zip(("id", "counterbalance", "seed", "schedule_hash", "n_planned"), row))

    def enrol(self, pid: str, counterbalance: int, seed: int, schedule_hash: str,
              planned: Sequence[PlannedRow]) -> None:
        """Add a participant and write the whole schedule in one transaction (before the first trial)."""
        with self.transaction(f"write the schedule of participant {pid!r}") as c:
            order = c.execute("SELECT COUNT(*) FROM participants").fetchone()[0]
            _insert(c, "participants", (pid, counterbalance, seed, schedule_hash, len(planned), utc_now(), order, 0,
                                        0))
            for t in planned:
                _insert(c, "planned_trials", (pid, t.idx, t.kind, t.family, t.scene, t.block,
                                              json.dumps(list(t.conditions)), t.expected, int(t.break_before)))

    def planned(self, pid: str) -> list[PlannedRow]:
        rows = self.conn.execute("SELECT idx, kind, family, scene, block, conditions, expected, break_before "
                                 "FROM planned_trials WHERE participant = ? ORDER BY idx", (pid,)).fetchall()
        return [PlannedRow(r[0], r[1], r[2], r[3], r[4], self._conditions(pid, r[0], r[5]), r[6], bool(r[7]))
                for r in rows]

    def _conditions(self, pid, idx, text) -> tuple[str, ...]:
        """The conditions of a planned trial (a JSON list of names), or the one-line refusal naming it."""
        try:
            conds = json.loads(text) if isinstance(text, str) else None
        except (ValueError, RecursionError):
            conds = None
        if not (isinstance(conds, list) and conds and all(isinstance(c, str) for c in conds)):
            raise StoreError(f"{self.path}: participant {pid!r}, trial {idx!r}: conditions={_short(text)} is "
                             f"invalid: must be a JSON list of condition names{_NOT_OURS}")
        return tuple(conds)

    def has_answers(self) -> bool:
        """Whether any participant has answered anything (a database without answers holds no one's data)."""
        return self.conn.execute("SELECT 1 FROM responses LIMIT 1").fetchone() is not None

    def answered(self, pid: str) -> set[int]:
        return {r[0] for r in self.conn.execute("SELECT idx FROM responses WHERE participant = ?", (pid,))}

    def first_unanswered(self, pid: str) -> int | None:
        """Index of the first planned trial without a response (references count as answered once passed)."""
        row = self.conn.execute(
            "SELECT MIN(p.idx) FROM planned_trials p LEFT JOIN responses r ON r.participant = p.participant "
            "AND r.idx = p.idx WHERE p.participant = ? AND r.idx IS NULL", (pid,)).fetchone()
        return row[0]

    # -- sessions ------------------------------------------------------------------------------------------
    def live_session(self, pid: str) -> dict | None:
        """A session of ``pid`` whose process is still running (here or on another machine), else None."""
        for sid, process in self.conn.execute("SELECT id, process FROM sessions WHERE participant = ? AND "
                                              "status = 'running' ORDER BY rowid", (pid,)).fetchall():
            state = process_state(process)
            if state != "dead":
                ident = json.loads(process)
                return {"id": sid, "state": state, "host": ident.get("host"), "pid": ident.get("pid")}
        return None

    def _refuse_live(self, pid: str) -> None:
        live = self.live_session(pid)
        if live is not None:
            where = "here" if live["state"] == "alive" else f"on {live['host']}"
            raise StoreError(f"{self.path}: participant {pid!r} has session {live['id']} still running ({where}, "
                             f"process {live['pid']}): finish or stop it first, then --resume")

    def check_not_running(self, pid: str) -> None:
        """Refuse (StoreError) when another process is running a session of ``pid``."""
        self._refuse_live(pid)

    def start_session(self, pid: str, protocol_hash: str, seed: int, software: dict, display: dict,
                      measured: dict, presenter: str, resumed_from: str | None = None,
                      scenes: dict | None = None) -> str:
        """Open a new session of ``pid``; sessions left ``running`` by a process that died become
        ``interrupted``. Refused while another process runs a session of ``pid`` (checked inside the write
        transaction, so two concurrent resumes cannot both start).

        ``scenes`` (live protocols: ``{"folder": protocol folder, "scenes": {scene: content sha256}}``) is
        recorded in the same transaction as a ``scenes`` event: what ``studyapp replay`` checks
        (:meth:`session_scenes`)."""
        with self.transaction(f"start a session of participant {pid!r}") as c:
            self._refuse_live(pid)
            n = c.execute("SELECT COUNT(*) FROM sessions WHERE participant = ?", (pid,)).fetchone()[0]
            sid = f"{pid}-s{n + 1}"
            _update(c, "sessions", {"participant": pid, "status": "running"},
                    {"status": "interrupted", "ended_utc": utc_now()})
            _insert(c, "sessions", (sid, pid, protocol_hash, json.dumps(software, sort_keys=True),
                                    json.dumps(display, sort_keys=True), measured.get("refresh_hz"),
                                    measured.get("keyboard_backend"), presenter, seed, utc_now(), None, "running",
                                    resumed_from, process_identity(), None))
            if scenes is not None:
                n_ev = c.execute("SELECT COALESCE(MAX(id), 0) FROM events").fetchone()[0]
                _insert(c, "events", (n_ev + 1, sid, utc_now(), "scenes", json.dumps(scenes, sort_keys=True)))
        return sid

    def running_sessions(self, pid: str) -> list[str]:
        """Sessions of ``pid`` still marked running (stopped without being closed), oldest first."""
        return [r[0] for r in self.conn.execute("SELECT id FROM sessions WHERE participant = ? AND "
                                                "status = 'running' ORDER BY rowid", (pid,))]

    def last_session(self, pid: str) -> str | None:
        row = self.conn.execute("SELECT id FROM sessions WHERE participant = ? ORDER BY rowid DESC LIMIT 1",
                                (pid,)).fetchone()
        return row[0] if row else None

    def end_session(self, sid: str, status: str) -> None:
        with self.transaction(f"close session {sid}") as c:
            _update(c, "sessions", {"id": sid}, {"status": status, "ended_utc": utc_now()})
        self.checkpoint()

    def checkpoint(self) -> None:
        """Copy the WAL into the database file (between trials: at breaks and at the end of a session)."""
        try:
            self.conn.execute("PRAGMA wal_checkpoint(PASSIVE)")
        except sqlite3.Error as exc:  # a failed checkpoint loses nothing: the WAL still holds the data
            if _is_full(exc):
                raise self._error("checkpoint the write-ahead log", exc) from None

    def event(self, sid: str, kind: str, detail: str = "") -> None:
        with self.transaction(f"record the event {kind!r}") as c:
            n = c.execute("SELECT COALESCE(MAX(id), 0) FROM events").fetchone()[0]
            _insert(c, "events", (n + 1, sid, utc_now(), kind, detail))

    # -- responses -----------------------------------------------------------------------------------------
    def commit_response(self, pid: str, idx: int, sid: str, answers: Sequence[str], chosen: str = "",
                        chosen_2: str = "", response: int | None = None, rt_s: float | None = None,
                        onset_s: float | None = None, dropped_frames: int = 0, switches: int = 0,
                        gaze_left_fovea: bool | None = None, correct: bool | None = None,
                        frames: Sequence | None = None, adaptive: AdaptiveRow | None = None) -> None:
        """Write one response durably (fsynced commit) before the next trial starts.

        ``frames`` (live trials: :class:`studyapp.runner.live.FrameRecord`-like rows, one per flip) are written
        in the same transaction: a crash loses at most the frames of the trial in progress, never an answer.
        The participant's answer and frame counts are updated in the same transaction too, so a row lost from
        the file later is detected (:func:`verify`). ``adaptive`` (a trial of an adaptive design) is written in
        the same transaction: the level, the answer and the procedure's state are committed with the response."""
        rt = None if rt_s is None or not math.isfinite(rt_s) else float(rt_s)
        onset = None if onset_s is None or not math.isfinite(onset_s) else float(onset_s)
        with self.transaction(f"save the response to trial {idx} of participant {pid!r}") as c:
            _insert(c, "responses", (pid, idx, sid, json.dumps(list(answers)), chosen, chosen_2, response, rt, onset,
                                     int(dropped_frames), int(switches),
                                     None if gaze_left_fovea is None else int(gaze_left_fovea),
                                     None if correct is None else int(correct), utc_now()))
            if adaptive is not None:
                a = adaptive
                c.execute(ADAPTIVE_SCHEMA)
                _insert(c, "adaptive", (pid, idx, a.procedure, a.varied, float(a.level), float(a.intensity),
                                        None if a.correct is None else int(a.correct), _real(a.estimate_mean),
                                        _real(a.estimate_sd), a.state, int(a.skipped)))
            for f in frames or ():
                _insert(c, "frames", (pid, idx, *_frame_values(f)))
            n = c.execute("SELECT n_answered, n_frames FROM participants WHERE id = ?", (pid,)).fetchone()
            _update(c, "participants", {"id": pid}, {"n_answered": (n[0] if n else 0) + 1,
                                                     "n_frames": (n[1] if n else 0) + len(frames or ())})

    def record_validation(self, sid: str, error_deg: float, detail: str) -> None:
        """The eye tracker's validation accuracy (mean error, degrees) of a session, and an event with the
        attempts."""
        with self.transaction(f"record the eye-tracker validation of session {sid}") as c:
            _update(c, "sessions", {"id": sid}, {"validation_deg": float(error_deg)})
            n = c.execute("SELECT COALESCE(MAX(id), 0) FROM events").fetchone()[0]
            _insert(c, "events", (n + 1, sid, utc_now(), "validation", detail))

    # -- reading -------------------------------------------------------------------------------------------
    def sessions(self) -> list[dict]:
        """Every session, oldest first. A session marked ``running`` whose process has died is reported as
        ``interrupted`` (the file is not changed; the next ``--resume`` records it)."""
        cols = ("id", "participant", "status", "started_utc", "ended_utc", "resumed_from", "presenter", "seed",
                "measured_refresh_hz", "process")
        rows = self.conn.execute(f"SELECT {', '.join('s.' + c for c in cols)}, "
                                 "(SELECT COUNT(*) FROM responses r WHERE r.session = s.id) "
                                 "FROM sessions s ORDER BY s.rowid").fetchall()
        out = []
        for r in rows:
            d = dict(zip(cols + ("responses",), r))
            if d["status"] == "running" and process_state(d.pop("process")) == "dead":
                d["status"] = "interrupted"
            d.pop("process", None)
            out.append(d)
        return out

    def progress(self) -> list[dict]:
        """Per participant: planned answered trials, answered so far, catch trials passed."""
        rows = self.conn.execute(
            "SELECT p.id, "
            "(SELECT COUNT(*) FROM planned_trials t WHERE t.participant = p.id AND t.kind != 'reference'), "
            "(SELECT COUNT(*) FROM responses r JOIN planned_trials t ON t.participant = r.participant "
            " AND t.idx = r.idx WHERE r.participant = p.id AND t.kind != 'reference'), "
            "(SELECT COUNT(*) FROM planned_trials t WHERE t.participant = p.id AND t.kind = 'catch'), "
            "(SELECT COALESCE(SUM(r.correct), 0) FROM responses r JOIN planned_trials t ON "
            " t.participant = r.participant AND t.idx = r.idx WHERE r.participant = p.id AND t.kind = 'catch') "
            "FROM participants p ORDER BY p.enrol_order").fetchall()
        return [dict(zip(("participant", "planned", "answered", "catch_planned", "catch_correct"), r)) for r in rows]

    def tidy_rows(self) -> list[dict]:
        """The tidy trial log as dicts in :data:`ALL_COLUMNS` order (participants in enrolment order)."""
        q = ("SELECT t.participant, r.session, t.block, t.scene, t.idx, t.family, t.conditions, r.chosen, "
             "r.chosen_2, r.response, r.rt_s, t.kind FROM responses r JOIN planned_trials t ON "
             "t.participant = r.participant AND t.idx = r.idx JOIN participants p ON p.id = t.participant "
             "WHERE t.kind != 'reference' ORDER BY p.enrol_order, t.idx")
        slow: dict[str, set] = {}  # session -> the conditions run below min_fps with --accept-slow

        def slow_in(sid: str) -> set:
            if sid not in slow:
                check = self.fps_check(sid)
                slow[sid] = set(check["accepted_slow"]) if check else set()
            return slow[sid]

        rows = []
        found = self.conn.execute(q).fetchall()  # all first: fps_check reads the same connection
        for pid, sid, block, scene, idx, fam, conds, chosen, chosen_2, resp, rt, kind in found:
            shown = self._conditions(pid, idx, conds)
            rows.append(tidy_row(pid, sid, block, scene, idx, fam, shown, chosen, chosen_2, resp, rt, kind,
                                 fps_check_slow=bool(slow_in(sid) & set(shown))))
        timing = self.trial_timing()
        adaptive = {(a["participant"], a["idx"]): a for a in self.adaptive_rows()}
        out = []
        for r in rows:
            r.update(timing.get((r["participant"], r["trial"]), {}))
            a = adaptive.get((r["participant"], r["trial"]))
            if a is not None:
                if a["skipped"]:  # the procedure had stopped: nothing was shown, nothing answered
                    continue
                r.update(adaptive_columns(a))
            out.append(r)
        return out

    def adaptive_rows(self, pid: str | None = None) -> list[dict]:
        """The rows of the ``adaptive`` table (of participant ``pid``), in trial order; ``correct`` and
        ``skipped`` as bools (``correct`` None when skipped). Empty for a database written before the table."""
        if "adaptive" not in _tables(self.conn):
            return []
        cols = COLUMNS["adaptive"]
        q = f"SELECT {', '.join(cols)} FROM adaptive" + (" WHERE participant = ?" if pid is not None else "") + \
            " ORDER BY participant, idx"
        out = []
        for row in self.conn.execute(q, () if pid is None else (pid,)):
            d = dict(zip(cols, row))
            d["correct"] = None if d["correct"] is None else bool(d["correct"])
            d["skipped"] = bool(d["skipped"])
            out.append(d)
        return out

    def trial_flips(self) -> dict[tuple[str, int], tuple[list, list, list, list, list]]:
        """(participant, trial) -> the checked flips of a live trial: flip times, render times (None: the last
        frame shown again), gaze sample times (None: no sample), dropped flags, stimulus shown (the arguments of
        :func:`data_schema.timing.summary`)."""
        out: dict[tuple[str, int], tuple[list, list, list, list, list]] = {}
        for f in self.iter_frames():
            cols = out.setdefault((f["participant"], f["idx"]), ([], [], [], [], []))
            for col, name in zip(cols, ("flip_s", "render_s", "gaze_t", "dropped", "stimulus")):
                col.append(f[name])
        return out

    def trial_timing(self) -> dict[tuple[str, int], dict]:
        """(participant, trial) -> the timing summary of a live trial's frames (:mod:`data_schema.timing`)."""
        from .timing import summary

        return {key: summary(*cols) for key, cols in self.trial_flips().items()}

    def frames(self, pid: str | None = None, idx: int | None = None) -> list[dict]:
        """The frames table (one row per flip of a live trial), optionally of one participant / trial; every
        row checked (:func:`check_frame`)."""
        return list(self.iter_frames(pid, idx))

    def iter_frames(self, pid: str | None = None, idx: int | None = None) -> Iterator[dict]:
        """:meth:`frames`, one row at a time (bounded memory); a row that studyapp cannot have logged is refused
        in one line naming the participant, trial, frame and field (:func:`check_frame`)."""
        cols = COLUMNS["frames"]
        where, args = [], []
        for col, val in (("participant", pid), ("idx", idx)):
            if val is not None:
                where.append(f"f.{col} = ?")
                args.append(val)
        q = (f"SELECT {', '.join('f.' + c for c in cols)}, t.conditions FROM frames f LEFT JOIN planned_trials t "
             "ON t.participant = f.participant AND t.idx = f.idx" + (f" WHERE {' AND '.join(where)}" if where else "")
             + " ORDER BY f.participant, f.idx, f.frame")
        n_stimuli: dict[tuple, int] = {}
        for r in self.conn.execute(q, args):
            row = dict(zip(cols, r[:-1]))
            key = (row["participant"], row["idx"])
            if key not in n_stimuli:  # rows come ordered by trial: one parse per trial
                n_stimuli.clear()
                n_stimuli[key] = 0 if r[-1] is None else len(self._conditions(*key, r[-1]))
            yield check_frame(self.path, row, n_stimuli[key])

    def response_session(self, pid: str, idx: int) -> str | None:
        """The session that answered trial ``idx`` of ``pid`` (None: not answered)."""
        row = self.conn.execute("SELECT session FROM responses WHERE participant = ? AND idx = ?",
                                (pid, idx)).fetchone()
        return None if row is None else row[0]

    def session_scenes(self, sid: str) -> dict | None:
        """What session ``sid`` recorded of its scenes (:meth:`start_session`): ``{"folder": str, "scenes":
        {scene: sha256}}``, or None for a session that recorded none (older studyapp, pre-rendered stimuli)."""
        rec = self._event_json(sid, "scenes")
        if rec is None:
            return None
        ok = (isinstance(rec, dict) and isinstance(rec.get("folder"), str) and isinstance(rec.get("scenes"), dict)
              and all(isinstance(k, str) and isinstance(v, str) and len(v) == 64 for k, v in rec["scenes"].items()))
        if not ok:
            raise StoreError(f"{self.path}: session {sid}: the record of its scenes is invalid: must be a folder and "
                             f"a sha256 per scene{_NOT_OURS}")
        return rec


    def _event_json(self, sid: str, kind: str):
        """The JSON detail of session ``sid``'s last event of ``kind``: None without one, ``False`` for a detail
        that is not JSON (refused by the caller)."""
        row = self.conn.execute("SELECT detail FROM events WHERE session = ? AND kind = ? ORDER BY id DESC LIMIT 1",
                                (sid, kind)).fetchone()
        if row is None:
            return None
        rec = _json(row[0]) if isinstance(row[0], str) else None
        return False if rec is None else rec

    def fps_check(self, sid: str) -> dict | None:
        """The frame-rate check session ``sid`` recorded before its first trial (``fps_check`` event, written by
        :mod:`studyapp.runner.fpscheck`'s caller): ``{"seconds", "scale", "min_fps", "rows": [{"condition",
        "scene", "fps_p5", "fps_p50", "latency_p50_ms", "frames"}], "accepted_slow": [condition, ...]}``, or None
        (no check: pre-rendered, simulated, older studyapp)."""
        rec = self._event_json(sid, "fps_check")
        if rec is None:
            return None
        ok = (isinstance(rec, dict) and isinstance(rec.get("rows"), list) and isinstance(rec.get("accepted_slow"), list)
              and all(isinstance(r, dict) and isinstance(r.get("condition"), str) and isinstance(r.get("scene"), str)
                      for r in rec["rows"]))
        if not ok:
            raise StoreError(f"{self.path}: session {sid}: the record of its frame-rate check is invalid{_NOT_OURS}")
        return rec

    def record_attempt(self, sid: str, pid: str, idx: int, frames: Sequence) -> None:
        """The flips of an attempt at trial ``idx`` that Escape interrupted (it has no answer, so its frames are
        not in the frames table, which holds the answered attempt's): an ``interrupted_attempt`` event of
        session ``sid``, which ``studyapp replay`` reads back (:meth:`attempts`)."""
        rows = [list(_frame_values(f)) for f in frames]
        self.event(sid, "interrupted_attempt", json.dumps({"participant": pid, "trial": int(idx), "frames": rows}))

    def attempts(self, pid: str, idx: int) -> list[dict]:
        """The interrupted attempts at trial ``idx`` of ``pid`` (:meth:`record_attempt`), oldest first:
        ``{"session": sid, "frames": [rows as :meth:`frames` returns them, each checked]}``."""
        row = self.conn.execute("SELECT conditions FROM planned_trials WHERE participant = ? AND idx = ?",
                                (pid, idx)).fetchone()
        n_stimuli = 0 if row is None else len(self._conditions(pid, idx, row[0]))
        cols = COLUMNS["frames"]
        out = []
        for sid, detail in self.conn.execute(
                "SELECT e.session, e.detail FROM events e JOIN sessions s ON s.id = e.session WHERE "
                "s.participant = ? AND e.kind = 'interrupted_attempt' ORDER BY e.id", (pid,)):
            rec = _json(detail) if isinstance(detail, str) else None
            if not (isinstance(rec, dict) and rec.get("participant") == pid and type(rec.get("trial")) is int
                    and isinstance(rec.get("frames"), list)
                    and all(isinstance(r, list) and len(r) == len(cols) - 2 for r in rec["frames"])):
                raise StoreError(f"{self.path}: session {sid}: the record of an interrupted attempt is invalid"
                                 f"{_NOT_OURS}")
            if rec["trial"] == idx:
                out.append({"session": sid, "frames": [check_frame(self.path, dict(zip(cols, (pid, idx, *r))),
                                                                   n_stimuli) for r in rec["frames"]]})
        return out

    def session_layout(self, sid: str) -> dict | None:
        """What live session ``sid`` recorded of its window (``live_layout`` event,
        :func:`studyapp.runner.live.layout_record`): ``{"window_px": (w, h), "scale": float, "conditions":
        {condition: {"backend": "cpu"|"gpu", "views": [EyeView, ...]}}}``, or None (an older studyapp,
        pre-rendered stimuli)."""
        from .geometry import PIXELS, EyeView

        rec = self._event_json(sid, "live_layout")
        if rec is None:
            return None
        try:
            ok = (isinstance(rec, dict) and isinstance(rec.get("window_px"), list) and len(rec["window_px"]) == 2
                  and isinstance(rec.get("conditions"), dict)
                  and all(isinstance(c, dict) and c.get("backend") in ("cpu", "gpu")
                          and isinstance(c.get("views"), list) and c["views"] for c in rec["conditions"].values()))
            if ok:
                return {"window_px": tuple(PIXELS.check("window_px", v) for v in rec["window_px"]),
                        "scale": float(rec.get("scale", 1.0)),
                        "conditions": {name: {"backend": c["backend"],
                                              "views": [EyeView.from_record(v) for v in c["views"]]}
                                       for name, c in rec["conditions"].items()}}
        except (UserError, TypeError, ValueError):
            pass
        raise StoreError(f"{self.path}: session {sid}: the record of its window layout is invalid{_NOT_OURS}")

#: The end of the refusal of a row studyapp cannot have written (its checksum is valid: it was made so).
_NOT_OURS = ": the database was not written by studyapp (restore its last good copy)"
#: Bounds of what a frame row holds: the presenter's clock (seconds), gaze in display pixels, scene units.
FRAME_TIME_S, FRAME_PIXELS, FRAME_SCENE = 1e9, 1e6, 1e9


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _json(text: str):
    """``json.loads``, None for text that is not JSON (or nests too deep to read)."""
    try:
        return json.loads(text)
    except (ValueError, RecursionError):
        return None


#: Real fields of a frame row: (column, bound, may be empty, lowest value).
_FRAME_REALS = (("flip_s", FRAME_TIME_S, False, None), ("render_s", FRAME_TIME_S, True, 0.0),
                ("gaze_t", FRAME_TIME_S, True, None), ("gaze_x", FRAME_PIXELS, True, None),
                ("gaze_y", FRAME_PIXELS, True, None),
                *((c, FRAME_SCENE, False, None) for c in ("pos_x", "pos_y", "pos_z", "look_x", "look_y", "look_z")))


def check_frame(path, row: dict, n_stimuli: int) -> dict:
    """One row of the frames table as studyapp logs it, or a :class:`StoreError` naming the database, the
    participant, trial and frame, and the field.

    Accepted: ``participant`` text; ``idx``, ``frame`` whole numbers >= 0; ``stimulus`` a whole number below
    ``n_stimuli`` (the stimuli of the planned trial); ``flip_s`` and (or None) ``render_s`` >= 0, ``gaze_t``
    finite seconds within +-1e9; ``gaze_x``/``gaze_y`` both None or both finite pixels within +-1e6; the six
    camera coordinates finite scene units within +-1e9, the look-at point away from the position; ``dropped``
    0 or 1. Integers in real columns are returned as floats. (Export streams millions of rows through here: the
    accepted path only compares; the message is built on refusal.)
    """
    out = dict(row)
    if type(row["participant"]) is not str:
        raise _frame_refusal(path, row, "participant", "must be text")
    for field in ("idx", "frame"):
        v = row[field]
        if type(v) is not int or v < 0:
            raise _frame_refusal(path, row, field, "must be a whole number >= 0")
    v = row["stimulus"]
    if type(v) is not int or not 0 <= v < n_stimuli:
        raise _frame_refusal(path, row, "stimulus", f"must be a stimulus index 0..{n_stimuli - 1} of the trial"
                             if n_stimuli else "the trial has no stimuli")
    for field, bound, optional, low in _FRAME_REALS:
        v = row[field]
        if v is None and optional:
            continue
        t = type(v)
        if not ((t is float or t is int) and -bound <= v <= bound and (low is None or v >= low)):
            lo = f"{low:g}" if low is not None else f"-{bound:g}"
            raise _frame_refusal(path, row, field, f"must be {'empty or ' if optional else ''}a number in "
                                 f"[{lo}, {bound:g}]")
        if t is int:
            out[field] = float(v)
    if (row["gaze_x"] is None) != (row["gaze_y"] is None):
        raise _frame_refusal(path, row, "gaze_y" if row["gaze_y"] is None else "gaze_x",
                             "gaze_x and gaze_y must both be given or both be empty")
    if (out["pos_x"], out["pos_y"], out["pos_z"]) == (out["look_x"], out["look_y"], out["look_z"]):
        raise _frame_refusal(path, row, "look_x", "the look-at point equals the camera position (no view direction)")
    if type(row["dropped"]) is not int or row["dropped"] not in (0, 1):
        raise _frame_refusal(path, row, "dropped", "must be 0 or 1")
    return out


def _frame_refusal(path, row: dict, field: str, why: str) -> StoreError:
    return StoreError(f"{path}: participant {_short(row.get('participant'))}, trial {_short(row.get('idx'))}, "
                      f"frame {_short(row.get('frame'))}: {field}={_short(row[field])} is invalid: {why}{_NOT_OURS}")


def adaptive_columns(row) -> dict:
    """The tidy log's adaptive columns (:data:`ADAPTIVE_COLUMNS`) of an adaptive trial (an :class:`AdaptiveRow`
    or a row of :meth:`Store.adaptive_rows`), and ``condition``: the varied condition (2afc trials too)."""
    get = row.get if isinstance(row, dict) else (lambda k: getattr(row, k))
    out = {c: get(c) for c in ADAPTIVE_COLUMNS}
    out["correct"] = int(out["correct"])
    out["condition"] = get("procedure").rsplit("@", 1)[0]
    return out


def tidy_row(participant: str, session: str, block: str, scene: str, trial: int, family: str,
             conditions: Sequence[str], chosen: str, chosen_2: str, response, rt_s, kind: str,
             fps_check_slow: bool = False) -> dict:
    """One row of the tidy log (:data:`ALL_COLUMNS`; ``""`` where a column does not apply to the family).
    ``fps_check_slow``: a condition shown was below ``min_fps`` in the session's frame-rate check (run with
    ``--accept-slow``: :meth:`Store.fps_check`'s ``accepted_slow``)."""
    row = dict.fromkeys(ALL_COLUMNS, "")
    row.update(participant=participant, session=session, block=block, scene=scene, trial=trial, family=family,
               chosen=chosen, chosen_2=chosen_2, response=response, rt_s=rt_s,
               practice=int(kind == "practice"), catch=int(kind == "catch"), fps_check_slow=int(fps_check_slow))
    row.update(families.get(family).tidy_columns(conditions))
    return row


# -- opening: recognise, check, then connect ------------------------------------------------------------------
def _damaged(path: Path, detail: str) -> StoreError:
    return StoreError(f"{path}: the study database is damaged ({detail}); nothing was read or changed: restore "
                      f"its last good copy, or salvage what is left with `sqlite3 {path.name} .recover | sqlite3 "
                      "recovered.db` and check it by hand")


def _header(path: Path) -> bytes:
    """The first 100 bytes of ``path``, checked to be a SQLite file that carries our marker."""
    if not path.is_dir():  # a folder is named below; a FIFO or device is refused unopened
        input_file(path, "study database", StoreError)
    try:
        with open(path, "rb") as fh:
            head = fh.read(100)
    except IsADirectoryError:
        raise StoreError(f"{path}: is a folder, not a study database") from None
    except OSError as exc:
        raise StoreError(f"{path}: cannot read the study database: {exc.strerror or exc}") from None
    if not head:
        raise StoreError(f"{path}: is an empty file, not a studyapp study database (only `studyapp run` creates "
                         "one, at a path that does not exist yet)")
    if len(head) < 100 or not head.startswith(SQLITE_MAGIC):
        raise StoreError(f"{path}: is not a studyapp study database (not an SQLite file)")
    app_id = int.from_bytes(head[68:72], "big")
    if app_id != APPLICATION_ID:
        raise StoreError(f"{path}: is an SQLite database of another application (application_id {app_id:#010x}), "
                         "not a studyapp study database: it was left untouched")
    version = int.from_bytes(head[60:64], "big")
    if version != STORE_FORMAT:
        raise StoreError(f"{path}: study database format {version} is not supported (this studyapp reads and "
                         f"writes format {STORE_FORMAT})")
    return head


def _uri(path: Path, **query) -> str:
    from urllib.parse import quote

    q = "&".join(f"{k}={v}" for k, v in query.items())
    return f"file:{quote(str(path.resolve()))}?{q}"


def _connect_ro(path: Path) -> sqlite3.Connection:
    """A read-only connection. On read-only media SQLite cannot create the WAL index (``-shm``); a database
    without a write-ahead log is then read as immutable, which is exact (nothing can change it there)."""
    try:
        conn = sqlite3.connect(_uri(path, mode="ro"), uri=True, isolation_level=None, timeout=10.0)
        conn.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()
        return conn
    except sqlite3.Error as exc:
        first = exc
    wal = Path(str(path) + "-wal")
    if not (wal.exists() and wal.stat().st_size > 0) and not os.access(path.parent, os.W_OK):
        with contextlib.suppress(sqlite3.Error):
            conn = sqlite3.connect(_uri(path, mode="ro", immutable=1), uri=True, isolation_level=None)
            conn.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()
            return conn
    raise StoreError(f"{path}: cannot open the study database: {str(first).splitlines()[0]}")


def _tables(conn: sqlite3.Connection) -> set[str]:
    return {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}


def _check_tables(path: Path, conn: sqlite3.Connection) -> None:
    have = _tables(conn)
    missing = [t for t in COLUMNS if t not in have and t not in OPTIONAL_TABLES]
    if missing:
        raise StoreError(f"{path}: is an incomplete studyapp study database (missing tables: {', '.join(missing)}); "
                         "it was left untouched")


@contextlib.contextmanager
def damage_is_refused(path: Path):
    """Turn SQLite's "malformed" errors while reading ``path`` into the one-line damaged-database refusal."""
    try:
        yield
    except UnicodeDecodeError as exc:  # text bytes overwritten: not UTF-8 any more
        raise _damaged(path, f"a text value is not UTF-8 ({exc.reason})") from None
    except sqlite3.DatabaseError as exc:
        if isinstance(exc, (sqlite3.OperationalError, sqlite3.IntegrityError)) and "malformed" not in str(exc):
            raise StoreError(f"{path}: cannot read the study database: {str(exc).splitlines()[0]}") from None
        raise _damaged(path, str(exc).splitlines()[0]) from None


def verify(path: Path, conn: sqlite3.Connection) -> None:
    """Refuse a damaged database: SQLite's ``quick_check`` and foreign keys, every row's checksum, and the
    stored row counts of every participant (a row that vanished from a damaged page is noticed too)."""
    try:
        # integrity_check, not quick_check: it also checks that every index agrees with its table, so a
        # damaged index cannot hide rows from the lookups below.
        bad = [r[0] for r in conn.execute("PRAGMA integrity_check(3)").fetchall() if r[0] != "ok"]
        if bad:
            raise _damaged(path, bad[0].replace("*** in database main ***", "").strip().replace("\n", "; ")[:160])
        fk = conn.execute("PRAGMA foreign_key_check").fetchone()
        if fk:
            raise _damaged(path, f"a row of {fk[0]} refers to a missing row of {fk[2]}")
        have = _tables(conn)
        for table, cols in COLUMNS.items():
            if table not in have:  # an optional table of a database written before it
                continue
            for row in conn.execute(f"SELECT {', '.join(cols)}, crc FROM {table}"):
                try:
                    ok = row_crc(table, row[:-1]) == row[-1]
                except (TypeError, ValueError):  # a BLOB where studyapp writes numbers or text
                    ok = False
                if not ok:
                    raise _damaged(path, f"a row of {table} fails its checksum")
        _check_adaptive(path, conn, have)
        for pid, n_planned, n_answered, n_frames in conn.execute(
                "SELECT id, n_planned, n_answered, n_frames FROM participants"):
            got = tuple(conn.execute(f"SELECT COUNT(*) FROM {t} WHERE participant = ?", (pid,)).fetchone()[0]
                        for t in ("planned_trials", "responses", "frames"))
            if got != (n_planned, n_answered, n_frames):
                raise _damaged(path, f"participant {pid!r} has {got[1]} answers, {got[0]} planned trials and "
                               f"{got[2]} frames; the file recorded {n_answered}, {n_planned} and {n_frames}")
    except UnicodeDecodeError as exc:
        raise _damaged(path, f"a text value is not UTF-8 ({exc.reason})") from None
    except sqlite3.DatabaseError as exc:
        raise _damaged(path, str(exc).splitlines()[0]) from None


def _check_adaptive(path: Path, conn: sqlite3.Connection, have: set[str]) -> None:
    """Every answered trial of an adaptive design (a planned trial that shows a condition of the recorded
    protocol's ``design.adaptive.vary``) has its ``adaptive`` row: without it the procedures would replay a
    shorter history and the export would lose the trial's level."""
    row = conn.execute("SELECT value FROM study WHERE key = 'protocol_json'").fetchone()
    proto = _json(row[0]) if row else None
    adaptive = ((proto or {}).get("design") or {}).get("adaptive") if isinstance(proto, dict) else None
    varied = set((adaptive or {}).get("vary") or {}) if isinstance(adaptive, dict) else set()
    if not varied:
        return
    recorded = set(conn.execute("SELECT participant, idx FROM adaptive").fetchall()) if "adaptive" in have else set()
    for pid, idx, conds in conn.execute("SELECT r.participant, r.idx, t.conditions FROM responses r JOIN "
                                        "planned_trials t ON t.participant = r.participant AND t.idx = r.idx "
                                        "WHERE t.kind = 'trial'"):
        shown = _json(conds)
        if isinstance(shown, list) and varied & {c for c in shown if isinstance(c, str)} and \
                (pid, idx) not in recorded:
            raise _damaged(path, f"participant {pid!r}, trial {idx}: an answered adaptive trial has no adaptive "
                           "record")


def open_store(path, mode: str = "read") -> Store:
    """Open a study database.

    Parameters
    ----------
    path : str or Path
    mode : {"read", "write", "create"}
        ``read``: an existing database on a read-only connection (works on read-only media); ``write``: an
        existing database, for running sessions; ``create``: a new database at a path that does not exist yet
        (``studyapp run`` only).

    Before anything else, an existing file must be an SQLite file with our marker (``application_id``
    "stdy" and ``user_version`` = the store format) and every table, checked from its header and an
    immutable read-only connection (a foreign, empty or incomplete file is refused untouched: no schema, no
    WAL, no side files); then its integrity is verified (:func:`verify`) before it is used.

    Raises
    ------
    StoreError
        One line naming the file, the problem and the way out.
    """
    path = Path(path)
    if mode not in ("read", "write", "create"):
        raise ValueError(f"open_store: mode={mode!r} is invalid: allowed read, write, create")
    if mode == "create":
        return _create(path)
    if not path.exists():
        raise StoreError(f"{path}: no such study database")
    _header(path)
    wal = Path(str(path) + "-wal")
    with damage_is_refused(path):
        if not (wal.exists() and wal.stat().st_size > 0):
            # Recognised without creating anything: immutable = no locks, no -shm/-wal files.
            with contextlib.closing(_connect_immutable(path)) as probe:
                _check_tables(path, probe)
        conn = _connect_ro(path)
        try:
            _check_tables(path, conn)
            verify(path, conn)
        except BaseException:
            conn.close()
            raise
    if mode == "read":
        conn.execute("PRAGMA query_only = ON")
        return Store(path, conn, readonly=True)
    conn.close()
    return Store(path, _connect_rw(path), readonly=False)


def _connect_immutable(path: Path) -> sqlite3.Connection:
    try:
        return sqlite3.connect(_uri(path, mode="ro", immutable=1), uri=True, isolation_level=None)
    except sqlite3.Error as exc:
        raise StoreError(f"{path}: cannot open the study database: {str(exc).splitlines()[0]}") from None


def _connect_rw(path: Path) -> sqlite3.Connection:
    try:
        conn = sqlite3.connect(str(path), isolation_level=None, timeout=10.0)
        conn.execute("PRAGMA journal_mode=WAL")
        conn.execute("PRAGMA synchronous=FULL")
        # Checkpoints (copying the WAL into the database, with its own fsyncs) run when a session ends or
        # pauses for a break, not inside a trial's commit; the WAL may grow to ~40 MB in between.
        conn.execute(f"PRAGMA wal_autocheckpoint={WAL_AUTOCHECKPOINT_PAGES}")
        conn.execute("PRAGMA foreign_keys=ON")
    except (sqlite3.Error, OSError) as exc:
        if _is_full(exc):
            raise StoreError(f"{path}: no space left on device: cannot open the study database") from None
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise StoreError(f"{path}: cannot open the study database for writing: {msg}") from None
    return conn


def _create(path: Path) -> Store:
    """A new study database at ``path``, which must not exist.

    The file is built completely under a temporary name (marker, format, every table) and then linked to
    ``path`` (``link`` fails if ``path`` exists: no race with another process), so a crash or a kill at any
    moment leaves either no database or a complete empty one, never a file that is refused later.
    """
    if path.exists() or path.is_symlink():
        raise StoreError(f"{path}: already exists: only a new path becomes a new study database")
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".creating", dir=path.parent)
        os.close(fd)
        tmp = Path(name)
        conn = sqlite3.connect(str(tmp), isolation_level=None)
        conn.execute("PRAGMA journal_mode=DELETE")
        conn.execute("PRAGMA synchronous=FULL")
        conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
        conn.execute(f"PRAGMA user_version = {STORE_FORMAT}")
        conn.executescript("BEGIN;" + SCHEMA + "COMMIT;")
        conn.close()
        os.chmod(tmp, 0o666 & ~current_umask())
        os.link(tmp, path)
    except FileExistsError:
        raise StoreError(f"{path}: already exists: only a new path becomes a new study database") from None
    except (sqlite3.Error, OSError) as exc:
        if _is_full(exc):
            raise StoreError(f"{path}: no space left on device: cannot create the study database") from None
        reason = getattr(exc, "strerror", None) or str(exc).splitlines()[0]
        raise StoreError(f"{path}: cannot create the study database: {reason}") from None
    finally:
        if tmp is not None:
            remove_database(tmp)
    _fsync_dir(path.parent)
    return Store(path, _connect_rw(path), readonly=False)


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def remove_database(path) -> None:
    """Delete a database and its WAL files (only used on a database this process has just created)."""
    for suffix in ("", "-wal", "-shm", "-journal"):
        Path(str(path) + suffix).unlink(missing_ok=True)


# -- exports and readers used by the analysis ------------------------------------------------------------------
def read_trials(db_path):
    """The tidy trial log of a study database as a pandas DataFrame (columns :data:`ALL_COLUMNS`).

    Text columns are strings (``""`` where a column does not apply to the trial family), ``trial``,
    ``practice``, ``catch`` and ``fps_check_slow`` are int64, ``response`` is float64 (1.0/0.0 for ``yes_no``,
    NaN for the other families) and ``rt_s`` float64 (NaN when not measured); the adaptive ``level``,
    ``intensity``, ``correct`` (1.0/0.0), ``estimate_mean`` and ``estimate_sd`` are float64, NaN outside adaptive
    trials.
    """
    with open_store(db_path) as st:
        if not st.meta():
            raise StoreError(f"{db_path}: the study database is empty")
        rows = st.tidy_rows()
    return tidy_frame(rows)


def tidy_frame(rows: Sequence[dict]):
    """Tidy rows (:func:`tidy_row`) as a DataFrame with the dtypes documented in :func:`read_trials`."""
    import pandas as pd

    df = pd.DataFrame(list(rows), columns=list(ALL_COLUMNS))
    for c in ("trial", "practice", "catch", "fps_check_slow"):
        df[c] = df[c].astype("int64")
    for c in ("response", "rt_s", *TIMING_COLUMNS, "level", "intensity", "correct", "estimate_mean", "estimate_sd"):
        df[c] = pd.to_numeric(df[c], errors="coerce").astype("float64")
    return df


def read_analysis_plan(db_path) -> dict | None:
    """The ``analysis`` block of the protocol a study database was written with (None if it has none).

    Added unless the block sets them: ``family`` and ``protocol`` (name, for information) and ``conditions``
    (the design's conditions in protocol order: the order of the tables).
    """
    with open_store(db_path) as st:
        proto = st.protocol_json()
    if not proto:
        return None
    plan = proto.get("analysis")
    if plan is None:
        return None
    out = dict(plan)
    out.setdefault("family", proto.get("family"))
    out.setdefault("protocol", proto.get("name"))
    conds = proto.get("conditions") or {}
    design = (proto.get("design") or {}).get("conditions") or [
        n for n, c in conds.items() if (c or {}).get("role", "main") == "main"]
    if len(design) >= 2:
        out.setdefault("conditions", list(design))  # the table order of the protocol
    return out


def _fmt(value) -> str:
    if value is None or value == "":
        return ""
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(round(value, 6))
    return str(value)


def tidy_csv_text(rows: Iterable[dict]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(ALL_COLUMNS)
    for r in rows:
        w.writerow([_fmt(r[c]) for c in ALL_COLUMNS])
    return buf.getvalue()


def export_csv(db_path, out) -> Path:
    """Write the tidy trial log as CSV (UTF-8, no BOM, ``\\n`` line ends, empty cell = not applicable)."""
    with open_store(db_path) as st:
        return write_text(out, tidy_csv_text(st.tidy_rows()))


def export_parquet(db_path, out) -> Path:
    """Write the tidy trial log as Parquet (types as in :func:`read_trials`)."""
    df = read_trials(db_path)
    with atomic_path(out) as tmp:
        df.to_parquet(tmp, index=False)
    return Path(out)


def export_pwcmp(db_path, out) -> Path:
    """Write the 2AFC trials (not practice or catch) in pwcmp's layout.

    Columns ``observer, session, scene, condition_1, condition_2, selection``; ``selection`` is 1 when
    ``condition_1`` (shown first/left) was chosen, 2 when ``condition_2`` was.
    """
    with open_store(db_path) as st:
        rows = [r for r in st.tidy_rows() if r["family"] == "2afc" and not r["practice"] and not r["catch"]]
    if not rows:
        raise StoreError(f"{db_path}: no 2afc trials to export in the pwcmp layout")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(("observer", "session", "scene", "condition_1", "condition_2", "selection"))
    for r in rows:
        w.writerow((r["participant"], r["session"], r["scene"], r["condition_a"], r["condition_b"],
                    1 if r["chosen"] == r["condition_a"] else 2))
    return write_text(out, buf.getvalue())


#: Rows ``export --format frames`` reads and converts at a time (as Python objects, ~1 KB a row) ...
FRAMES_BLOCK_ROWS = 32768
#: ... and rows per Parquet row group (held as Arrow columns, ~140 bytes a row; a larger group compresses
#: better): memory is bounded by these, not by the table (docs/benchmarks.md, "Frames export").
FRAMES_ROW_GROUP_ROWS = 262144


def export_frames(db_path, out) -> Path:
    """Write the frames of every live trial (one row per flip) as Parquet (``.parquet``) or CSV.

    Columns: the frames table's, ``idx`` named ``trial``, and ``gaze_age_ms`` (flip time - gaze sample time).
    Streamed: :data:`FRAMES_BLOCK_ROWS` rows at a time from a cursor, written as runs of CSV lines or gathered
    into Parquet row groups of :data:`FRAMES_ROW_GROUP_ROWS`, so memory does not grow with the table. The file
    is the one ``DataFrame.to_csv``/``to_parquet`` of the whole table gives (Parquet: the same bytes up to one
    row group, the same schema and values beyond).
    """
    out = Path(out)
    with open_store(db_path) as st, damage_is_refused(st.path):
        blocks = _frame_blocks(st, FRAMES_BLOCK_ROWS)
        first = next(blocks, None)
        if first is None:
            raise StoreError(f"{db_path}: no live-trial frames to export")
        with atomic_path(out) as tmp:
            if out.suffix.lower() == ".csv":
                with open(tmp, "w", encoding="utf-8", newline="") as fh:
                    for i, rows in enumerate(itertools.chain([first], blocks)):
                        _frames_table(db_path, rows).to_csv(fh, header=i == 0, index=False, lineterminator="\n")
            else:
                import pyarrow as pa
                import pyarrow.parquet as pq

                tables = (pa.Table.from_pandas(_frames_table(db_path, rows), preserve_index=False)
                          for rows in itertools.chain([first], blocks))
                writer = None
                try:
                    for group in _row_groups(tables, FRAMES_ROW_GROUP_ROWS):
                        if writer is None:  # what DataFrame.to_parquet writes: its schema, snappy
                            writer = pq.ParquetWriter(tmp, group.schema, compression="snappy")
                        writer.write_table(group, row_group_size=group.num_rows)
                finally:
                    if writer is not None:
                        writer.close()
    return out


def _row_groups(tables: Iterable, size: int) -> Iterator:
    """Arrow tables joined into tables of at least ``size`` rows (the last may have fewer)."""
    import pyarrow as pa

    pending: list = []
    for t in tables:
        pending.append(t)
        if sum(p.num_rows for p in pending) >= size:
            yield pa.concat_tables(pending)
            pending = []
    if pending:
        yield pa.concat_tables(pending)


def _frame_blocks(st: Store, size: int) -> Iterator[list[tuple]]:
    """The frames table in key order, ``size`` rows at a time, each row checked by :meth:`Store.iter_frames`
    (one cursor: nothing held but the block)."""
    rows = st.iter_frames()
    while block := [tuple(r.values()) for r in itertools.islice(rows, size)]:
        yield block


def _frames_table(db_path, rows: Sequence[tuple]):
    """One block of frame rows as the export's DataFrame: fixed dtypes, so that every block has the same
    schema (text ``participant``, int64 counts, float64 reals with NaN for NULL), ``idx`` named ``trial``, and
    ``gaze_age_ms``."""
    import numpy as np
    import pandas as pd

    data = {}
    for name, values in zip(COLUMNS["frames"], zip(*rows)):
        types = _FRAME_TYPES.get(name, (float, int, type(None)))
        if not all(type(v) in types for v in values):  # exact conversions only (numpy would parse "5", cut 1.5)
            bad = next(v for v in values if type(v) not in types)
            raise StoreError(f"{db_path}: a row of frames holds {name}={bad!r:.40}, not a value studyapp logs: the "
                             "database was not written by studyapp (restore its last good copy)")
        if name == "participant":
            data[name] = list(values)
        else:
            data["trial" if name == "idx" else name] = np.array(values, np.float64 if float in types else np.int64)
    df = pd.DataFrame(data)
    df["gaze_age_ms"] = (df["flip_s"] - df["gaze_t"]) * 1000.0
    return df


#: The Python types SQLite returns for the frames table's columns as studyapp writes them (default: a real,
#: NULL allowed; SQLite may return a whole real as int).
_FRAME_TYPES = {"participant": (str,), "idx": (int,), "frame": (int,), "stimulus": (int,), "dropped": (int,)}


def timed_commit_latencies(db_path, n: int = 1000) -> list[float]:
    """Seconds per :meth:`Store.commit_response` for ``n`` responses in a scratch study (benchmark helper)."""
    lat = []
    with open_store(db_path, "create") as st:
        st.bind_protocol("bench", "1", "0" * 64, {"name": "bench"})
        planned = [PlannedRow(i, "trial", "2afc", "s", "", ("a", "b"), "", False) for i in range(n)]
        st.enrol("B1", 1, 0, "0" * 64, planned)
        sid = st.start_session("B1", "0" * 64, 0, {}, {}, {}, "bench")
        for i in range(n):
            t0 = time.perf_counter()
            st.commit_response("B1", i, sid, ["A"], chosen="a", rt_s=0.5, onset_s=1.0)
            lat.append(time.perf_counter() - t0)
    return lat


def synthetic_frames_study(db_path, n_frames: int, per_trial: int = 720, trials_per_participant: int = 100) -> Path:
    """A new study database holding ``n_frames`` flips of live 2AFC trials (``per_trial`` flips each: 8 s at
    90 Hz), written through :meth:`Store.commit_response` like a session's (benchmark and test helper).

    Every value is one studyapp logs: flips 1/90 s apart, a render time on new frames (None on every 9th: the
    last frame shown again), a gaze sample 4-8 ms old (none on every 50th flip), a camera walking along x,
    every 100th flip dropped.
    """
    from types import SimpleNamespace

    n_trials = -(-n_frames // per_trial)
    with open_store(db_path, "create") as st:
        st.bind_protocol("synthetic_frames", "1", "0" * 64, {"name": "synthetic_frames"})
        for p in range(-(-n_trials // trials_per_participant)):
            pid = f"P{p + 1:03d}"
            first = p * trials_per_participant
            count = min(trials_per_participant, n_trials - first)
            st.enrol(pid, p, p, "0" * 64, [PlannedRow(i, "trial", "2afc", "hall", "", ("LaFR", "GT"), "", False)
                                           for i in range(count)])
            sid = st.start_session(pid, "0" * 64, p, {}, {}, {}, "synthetic")
            for i in range(count):
                n = min(per_trial, n_frames - (first + i) * per_trial)
                flips = [SimpleNamespace(
                    frame=k, stimulus=(k // 360) % 2, flip_s=10.0 * i + k / 90.0,
                    render_s=None if k % 9 == 8 else 0.004 + (k % 7) * 1e-4,
                    gaze_t=None if k % 50 == 49 else 10.0 * i + k / 90.0 - 0.004 - (k % 5) * 1e-3,
                    gaze_x=None if k % 50 == 49 else 960.0 + (k % 200) * 1.5,
                    gaze_y=None if k % 50 == 49 else 540.0 - (k % 120) * 0.75,
                    position=(k * 0.01, 1.6, -3.0), look_at=(k * 0.01, 1.2, 0.0), dropped=k % 100 == 99)
                    for k in range(n)]
                st.commit_response(pid, i, sid, ["A"], chosen="LaFR", rt_s=0.8, onset_s=10.0 * i, frames=flips)
            st.end_session(sid, "completed")
    return Path(db_path)
