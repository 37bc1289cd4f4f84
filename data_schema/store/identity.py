"""Identity: of a study database (the SQLite header carries studyapp's marker and store format) and of the process
that runs a session (host, pid, start time, boot: is the owner of a ``running`` session still alive?)."""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path

from ..atomic import input_file
from .tables import APPLICATION_ID, SQLITE_MAGIC, STORE_FORMAT, StoreError


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
