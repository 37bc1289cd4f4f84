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
``events``         pause, resume, end, break and error events per session

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
import io
import json
import math
import sqlite3
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from .atomic import atomic_path, write_text
from .errors import UserError
from .trial_log import ALL_COLUMNS

STORE_FORMAT = "1"
WAL_AUTOCHECKPOINT_PAGES = 10000

SCHEMA = """
CREATE TABLE IF NOT EXISTS study (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS participants (
    id TEXT PRIMARY KEY, counterbalance INTEGER NOT NULL, seed INTEGER NOT NULL, schedule_hash TEXT NOT NULL,
    n_planned INTEGER NOT NULL, created_utc TEXT NOT NULL, enrol_order INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS sessions (
    id TEXT PRIMARY KEY, participant TEXT NOT NULL REFERENCES participants(id), protocol_hash TEXT NOT NULL,
    software TEXT NOT NULL, display TEXT NOT NULL, measured_refresh_hz REAL, keyboard_backend TEXT,
    presenter TEXT NOT NULL, seed INTEGER NOT NULL, started_utc TEXT NOT NULL, ended_utc TEXT,
    status TEXT NOT NULL, resumed_from TEXT REFERENCES sessions(id));
CREATE TABLE IF NOT EXISTS planned_trials (
    participant TEXT NOT NULL REFERENCES participants(id), idx INTEGER NOT NULL, kind TEXT NOT NULL,
    family TEXT NOT NULL, scene TEXT NOT NULL, block TEXT NOT NULL, conditions TEXT NOT NULL,
    expected TEXT NOT NULL, break_before INTEGER NOT NULL, PRIMARY KEY (participant, idx)) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS responses (
    participant TEXT NOT NULL, idx INTEGER NOT NULL, session TEXT NOT NULL REFERENCES sessions(id),
    answers TEXT NOT NULL, chosen TEXT NOT NULL, chosen_2 TEXT NOT NULL, response INTEGER,
    rt_s REAL, onset_s REAL, dropped_frames INTEGER NOT NULL, switches INTEGER NOT NULL,
    gaze_left_fovea INTEGER, correct INTEGER, committed_utc TEXT NOT NULL,
    PRIMARY KEY (participant, idx),
    FOREIGN KEY (participant, idx) REFERENCES planned_trials(participant, idx)) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS events (
    id INTEGER PRIMARY KEY, session TEXT NOT NULL REFERENCES sessions(id), t_utc TEXT NOT NULL,
    kind TEXT NOT NULL, detail TEXT NOT NULL);
"""


class StoreError(UserError):
    """The store cannot do what was asked; one line naming the file and the problem."""


def utc_now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


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


def _is_full(exc: BaseException) -> bool:
    if isinstance(exc, OSError) and exc.errno == errno.ENOSPC:
        return True
    code = getattr(exc, "sqlite_errorcode", None)
    return code == getattr(sqlite3, "SQLITE_FULL", 13) or "disk is full" in str(exc) or \
        "No space left" in str(exc)


