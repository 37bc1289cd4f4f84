"""The session store (:class:`Store`): the study's protocol, participants and their planned trials, sessions,
responses (each one fsynced transaction), frame rows of live trials, adaptive rows and session events."""

from __future__ import annotations

import contextlib
import json
import math
import sqlite3
from collections.abc import Iterator, Sequence
from pathlib import Path

from ..errors import UserError
from .identity import process_identity, process_state
from .integrity import _tables, check_frame, damage_is_refused
from .tables import (
    _NOT_OURS, ADAPTIVE_SCHEMA, COLUMNS, STORE_FORMAT, AdaptiveRow, PlannedRow, StoreError, _frame_values, _insert,
    _is_full, _json, _real, _short, _update, utc_now)
from .tidy import adaptive_columns, tidy_row


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
        from ..timing import summary

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
        from ..geometry import PIXELS, EyeView

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
