"""Fuzzing names and output targets (issue 25, items 1, 2 and 10): random names through ``check_name`` and
``inside`` never escape their folder and never raise anything but a one-line ``UserError``; random target kinds
through every writer of ``data_schema.atomic`` are written (new, regular, a link to a regular file or folder)
or refused unopened and unchanged. Bounded to a few seconds."""

from __future__ import annotations

import contextlib
import os
import socket
import stat
from pathlib import Path

from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from data_schema import atomic
from data_schema.errors import UserError
from data_schema.names import check_name, inside

FUZZ = settings(max_examples=200, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

PIECES = st.sampled_from(["", ".", "..", "/", "\\", "\0", "\n", " ", ":", "*", "CON", "nul", "com1", "LPT9",
                          ".txt", "a", "GT", "é", "e\u0301", "\u202e", "\U0001f600", "~", "C:", "//", "x" * 60])
NAMES = st.one_of(st.text(max_size=30), st.lists(PIECES, max_size=6).map("".join),
                  st.text(alphabet=st.sampled_from("./\\\0 a:"), max_size=8))


@FUZZ
@given(name=NAMES, nested=st.lists(NAMES, max_size=2))
@example(name="..", nested=[])
@example(name="a", nested=["..", ".."])
@example(name="/etc", nested=[])
def test_names_never_escape(tmp_path_factory, name, nested):
    folder = tmp_path_factory.getbasetemp() / "names"
    folder.mkdir(exist_ok=True)
    try:
        assert check_name("scene", name) == name
        accepted = True
    except UserError as exc:
        assert "\n" not in str(exc) and str(exc).startswith(f"scene name {name!r}: ")
        accepted = False
    if accepted:  # one plain component: a child of the folder, and inside() agrees
        assert inside(folder, name) == folder / name and (folder / name).parent == folder
    try:
        path = inside(folder, name, *nested)
    except UserError as exc:
        assert "would be written outside" in str(exc) and "\n" not in str(exc)
        return
    assert path.resolve().is_relative_to(folder.resolve())


# -- output targets ---------------------------------------------------------------------------------------------
KINDS = ("new", "regular", "link_regular", "folder", "link_folder", "devnull", "fifo", "socket", "link_devnull",
         "link_fifo", "dangling", "under_devnull")
WRITERS = ("write_text", "write_bytes", "atomic_files", "atomic_dir", "check_target", "check_dir_target")




def _make(kind: str, folder: Path, keep: list) -> Path:
    t = folder / "t"
    if kind == "regular":
        t.write_text("old\n")
        os.chmod(t, 0o640)
    elif kind == "link_regular":
        (folder / "real").write_text("old\n")
        t.symlink_to(folder / "real")
    elif kind == "folder":
        t.mkdir()
        (t / "analysis.json").write_text("{}\n")
    elif kind == "link_folder":
        (folder / "realdir").mkdir()
        t.symlink_to(folder / "realdir")
    elif kind == "devnull":
        return Path("/dev/null")
    elif kind in ("fifo", "link_fifo"):
        os.mkfifo(folder / "fifo")
        if kind == "fifo":
            return folder / "fifo"
        t.symlink_to(folder / "fifo")
    elif kind == "socket":
        s = socket.socket(socket.AF_UNIX)
        cwd = os.getcwd()
        os.chdir(folder)  # an AF_UNIX path has 108 bytes at most: bind the short relative name
        try:
            s.bind("t")
        finally:
            os.chdir(cwd)
        keep.append(s)
    elif kind == "link_devnull":
        t.symlink_to("/dev/null")
    elif kind == "dangling":
        t.symlink_to(folder / "missing")
    elif kind == "under_devnull":
        return Path("/dev/null/t")
    return t


def _write(writer: str, target: Path) -> None:
    if writer == "write_text":
        atomic.write_text(target, "new\n")
    elif writer == "write_bytes":
        atomic.write_bytes(target, b"new\n")
    elif writer == "atomic_files":
        with atomic.atomic_files([target]) as (tmp,):
            tmp.write_text("new\n")
    elif writer == "atomic_dir":
        with atomic.atomic_dir(target, "analysis.json") as tmp:
            (tmp / "analysis.json").write_text("new\n")
    elif writer == "check_target":
        atomic.check_target(target)
    else:
        atomic.check_dir_target(target, "analysis.json")


def _state(path: Path):
    with contextlib.suppress(FileNotFoundError, NotADirectoryError):
        st = os.lstat(path)
        with contextlib.suppress(FileNotFoundError):
            target = os.stat(path)
            return (st.st_mode, st.st_ino, st.st_rdev, target.st_mode, target.st_ino, target.st_rdev)
        return (st.st_mode, st.st_ino)
    return None


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(kind=st.sampled_from(KINDS), writer=st.sampled_from(WRITERS))
def test_writers_write_or_refuse_unopened(tmp_path_factory, hang_guard, kind, writer):
    folder = tmp_path_factory.mktemp("t")
    keep: list = []
    target = _make(kind, folder, keep)
    before, listing = _state(target), sorted(os.listdir(folder))
    folder_writer = writer in ("atomic_dir", "check_dir_target")
    fits = kind == "new" or kind in (("folder", "link_folder") if folder_writer else ("regular", "link_regular"))
    try:
        with hang_guard(20):
            _write(writer, target)
        refused = None
    except UserError as exc:
        refused = str(exc)
    finally:
        for s in keep:
            s.close()
    if not fits:
        assert refused is not None and "\n" not in refused, (kind, writer)
        assert _state(target) == before and sorted(os.listdir(folder)) == listing
        assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
        return
    assert refused is None, refused
    if writer.startswith("check"):
        assert _state(target) == before
        return
    real = Path(os.path.realpath(target))
    assert os.path.islink(target) == kind.startswith("link")  # a link is written through, never replaced
    content = (real / "analysis.json") if folder_writer else real
    assert content.read_text() == "new\n"
    if kind == "regular":
        assert stat.S_IMODE(os.stat(target).st_mode) == 0o640
    assert not [n for n in os.listdir(folder) if n.endswith(".tmp")]