class Store:
    """An open study database. Use :func:`open_store`; close with :meth:`close` (or ``with``)."""

    def __init__(self, path: Path, conn: sqlite3.Connection) -> None:
        self.path = path
        self.conn = conn

    # -- plumbing ------------------------------------------------------------------------------------------
    def __enter__(self) -> Store:  # noqa: PYI034 - a final class
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        with contextlib.suppress(sqlite3.Error):
            self.conn.close()

    @contextlib.contextmanager
    def transaction(self, what: str):
        """``BEGIN IMMEDIATE`` ... ``COMMIT``; any error rolls back and becomes a one-line StoreError."""
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
            return StoreError(f"{self.path}: disk full: could not {what}; nothing already recorded was "
                              "changed (free some space, then run again with --resume)")
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
            rows = {"store_format": STORE_FORMAT, "protocol_name": name, "protocol_version": version,
                    "protocol_hash": content_hash, "created_utc": utc_now(),
                    "protocol_json": json.dumps(protocol, sort_keys=True, default=str)}
            with self.transaction("record the protocol") as c:
                c.executemany("INSERT INTO study (key, value) VALUES (?, ?)", sorted(rows.items()))
            return
        if meta.get("store_format") != STORE_FORMAT:
            raise StoreError(f"{self.path}: store format {meta.get('store_format')!r} is not supported "
                             f"(this studyapp writes format {STORE_FORMAT})")
        if meta.get("protocol_hash") != content_hash:
            raise StoreError(
                f"{self.path}: written by protocol {meta.get('protocol_name')!r} version "
                f"{meta.get('protocol_version')!r} (sha256 {meta.get('protocol_hash', '')[:12]}), not by "
                f"{name!r} version {version!r} (sha256 {content_hash[:12]}): use another --db for a changed protocol")

    def protocol_json(self) -> dict | None:
        text = self.meta().get("protocol_json")
        return json.loads(text) if text else None

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
            c.execute("INSERT INTO participants VALUES (?, ?, ?, ?, ?, ?, ?)",
                      (pid, counterbalance, seed, schedule_hash, len(planned), utc_now(), order))
            c.executemany("INSERT INTO planned_trials VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                          [(pid, t.idx, t.kind, t.family, t.scene, t.block, json.dumps(list(t.conditions)),
                            t.expected, int(t.break_before)) for t in planned])

    def planned(self, pid: str) -> list[PlannedRow]:
        rows = self.conn.execute("SELECT idx, kind, family, scene, block, conditions, expected, break_before "
                                 "FROM planned_trials WHERE participant = ? ORDER BY idx", (pid,)).fetchall()
        return [PlannedRow(r[0], r[1], r[2], r[3], r[4], tuple(json.loads(r[5])), r[6], bool(r[7])) for r in rows]

    def answered(self, pid: str) -> set[int]:
        return {r[0] for r in self.conn.execute("SELECT idx FROM responses WHERE participant = ?", (pid,))}

    def first_unanswered(self, pid: str) -> int | None:
        """Index of the first planned trial without a response (references count as answered once passed)."""
        row = self.conn.execute(
            "SELECT MIN(p.idx) FROM planned_trials p LEFT JOIN responses r ON r.participant = p.participant "
            "AND r.idx = p.idx WHERE p.participant = ? AND r.idx IS NULL", (pid,)).fetchone()
        return row[0]

    # -- sessions ------------------------------------------------------------------------------------------
    def start_session(self, pid: str, protocol_hash: str, seed: int, software: dict, display: dict,
                      measured: dict, presenter: str, resumed_from: str | None = None) -> str:
        with self.transaction(f"start a session of participant {pid!r}") as c:
            n = c.execute("SELECT COUNT(*) FROM sessions WHERE participant = ?", (pid,)).fetchone()[0]
            sid = f"{pid}-s{n + 1}"
            if resumed_from is not None:
                c.execute("UPDATE sessions SET status = 'interrupted', ended_utc = COALESCE(ended_utc, ?) "
                          "WHERE participant = ? AND status = 'running'", (utc_now(), pid))
            c.execute("INSERT INTO sessions VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, NULL, 'running', ?)",
                      (sid, pid, protocol_hash, json.dumps(software, sort_keys=True),
                       json.dumps(display, sort_keys=True), measured.get("refresh_hz"),
                       measured.get("keyboard_backend"), presenter, seed, utc_now(), resumed_from))
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
            c.execute("UPDATE sessions SET status = ?, ended_utc = ? WHERE id = ?", (status, utc_now(), sid))
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
            c.execute("INSERT INTO events (session, t_utc, kind, detail) VALUES (?, ?, ?, ?)",
                      (sid, utc_now(), kind, detail))

    # -- responses -----------------------------------------------------------------------------------------
    def commit_response(self, pid: str, idx: int, sid: str, answers: Sequence[str], chosen: str = "",
                        chosen_2: str = "", response: int | None = None, rt_s: float | None = None,
                        onset_s: float | None = None, dropped_frames: int = 0, switches: int = 0,
                        gaze_left_fovea: bool | None = None, correct: bool | None = None) -> None:
        """Write one response durably (fsynced commit) before the next trial starts."""
        rt = None if rt_s is None or not math.isfinite(rt_s) else float(rt_s)
        onset = None if onset_s is None or not math.isfinite(onset_s) else float(onset_s)
        with self.transaction(f"save the response to trial {idx} of participant {pid!r}") as c:
            c.execute("INSERT INTO responses VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                      (pid, idx, sid, json.dumps(list(answers)), chosen, chosen_2, response, rt, onset,
                       int(dropped_frames), int(switches), None if gaze_left_fovea is None else int(gaze_left_fovea),
                       None if correct is None else int(correct), utc_now()))

    # -- reading -------------------------------------------------------------------------------------------
    def sessions(self) -> list[dict]:
        cols = ("id", "participant", "status", "started_utc", "ended_utc", "resumed_from", "presenter", "seed",
                "measured_refresh_hz")
        rows = self.conn.execute(f"SELECT {', '.join('s.' + c for c in cols)}, "
                                 "(SELECT COUNT(*) FROM responses r WHERE r.session = s.id) "
                                 "FROM sessions s ORDER BY s.rowid").fetchall()
        return [dict(zip(cols + ("responses",), r)) for r in rows]

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
        return [tidy_row(pid, sid, block, scene, idx, fam, json.loads(conds), chosen, chosen_2, resp, rt, kind)
                for pid, sid, block, scene, idx, fam, conds, chosen, chosen_2, resp, rt, kind in self.conn.execute(q)]


