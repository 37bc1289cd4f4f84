"""Output targets (issue 25, item 1): every command that writes refuses a device node, a FIFO, a socket and a
symlink to any of them without opening it (one line, exit 2, the target unchanged, nothing created); a
symlink to a regular file is written through; a replaced file keeps its mode and owner.

The CLI runs in this process under an alarm (the ``hang_guard`` fixture): a command that opened the FIFO would
block, and the alarm turns that into a failure instead of a hang.
"""

from __future__ import annotations

import os
import socket
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from data_schema.atomic import (
    atomic_dir,
    check_dir_target,
    check_target,
    current_umask,
    is_sqlite_file,
    real_file,
    write_text,
)
from data_schema.errors import UserError
from data_schema.store import PlannedRow, open_store
from studyapp.cli import main

ROOT = Path(__file__).resolve().parents[1]
PROTOCOL = ROOT / "studyapp" / "protocols" / "seed001_2afc.yaml"
KINDS = ("devnull", "fifo", "socket", "link_devnull", "link_fifo")




def _make(kind: str, folder: Path, name: str, keep: list) -> Path:
    """A target of ``kind`` named ``name`` in ``folder`` (``devnull``: /dev/null itself, or a link to it when
    the command needs a suffix)."""
    path = folder / name
    if kind == "devnull":
        if Path(name).suffix:
            os.symlink("/dev/null", path)
            return path
        return Path("/dev/null")
    if kind in ("fifo", "link_fifo"):
        fifo = folder / ("fifo_" + name)
        os.mkfifo(fifo)
        if kind == "fifo":
            return fifo
        os.symlink(fifo, path)
        return path
    if kind == "socket":
        sock = socket.socket(socket.AF_UNIX)
        sock.bind(name)  # relative to the current folder (the test's): an AF_UNIX path has 108 bytes at most
        keep.append(sock)
        return path
    os.symlink("/dev/null", path)  # link_devnull
    return path


def _state(path: Path):
    st = os.lstat(path)
    target = os.stat(path) if stat.S_ISLNK(st.st_mode) else st
    return (st.st_mode, st.st_ino, st.st_rdev, target.st_mode, target.st_ino, target.st_rdev)


