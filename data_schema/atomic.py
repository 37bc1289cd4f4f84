"""Atomic file writes: write to a temporary file in the same folder, fsync, then rename over the target.

A reader (or a crash) never sees a half-written file: either the old content or the new one. A failed write
removes its temporary file and reports the *target* (never the temporary name) in one line, e.g.
``results/report.md: cannot write: no space left on device``. :func:`atomic_dir` does the same for a folder of
files, and :func:`check_target` refuses targets whose loss would destroy data (a study database). A process
killed mid-write leaves its temporary file: :func:`remove_stale_temporaries` removes those, and
:func:`sole_writer` keeps a second writer out of a folder so that the sweep cannot take a live one's file.

What may be written to
----------------------
A file target is a new name, or an existing regular file; a folder target a new name or an existing folder
(:func:`real_file`, :func:`real_folder`, asked by every function here). Anything else is refused in one line
*without being opened* (``lstat``/``stat`` only): a device node (``/dev/null``), a FIFO (opening one blocks until
a writer comes), a socket, a symlink to any of them (``/dev/stdout`` while stdout is a pipe), a symlink to a
missing file, a symlink through an open file descriptor (``/dev/stdout``, ``/proc/self/fd/1`` even when stdout is
a file: whatever the shell redirected there is not a name to replace), and a path under something that is not a
folder. A symlink to a regular file (or a folder) is written *through*: the real file is replaced and the link is
kept, as a plain ``open(path, "w")`` would; the link is never replaced by a file. A replaced file keeps its
permission bits (``st_mode & 0o7777``) and, where the process may (as root), its owner and group; a new file
gets 0666 less the umask, a new folder 0777 less it.
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
from .names import printable

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
    lock = real_file(Path(folder) / f".{command}.lock")  # a FIFO planted there would block the open below
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


#: What a file that is neither a regular file nor a folder is, by its ``stat`` type.
_SPECIAL_KINDS = ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                  (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"))


def _kind(mode: int) -> str:
    if stat.S_ISREG(mode):
        return "a regular file"
    if stat.S_ISDIR(mode):
        return "a folder"
    return next((name for test, name in _SPECIAL_KINDS if test(mode)), "a special file")


def _choose(what: str, option: str | None) -> str:
    return f"choose {what}" + (f" for {option}" if option else "")


def _lstat(path: Path) -> os.stat_result | None:
    """``lstat`` of ``path``, None when nothing is there; never opens it."""
    try:
        return os.lstat(path)
    except (FileNotFoundError, NotADirectoryError):
        return None
    except ValueError:  # a NUL in the name
        raise UserError(f"{printable(path)}: holds a NUL character: choose another name") from None
    except OSError as exc:
        raise _write_error(path, exc) from None


def _followed(path: Path, st: os.stat_result, option: str | None) -> tuple[os.stat_result, str]:
    """``(stat, "a symlink to ")`` of what the symlink ``path`` leads to, ``(st, "")`` for anything else."""
    if not stat.S_ISLNK(st.st_mode):
        return st, ""
    try:
        return os.stat(path), "a symlink to "
    except FileNotFoundError:
        raise UserError(f"{printable(path)}: is a symlink to a missing file ({printable(os.readlink(path))}): "
                        f"{_choose('the file name itself', option)}") from None
    except OSError as exc:  # a symlink loop
        raise _write_error(path, exc) from None


def _check_parents(path: Path, option: str | None) -> None:
    """Refuse a new ``path`` whose nearest existing ancestor is not a folder (``/dev/null/x.csv``)."""
    for parent in path.parents:
        st = _lstat(parent)
        if st is None:
            continue
        st, link = _followed(parent, st, option)
        if not stat.S_ISDIR(st.st_mode):
            raise UserError(f"{printable(path)}: cannot write: {printable(parent)} is {link}{_kind(st.st_mode)}, not a "
                            f"folder: {_choose('another path', option)}")
        return


def _real(path, option: str | None, folder: bool) -> Path:
    path = Path(path)
    st = _lstat(path)
    if st is None:
        _check_parents(path, option)
        return path
    st, link = _followed(path, st, option)
    want = ("a folder", "a folder") if folder else ("a regular file", "a file name")
    if not (stat.S_ISDIR if folder else stat.S_ISREG)(st.st_mode):
        raise UserError(f"{printable(path)}: is {link}{_kind(st.st_mode)}, not {want[0]}: {_choose(want[1], option)}")
    if not link:
        return path
    real = Path(os.path.realpath(path))
    hop = _descriptor_hop(path)
    if hop is not None or not real.exists() or not os.path.samefile(real, path):
        raise UserError(f"{printable(path)}: is a file descriptor's link ({printable(hop or real)}), not a "
                        f"{'folder' if folder else 'file'} name: {_choose(want[1], option)}")
    return real


def _descriptor_hop(path: Path) -> Path | None:
    """The first hop of the symlink chain from ``path`` that is a file descriptor's magic link (``/proc/self/fd/1``
    behind ``/dev/stdout``), or None: its "target" is whatever the descriptor has open (a shell's redirect, a
    deleted file), not a name to write through."""
    for _ in range(40):  # the kernel follows at most 40 links
        if path.parts[:2] == ("/", "proc") or path.parts[:3] == ("/", "dev", "fd"):
            return path
        if not path.is_symlink():
            return None
        target = Path(os.readlink(path))
        path = target if target.is_absolute() else path.parent / target
    return None


def real_file(path, option: str | None = None) -> Path:
    """The file a write to ``path`` replaces: ``path`` (new or a regular file), or the regular file a symlink
    leads to; anything else is refused in one line without being opened (see the module docstring).

    ``option`` (``--out``) is named in the message: ``/dev/null: is a character device, not a regular file:
    choose a file name for --out``.
    """
    return _real(path, option, folder=False)


def real_folder(path, option: str | None = None) -> Path:
    """The folder written into for ``path``: ``path`` (new or a folder), or the folder a symlink leads to;
    anything else is refused in one line without being opened, as in :func:`real_file`."""
    return _real(path, option, folder=True)


def input_file(path, what: str = "file", error: type[UserError] = UserError) -> Path:
    """``path`` if it is missing (the reader says so in its own words) or a regular file, or a symlink to one;
    anything else is refused in one line *without being opened*: a folder, and a FIFO (opening one blocks until
    a writer comes), device or socket, or a symlink to one. For every reader of a user's file (protocols,
    scenes, plans, study databases, logs, images, gaze CSVs); ``what`` names it in the message, ``error`` is the
    reader's :class:`UserError` subclass.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        return path
    except ValueError:  # a NUL in the name
        raise error(f"{printable(path)}: holds a NUL character: not a {what}") from None
    except OSError as exc:
        raise error(f"{printable(path)}: cannot read the {what}: {(exc.strerror or str(exc)).lower()}") from None
    if not stat.S_ISREG(st.st_mode):
        link = "a symlink to " if path.is_symlink() else ""
        raise error(f"{printable(path)}: is {link}{_kind(st.st_mode)}, not a {what}: refusing to read it")
    return path


