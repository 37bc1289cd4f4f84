"""Atomic file writes: write to a temporary file in the same folder, fsync, then rename over the target.

A reader (or a crash) never sees a half-written file: either the old content or the new one. A failed write
removes its temporary file and reports the *target* (never the temporary name) in one line, e.g.
``results/report.md: cannot write: no space left on device``. :func:`atomic_dir` does the same for a folder of
files, and :func:`check_target` refuses targets whose loss would destroy data (a study database). A process
killed mid-write leaves its temporary file: :func:`remove_stale_temporaries` removes those, and
:func:`sole_writer` keeps a second writer out of a folder so that the sweep cannot take a live one's file.
"""

from __future__ import annotations

import contextlib
import errno
import itertools
import os
import re
import shutil
import stat
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path

from .errors import UserError

SQLITE_MAGIC = b"SQLite format 3\x00"

#: The name of an atomic write's temporary file: ``.<target name>.<mkstemp's 8 random characters>.tmp``.
TEMPORARY_NAME = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp", re.DOTALL)  # a name may hold a line break
#: A temporary file older than this was left by a process that was killed mid-write (SIGKILL, power cut): every
#: write of ours renames its temporary file within seconds (a frame, a stats record), so none is this old.
STALE_TEMPORARY_S = 600.0


def current_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _new_temporary(path: Path) -> Path:
    """A new, empty temporary file next to ``path`` whose name matches :data:`TEMPORARY_NAME`."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    return Path(tmp)


def remove_stale_temporaries(folder, older_than_s: float = STALE_TEMPORARY_S) -> int:
    """Remove the temporary files that killed writers left in ``folder``; return how many.

    Only regular files named like ours (:data:`TEMPORARY_NAME`) and last modified over ``older_than_s`` seconds
    ago are removed, so a write under way in another process keeps its file (``older_than_s=0`` where
    :func:`sole_writer` rules out any) and a user's own files are never touched. For folders only our commands
    write to (a stimulus set, the stimulus cache), before they resume.
    """
    folder = Path(folder)
    if not folder.is_dir():
        return 0
    cutoff = time.time() - older_than_s
    removed = 0
    for f in folder.glob(".*.tmp"):
        with contextlib.suppress(OSError):  # gone already, or not ours to remove: leave it
            st = f.lstat()
            if TEMPORARY_NAME.fullmatch(f.name) and stat.S_ISREG(st.st_mode) and st.st_mtime < cutoff:
                f.unlink()
                removed += 1
    return removed


@contextlib.contextmanager
def sole_writer(folder, command: str):
    """Run the block as the only ``command`` writing into ``folder``; yield True when that is locked in.

    A second process that asks for the same folder meanwhile is refused in one line. The lock (``fcntl.flock``
    on the empty file ``folder/.<command>.lock``, which stays: its content never differs between runs) ends with
    its process however that ends, SIGKILL included, so a killed writer never blocks the next. A block that
    wrote nothing into a folder this had to create (a refused or failed command) leaves no folder and no lock.
    Where there are no such locks (Windows) the block runs unlocked and this yields False.
    """
    try:
        import fcntl
    except ImportError:
        yield False
        return
    lock = Path(folder) / f".{command}.lock"
    new = list(itertools.takewhile(lambda d: not d.exists(), (lock.parent, *lock.parent.parents)))
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(lock, os.O_RDONLY | os.O_CREAT, 0o666)
    except OSError as exc:
        raise _write_error(lock, exc) from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise UserError(f"{lock.parent}: another {command} is writing here: wait for it to end") from None
        yield True
    finally:
        with contextlib.suppress(OSError):
            if new and [f.name for f in lock.parent.iterdir()] == [lock.name]:  # nothing written: leave no trace
                lock.unlink()
                for d in new:  # the deepest first; a folder with anything in it stays
                    d.rmdir()
        os.close(fd)


def _write_error(path: Path, exc: OSError) -> UserError:
    reason = "no space left on device" if exc.errno == errno.ENOSPC else (exc.strerror or str(exc)).lower()
    return UserError(f"{path}: cannot write: {reason}")


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path next to ``path``; on success it is fsynced and renamed to ``path``.

    The file gets the usual permissions of a new file (0666 less the process umask), not ``mkstemp``'s 0600.
    An ``OSError`` while writing becomes a one-line :class:`UserError` naming ``path``.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = _new_temporary(path)
    except OSError as exc:
        raise _write_error(path, exc) from None
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise _write_error(path, exc) from None
        raise


def write_text(path, text: str) -> Path:
    """Atomically write ``text`` (UTF-8, ``\\n`` line ends) to ``path``."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8", newline="\n")
    return Path(path)