def tidy_row(participant: str, session: str, block: str, scene: str, trial: int, family: str,
             conditions: Sequence[str], chosen: str, chosen_2: str, response, rt_s, kind: str) -> dict:
    """One row of the tidy log (:data:`ALL_COLUMNS`; ``""`` where a column does not apply to the family)."""
    row = dict.fromkeys(ALL_COLUMNS, "")
    row.update(participant=participant, session=session, block=block, scene=scene, trial=trial, family=family,
               chosen=chosen, chosen_2=chosen_2, response=response, rt_s=rt_s,
               practice=int(kind == "practice"), catch=int(kind == "catch"))
    if family == "yes_no":
        row["condition"] = conditions[0]
        row["chosen"] = ""
    elif family == "2afc":
        row["condition_a"], row["condition_b"] = conditions[0], conditions[1]
    else:
        row["conditions"] = "|".join(conditions)
    return row


def open_store(path, create: bool = True) -> Store:
    """Open (or create) a study database with WAL and ``synchronous=FULL``.

    Raises
    ------
    StoreError
        The file is not a study database, is locked, or cannot be created.
    """
    path = Path(path)
    if not create and not path.exists():
        raise StoreError(f"{path}: no such study database")
    if path.exists() and path.is_dir():
        raise StoreError(f"{path}: is a folder, not a study database")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        conn = sqlite3.connect(str(path), isolation_level=None, timeout=10.0)
        conn.execute("PRAGMA journal_mode=WAL")
        conn.execute("PRAGMA synchronous=FULL")
        # Checkpoints (copying the WAL into the database, with its own fsyncs) run when a session ends or
        # pauses for a break, not inside a trial's commit; the WAL may grow to ~40 MB in between.
        conn.execute(f"PRAGMA wal_autocheckpoint={WAL_AUTOCHECKPOINT_PAGES}")
        conn.execute("PRAGMA foreign_keys=ON")
        existing = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if existing and "study" not in existing:
            conn.close()
            raise StoreError(f"{path}: not a studyapp study database (tables: {', '.join(sorted(existing))})")
        if not existing:
            conn.executescript(SCHEMA)
    except StoreError:
        raise
    except (sqlite3.Error, OSError) as exc:
        if _is_full(exc):
            raise StoreError(f"{path}: disk full: cannot create the study database") from None
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise StoreError(f"{path}: cannot open the study database: {msg}") from None
    return Store(path, conn)


# -- exports and readers used by the analysis ------------------------------------------------------------------
def read_trials(db_path):
    """The tidy trial log of a study database as a pandas DataFrame (columns :data:`ALL_COLUMNS`).

    Text columns are strings (``""`` where a column does not apply to the trial family), ``trial``,
    ``practice`` and ``catch`` are int64, ``response`` is float64 (1.0/0.0 for ``yes_no``, NaN for the other
    families) and ``rt_s`` float64 (NaN when not measured).
    """
    with open_store(db_path, create=False) as st:
        if not st.meta():
            raise StoreError(f"{db_path}: the study database is empty")
        rows = st.tidy_rows()
    return tidy_frame(rows)


def tidy_frame(rows: Sequence[dict]):
    """Tidy rows (:func:`tidy_row`) as a DataFrame with the dtypes documented in :func:`read_trials`."""
    import pandas as pd

    df = pd.DataFrame(list(rows), columns=list(ALL_COLUMNS))
    for c in ("trial", "practice", "catch"):
        df[c] = df[c].astype("int64")
    for c in ("response", "rt_s"):
        df[c] = pd.to_numeric(df[c], errors="coerce").astype("float64")
    return df


def read_analysis_plan(db_path) -> dict | None:
    """The ``analysis`` block of the protocol a study database was written with (None if it has none).

    Added unless the block sets them: ``family`` and ``protocol`` (name, for information) and ``conditions``
    (the design's conditions in protocol order: the order of the tables).
    """
    with open_store(db_path, create=False) as st:
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
    with open_store(db_path, create=False) as st:
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
    with open_store(db_path, create=False) as st:
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


def timed_commit_latencies(db_path, n: int = 1000) -> list[float]:
    """Seconds per :meth:`Store.commit_response` for ``n`` responses in a scratch study (benchmark helper)."""
    lat = []
    with open_store(db_path) as st:
        st.bind_protocol("bench", "1", "0" * 64, {"name": "bench"})
        planned = [PlannedRow(i, "trial", "2afc", "s", "", ("a", "b"), "", False) for i in range(n)]
        st.enrol("B1", 1, 0, "0" * 64, planned)
        sid = st.start_session("B1", "0" * 64, 0, {}, {}, {}, "bench")
        for i in range(n):
            t0 = time.perf_counter()
            st.commit_response("B1", i, sid, ["A"], chosen="a", rt_s=0.5, onset_s=1.0)
            lat.append(time.perf_counter() - t0)
    return lat