def _take_mode_and_owner(tmp: Path, target: Path, new_mode: int) -> None:
    """Give ``tmp`` the permission bits and, where allowed (as root), the owner of the ``target`` it replaces;
    ``new_mode`` less the umask when there is no target."""
    try:
        st = os.stat(target)
    except FileNotFoundError:
        os.chmod(tmp, new_mode & ~current_umask())
        return
    mine = os.stat(tmp)
    if hasattr(os, "chown") and (mine.st_uid, mine.st_gid) != (st.st_uid, st.st_gid):
        with contextlib.suppress(PermissionError):  # only root may give a file away: else it becomes ours
            os.chown(tmp, st.st_uid, st.st_gid)
    os.chmod(tmp, stat.S_IMODE(st.st_mode))  # after chown, which clears set-id bits


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path next to ``path``; on success it is fsynced and renamed to ``path``.

    ``path`` must be new or a regular file (a symlink to one is written through: :func:`real_file`). A new file
    gets the usual permissions (0666 less the process umask), not ``mkstemp``'s 0600; a replaced one keeps its
    mode and owner. An ``OSError`` while writing becomes a one-line :class:`UserError` naming ``path``.
    """
    path = Path(path)
    real = real_file(path)
    try:
        real.parent.mkdir(parents=True, exist_ok=True)
        tmp = _new_temporary(real)
    except OSError as exc:
        raise _write_error(path, exc) from None
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        _take_mode_and_owner(tmp, real, 0o666)
        os.replace(tmp, real)
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
    reals = [real_file(t) for t in targets]
    tmps: list[Path] = []
    try:
        for t in reals:
            t.parent.mkdir(parents=True, exist_ok=True)
            tmps.append(_new_temporary(t))
        yield list(tmps)
        for tmp, t in zip(tmps, reals):
            with open(tmp, "rb+") as fh:
                os.fsync(fh.fileno())
            _take_mode_and_owner(tmp, t, 0o666)
        for tmp, t in zip(tmps, reals):
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
    path = Path(path)
    real = real_folder(check_dir_target(path, marker))
    try:
        real.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{real.name}.", suffix=".tmp", dir=real.parent))
        os.chmod(tmp, 0o777 & ~current_umask())
    except OSError as exc:
        raise _write_error(path, exc) from None
    try:
        yield tmp
        _take_mode_and_owner(tmp, real, 0o777)  # after the writes: the old folder may have been read-only
        old = None
        if real.exists():
            old = real.with_name(f".{real.name}.old-{os.getpid()}")
            os.replace(real, old)
        os.replace(tmp, real)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, OSError):
            raise _write_error(path, exc) from None
        if isinstance(exc, UserError) and str(tmp) in str(exc):  # name the target, never the temporary folder
            raise UserError(str(exc).replace(str(tmp), str(path))) from None
        raise


def check_dir_target(path, marker: str, option: str | None = "--out") -> Path:
    """Refuse an output folder that :func:`atomic_dir` would not replace (see there, and :func:`real_folder`);
    return it as a Path."""
    path = Path(path)
    real_folder(path, option)
    if path.is_dir() and any(path.iterdir()) and not (path / marker).exists():
        raise UserError(f"{path}: is a folder with other files in it (no {marker}): choose an empty or new "
                        "--out folder")
    return path


def is_sqlite_file(path) -> bool:
    """Whether ``path`` is a regular file (or a symlink to one) that starts like an SQLite database; anything
    else is never opened (a FIFO would block)."""
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return False
        with open(path, "rb") as fh:
            return fh.read(16) == SQLITE_MAGIC
    except OSError:
        return False


def check_target(path, inputs: Iterable = (), option: str | None = "--out") -> Path:
    """Refuse an output path whose writing would destroy data; return it as a Path.

    Refused: anything but a new name or a regular file (:func:`real_file`, named with ``option``), one of the
    command's ``inputs`` (the same path, or the same file by inode, e.g. through a link),
    their SQLite side files (``-wal``, ``-shm``), and any existing SQLite database (a study database is never
    overwritten by an export or a report).
    """
    path = Path(path)
    if (st := _lstat(path)) is not None and stat.S_ISDIR(_followed(path, st, option)[0].st_mode):
        raise UserError(f"{printable(path)}: is a folder: give a file name" + (f" for {option}" if option else ""))
    real_file(path, option)
    for src in inputs:
        src = Path(src)
        for candidate in (src, Path(str(src) + "-wal"), Path(str(src) + "-shm")):
            same = path.resolve() == candidate.resolve()
            with contextlib.suppress(OSError):
                same = same or (path.exists() and candidate.exists() and path.samefile(candidate))
            if same:
                raise UserError(f"{path}: is the input {src}: refusing to overwrite it (choose another --out)")
    if is_sqlite_file(path):
        raise UserError(f"{path}: is an SQLite database: refusing to overwrite it (choose another --out)")
    return path
