"""Open modes of a study database (:func:`open_store`): ``read`` (read-only connection, read-only media too),
``write`` (an existing database, for running or resuming sessions) and ``create`` (a new file, complete or absent);
an existing file is recognised (:mod:`.identity`) and verified (:mod:`.integrity`) before it is used."""

from __future__ import annotations

import contextlib
import os
import sqlite3
import tempfile
from pathlib import Path

from ..atomic import current_umask
from .identity import _header
from .integrity import _check_tables, damage_is_refused, verify
from .session import Store
from .tables import APPLICATION_ID, SCHEMA, STORE_FORMAT, WAL_AUTOCHECKPOINT_PAGES, StoreError, _is_full


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
