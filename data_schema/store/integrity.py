"""Integrity checks of a study database: damaged files refused in one line (SQLite's own checks, every row's
checksum, the stored row counts, adaptive records), and the checks of each frame row as it is read."""

from __future__ import annotations

import contextlib
import sqlite3
from pathlib import Path

from .tables import _NOT_OURS, COLUMNS, OPTIONAL_TABLES, StoreError, _json, _short, row_crc

#: Bounds of what a frame row holds: the presenter's clock (seconds), gaze in display pixels, scene units.
FRAME_TIME_S, FRAME_PIXELS, FRAME_SCENE = 1e9, 1e6, 1e9


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


def _damaged(path: Path, detail: str) -> StoreError:
    return StoreError(f"{path}: the study database is damaged ({detail}); nothing was read or changed: restore "
                      f"its last good copy, or salvage what is left with `sqlite3 {path.name} .recover | sqlite3 "
                      "recovered.db` and check it by hand")


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