def write_bytes(path, data: bytes) -> Path:
    """Atomically write ``data`` to ``path``."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


@contextlib.contextmanager
def atomic_files(paths: Iterable):
    """Yield temporary paths for files that belong together (a PNG and its linear image): they are renamed
    into place, in the given order, only after every one was written and fsynced; a failure or Ctrl-C before
    that removes them all. Put the file whose presence marks completeness last."""
    targets = [Path(p) for p in paths]
    tmps: list[Path] = []
    try:
        for t in targets:
            t.parent.mkdir(parents=True, exist_ok=True)
            tmps.append(_new_temporary(t))
        yield list(tmps)
        for tmp in tmps:
            with open(tmp, "rb+") as fh:
                os.fsync(fh.fileno())
            os.chmod(tmp, 0o666 & ~current_umask())
        for tmp, t in zip(tmps, targets):
            os.replace(tmp, t)
    except BaseException as exc:
        for tmp in tmps:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
        if isinstance(exc, OSError):
            raise _write_error(targets[-1], exc) from None  # the pair is named by its last (marker) file
        raise


@contextlib.contextmanager
def atomic_dir(path, marker: str):
    """Yield a temporary folder next to ``path``; on success it replaces ``path`` (a report folder).

    ``path`` may not exist, be empty, or hold an earlier output of the same command (it contains ``marker``,
    e.g. ``analysis.json``); a folder with other content is refused before anything is written, so nothing
    that is not ours is replaced. On failure (full disk, Ctrl-C) the temporary folder is removed and ``path``
    is as it was.
    """
    path = check_dir_target(path, marker)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
        os.chmod(tmp, 0o777 & ~current_umask())
    except OSError as exc:
        raise _write_error(path, exc) from None
    try:
        yield tmp
        old = None
        if path.exists():
            old = path.with_name(f".{path.name}.old-{os.getpid()}")
            os.replace(path, old)
        os.replace(tmp, path)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, OSError):
            raise _write_error(path, exc) from None
        if isinstance(exc, UserError) and str(tmp) in str(exc):  # name the target, never the temporary folder
            raise UserError(str(exc).replace(str(tmp), str(path))) from None
        raise


def check_dir_target(path, marker: str) -> Path:
    """Refuse an output folder that :func:`atomic_dir` would not replace (see there); return it as a Path."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UserError(f"{path}: exists and is not a folder: choose a new --out folder")
    if path.is_dir() and any(path.iterdir()) and not (path / marker).exists():
        raise UserError(f"{path}: is a folder with other files in it (no {marker}): choose an empty or new "
                        "--out folder")
    return path


def is_sqlite_file(path) -> bool:
    try:
        with open(path, "rb") as fh:
            return fh.read(16) == SQLITE_MAGIC
    except OSError:
        return False


def check_target(path, inputs: Iterable = ()) -> Path:
    """Refuse an output path whose writing would destroy data; return it as a Path.

    Refused: one of the command's ``inputs`` (the same path, or the same file by inode, e.g. through a link),
    their SQLite side files (``-wal``, ``-shm``), and any existing SQLite database (a study database is never
    overwritten by an export or a report).
    """
    path = Path(path)
    for src in inputs:
        src = Path(src)
        for candidate in (src, Path(str(src) + "-wal"), Path(str(src) + "-shm")):
            same = path.resolve() == candidate.resolve()
            with contextlib.suppress(OSError):
                same = same or (path.exists() and candidate.exists() and path.samefile(candidate))
            if same:
                raise UserError(f"{path}: is the input {src}: refusing to overwrite it (choose another --out)")
    if path.is_dir():
        raise UserError(f"{path}: is a folder: give a file name")
    if path.exists() and is_sqlite_file(path):
        raise UserError(f"{path}: is an SQLite database: refusing to overwrite it (choose another --out)")
    return path