def _tree(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _db(path: Path) -> Path:
    st = open_store(path, "create")
    st.bind_protocol("p", "1.0", "a" * 64, {"name": "p", "family": "2afc"})
    st.enrol("P1", 1, 0, "b" * 64, [PlannedRow(0, "trial", "2afc", "s0", "hmd", ("x", "y"), "", False)])
    sid = st.start_session("P1", "a" * 64, 0, {"studyapp": "t"}, {"width_px": 10}, {"refresh_hz": 60.0}, "test")
    st.commit_response("P1", 0, sid, ["A"], chosen="x", rt_s=0.7, onset_s=1.0)
    st.close()
    return path


def _inputs(folder: Path) -> dict[str, Path]:
    from PIL import Image

    ins = folder / "inputs"
    ins.mkdir()
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(ins / "gt.png")
    Image.fromarray(np.full((4, 4, 3), 9, np.uint8)).save(ins / "img.png")
    (ins / "log.csv").write_text("participant,trial,family,condition_a,condition_b,chosen\n", encoding="utf-8")
    (ins / "p.yaml").write_text(PROTOCOL.read_text(encoding="utf-8"), encoding="utf-8")
    return {"db": _db(ins / "study.db"), "gt": ins / "gt.png", "img": ins / "img.png", "log": ins / "log.csv",
            "protocol": ins / "p.yaml"}


#: (command class, what the target is, the target's file name, argv given the target and the inputs)
COMMANDS = {
    "export": ("file", "t.csv", lambda t, i: ["export", "--db", i["db"], "--out", t]),
    "export_frames": ("file", "t.parquet", lambda t, i: ["export", "--db", i["db"], "--format", "frames",
                                                         "--out", t]),
    "render": ("file", "t.png", lambda t, i: ["render", "--scene", "cornell", "--renderer", "gt", "--width", "8",
                                              "--height", "8", "--out", t]),
    "analyze": ("folder", "t", lambda t, i: ["analyze", i["log"], "--out", t]),
    "quality": ("folder", "t", lambda t, i: ["quality", "--gt", i["gt"], i["img"], "--fov-y", "90", "--out", t]),
    "foveation_table": ("folder", "t", lambda t, i: ["foveation", "table", "--out", t]),
    "foveation_plots": ("folder", "t", lambda t, i: ["foveation", "plots", "--out", t]),
    "demo": ("folder", "t", lambda t, i: ["demo", "--out", t]),
    "prepare_stimuli": ("folder", "t", lambda t, i: ["prepare", i["protocol"], "--serial", "--stimuli", t]),
    "prepare_cache": ("folder", "t", lambda t, i: ["prepare", i["protocol"], "--serial", "--cache", t]),
    "run_db": ("file", "t.db", lambda t, i: ["run", i["protocol"], "--participant", "P1", "--simulate",
                                             "--quiet", "--db", t]),
    "run_gaze_log": ("file", "t.csv", lambda t, i: ["run", i["protocol"], "--participant", "P1", "--simulate",
                                                    "--quiet", "--gaze-log", t]),
    "run_screenshot_dir": ("folder", "t", lambda t, i: ["run", i["protocol"], "--participant", "P1",
                                                        "--simulate", "--quiet", "--screenshot-dir", t]),
}


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_writer_refuses_special_targets_unopened(command, kind, tmp_path, monkeypatch, capsys, hang_guard):
    what, name, argv = COMMANDS[command]
    monkeypatch.chdir(tmp_path)
    inputs = _inputs(tmp_path)
    keep: list = []
    target = _make(kind, tmp_path, name, keep)
    before, tree = _state(target), _tree(tmp_path)
    capsys.readouterr()
    try:
        with hang_guard(60):
            code = main([str(a) for a in argv(target, inputs)])
    finally:
        for sock in keep:
            sock.close()
    _, err = capsys.readouterr()
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith(f"studyapp: error: {target}: is "), err
    shown = {"devnull": "a character device", "fifo": "a FIFO (named pipe)", "socket": "a socket",
             "link_devnull": "a symlink to a character device", "link_fifo": "a symlink to a FIFO (named pipe)"}
    if kind == "devnull" and Path(name).suffix:
        shown["devnull"] = "a symlink to a character device"
    assert f": is {shown[kind]}, not a {'regular file' if what == 'file' else 'folder'}: " in err, err
    assert _state(target) == before, "the target changed"
    assert _tree(tmp_path) == tree, "something was created"
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


@pytest.mark.parametrize("target", ["/dev/stdout", "/proc/self/fd/1"])
def test_export_to_stdout_pipe_is_refused_not_hung(target, tmp_path):
    db = _db(tmp_path / "study.db")
    proc = subprocess.run([sys.executable, "-m", "studyapp", "export", "--db", str(db), "--out", target],
                          capture_output=True, text=True, timeout=60, cwd=tmp_path,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1
    assert proc.stderr.startswith(f"studyapp: error: {target}: is a symlink to a FIFO (named pipe), not a regular "
                                  "file: choose a file name for --out"), proc.stderr
    assert proc.stdout == "" and sorted(p.name for p in tmp_path.iterdir()) == ["study.db"]


@pytest.mark.parametrize("target", ["/dev/stdout", "/proc/self/fd/1"])
def test_export_to_stdout_redirected_to_a_file_is_refused(target, tmp_path):
    """Through a descriptor's link the "file" is whatever the shell opened: never replaced by name."""
    db = _db(tmp_path / "study.db")
    redirect = tmp_path / "redirect.csv"
    with open(redirect, "w") as fh:
        proc = subprocess.run([sys.executable, "-m", "studyapp", "export", "--db", str(db), "--out", target],
                              stdout=fh, stderr=subprocess.PIPE, text=True, timeout=60, cwd=tmp_path,
                              env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 2
    assert proc.stderr == (f"studyapp: error: {target}: is a file descriptor's link (/proc/self/fd/1), not a file "
                           "name: choose a file name for --out\n")
    assert redirect.read_text() == ""


def test_check_target_never_opens_a_fifo(tmp_path, hang_guard):
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    with hang_guard(20):
        assert is_sqlite_file(fifo) is False
        with pytest.raises(UserError, match=r"f: is a FIFO \(named pipe\), not a regular file: choose a file name "
                                            r"for --db$"):
            check_target(fifo, option="--db")
        with pytest.raises(UserError, match=r"f: is a FIFO \(named pipe\), not a folder: choose a folder for --out"):
            check_dir_target(fifo, "analysis.json")


def test_dangling_symlink_and_path_under_a_device_are_refused(tmp_path):
    link = tmp_path / "l.csv"
    os.symlink(tmp_path / "missing" / "x.csv", link)
    with pytest.raises(UserError, match=r"l.csv: is a symlink to a missing file \(.*missing/x.csv\): choose the "
                                        r"file name itself$"):
        write_text(link, "x\n")
    with pytest.raises(UserError, match=r"^/dev/null/x.csv: cannot write: /dev/null is a character device, not a "
                                        r"folder: choose another path$"):
        write_text("/dev/null/x.csv", "x\n")
    assert not (tmp_path / "missing").exists() and os.path.islink(link)


def test_symlink_to_a_regular_file_is_written_through(tmp_path):
    real = tmp_path / "data" / "real.csv"
    real.parent.mkdir()
    real.write_text("old\n")
    link = tmp_path / "latest.csv"
    os.symlink(real, link)
    assert real_file(link) == real.resolve()
    write_text(link, "new\n")
    assert os.path.islink(link) and os.readlink(link) == str(real)
    assert real.read_text() == "new\n"
    assert sorted(p.name for p in real.parent.iterdir()) == ["real.csv"]  # no temporary left behind


def test_reexport_keeps_mode_and_owner(tmp_path, capsys):
    db = _db(tmp_path / "study.db")
    out = tmp_path / "trials.csv"
    out.write_text("old\n")
    os.chmod(out, 0o600)
    owner = (os.getuid(), os.getgid())
    if os.geteuid() == 0:  # root (the README installs as root): the old owner is given back
        owner = (12345, 23456)
        os.chown(out, *owner)
    assert main(["export", "--db", str(db), "--out", str(out)]) == 0
    st = os.stat(out)
    assert stat.S_IMODE(st.st_mode) == 0o600
    assert (st.st_uid, st.st_gid) == owner
    assert out.read_text().startswith("participant,")
    # a new file: 0666 less the umask, as before
    new = tmp_path / "new.csv"
    assert main(["export", "--db", str(db), "--out", str(new)]) == 0
    assert stat.S_IMODE(os.stat(new).st_mode) == 0o666 & ~current_umask()
    capsys.readouterr()


def test_replaced_report_folder_keeps_mode(tmp_path):
    out = tmp_path / "report"
    out.mkdir()
    (out / "analysis.json").write_text("{}\n")
    os.chmod(out, 0o550)  # read-only: the new content is still written, then the mode applied
    with atomic_dir(out, "analysis.json") as tmp:
        write_text(tmp / "analysis.json", "[]\n")
    assert stat.S_IMODE(os.stat(out).st_mode) == 0o550
    assert (out / "analysis.json").read_text() == "[]\n"


#: Readers of a user's file, given the special file as the input (argv given it, the inputs and an out folder).
READERS = {
    "export_db": lambda f, i, o: ["export", "--db", f, "--out", o / "t.csv"],
    "sessions_db": lambda f, i, o: ["sessions", "--db", f],
    "replay_db": lambda f, i, o: ["replay", "--db", f, "--participant", "P1", "--trial", "0", "--out", o / "r"],
    "analyze_db": lambda f, i, o: ["analyze", f.with_name(f.name), "--out", o / "a"],
    "analyze_log": lambda f, i, o: ["analyze", f, "--out", o / "a"],
    "validate": lambda f, i, o: ["validate", f],
    "render_scene": lambda f, i, o: ["render", "--scene", f, "--renderer", "gt", "--width", "8", "--height", "8",
                                     "--out", o / "t.png"],
    "quality_gt": lambda f, i, o: ["quality", "--gt", f, i["img"], "--fov-y", "90", "--out", o / "q"],
    "quality_image": lambda f, i, o: ["quality", "--gt", i["gt"], f, "--fov-y", "90", "--out", o / "q"],
}
#: The file name each reader needs (its suffix picks the format).
READER_NAMES = {"export_db": "s.db", "sessions_db": "s.db", "replay_db": "s.db", "analyze_db": "s.db",
                "analyze_log": "log.csv", "validate": "p.yaml", "render_scene": "box.yaml", "quality_gt": "g.png",
                "quality_image": "i.png"}


@pytest.mark.parametrize("kind", ("fifo", "link_fifo", "link_devnull"))
@pytest.mark.parametrize("reader", sorted(READERS))
def test_every_reader_refuses_a_special_input_unopened(reader, kind, tmp_path, monkeypatch, capsys, hang_guard):
    """An input that is a FIFO (or a link to one, or to /dev/null) is refused in one line naming it and its
    kind, without being opened: opening a FIFO blocks until a writer comes (export --db, sessions, replay,
    validate, render --scene, analyze and quality all hung)."""
    monkeypatch.chdir(tmp_path)
    inputs = _inputs(tmp_path)
    keep: list = []
    special = _make(kind, tmp_path, READER_NAMES[reader], keep)
    out = tmp_path / "out"
    tree = _tree(tmp_path)
    capsys.readouterr()
    with hang_guard(60):
        code = main([str(a) for a in READERS[reader](special, inputs, out)])
    _, err = capsys.readouterr()
    assert code == 2, err
    shown = {"fifo": "a FIFO (named pipe)", "link_fifo": "a symlink to a FIFO (named pipe)",
             "link_devnull": "a symlink to a character device"}[kind]
    assert err.count("\n") == 1 and f"{special}: is {shown}, not a " in err and "refusing to read it" in err, err
    assert _tree(tmp_path) == tree, "something was created"
