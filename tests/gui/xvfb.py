"""Helpers for GUI tests: a private Xvfb server and real input events injected with xdotool.

Not collected by pytest (no ``test_`` prefix); imported by ``tests/test_presentation_gui.py`` and friends.
"""

from __future__ import annotations

import json
import os
import queue
import select
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
PYTHON = sys.executable


def query(db: Path, sql: str, *args) -> list:
    """Rows of ``sql`` on the study database ``db``, read-only, while a session may be writing to it (``[]``
    while it does not exist yet or is busy)."""
    import sqlite3

    try:
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5)
        try:
            return con.execute(sql, args).fetchall()
        finally:
            con.close()
    except sqlite3.OperationalError:
        return []


def missing_tools() -> list[str]:
    """Names of the binaries a GUI test needs and this machine lacks."""
    return [b for b in ("Xvfb", "xdotool") if shutil.which(b) is None]


def require_tools() -> None:
    """Fail a GUI test (never skip it) on a machine without the binaries it needs."""
    assert not missing_tools(), f"GUI tests need {missing_tools()} (Debian: xvfb, xdotool; ./run installs them)"


class Xvfb:
    """A private X server: ``with Xvfb() as x: subprocess.run(..., env=x.env)``.

    Xvfb chooses a free display number itself (``-displayfd``), so parallel test runs never collide.
    """

    def __init__(self, screen: str = "1280x1024x24", timeout_s: float = 15.0):
        self.screen = screen
        self.timeout_s = timeout_s
        self.proc = None
        self.display = None

    def __enter__(self) -> "Xvfb":
        r, w = os.pipe()
        self.proc = subprocess.Popen(
            ["Xvfb", "-displayfd", str(w), "-screen", "0", self.screen, "-nolisten", "tcp", "-noreset"],
            pass_fds=(w,),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(w)
        buf = b""
        deadline = time.monotonic() + self.timeout_s
        try:
            while not buf.endswith(b"\n"):
                left = deadline - time.monotonic()
                if left <= 0 or not select.select([r], [], [], left)[0]:
                    raise RuntimeError("Xvfb did not report a display number in time")
                chunk = os.read(r, 64)
                if not chunk:
                    raise RuntimeError(f"Xvfb exited with status {self.proc.wait()}")
                buf += chunk
        except BaseException:
            self.__exit__(None, None, None)
            raise
        finally:
            os.close(r)
        self.display = f":{int(buf.strip())}"
        return self

    def __exit__(self, *exc) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    @property
    def env(self) -> dict:
        env = dict(os.environ, DISPLAY=self.display, PYTHONPATH=str(ROOT))
        env.pop("WAYLAND_DISPLAY", None)
        return env

    def xdotool(self, *args: str) -> None:
        subprocess.run(["xdotool", *args], env=self.env, check=True, timeout=10)

    def key(self, *keys: str) -> None:
        """Press and release each key in turn (X keysym names: ``Left``, ``space``, ``Escape``, ``b``...)."""
        for k in keys:
            self.xdotool("key", k)
            time.sleep(0.05)


class Driver:
    """Runs ``tests/gui/drive_presenter.py SPEC`` under an :class:`Xvfb`; reads its JSON event lines."""

    def __init__(self, x: Xvfb, spec: dict, workdir: Path, timeout_s: float = 25.0):
        self.x = x
        self.spec_path = workdir / "spec.json"
        self.result_path = workdir / "result.json"
        spec = dict(spec, result=str(self.result_path))
        self.spec_path.write_text(json.dumps(spec))
        self.deadline = time.monotonic() + timeout_s
        self.events: list[dict] = []
        self._lines: queue.Queue = queue.Queue()
        self.stderr_path = workdir / "driver.stderr"
        with open(self.stderr_path, "w") as err:  # a file, not a pipe: PsychoPy's logging must never block
            self.proc = subprocess.Popen(
                [PYTHON, str(HERE / "drive_presenter.py"), str(self.spec_path)],
                env=x.env,
                cwd=str(workdir),
                stdout=subprocess.PIPE,
                stderr=err,
                text=True,
            )
        threading.Thread(target=self._read_lines, daemon=True).start()

    def _read_lines(self) -> None:
        for line in self.proc.stdout:  # a thread: select() on a buffered pipe would miss buffered lines
            self._lines.put(line)
        self._lines.put(None)

    def next_event(self) -> dict:
        """The next event the presenter reported (fails the test on timeout or a crash)."""
        while True:
            try:
                line = self._lines.get(timeout=max(0.0, self.deadline - time.monotonic()))
            except queue.Empty:
                self.proc.kill()
                raise AssertionError(f"GUI driver timed out; events so far: {self.events}") from None
            if line is None:
                err = self.stderr_path.read_text()
                raise AssertionError(
                    f"GUI driver exited ({self.proc.wait()}) early; events so far: {self.events}\n"
                    f"{err[-3000:]}"
                )
            if line.startswith("EVENT "):
                ev = json.loads(line[6:])
                self.events.append(ev)
                return ev

    def wait_for(self, name: str, **match) -> dict:
        """Skip events until one named ``name`` whose fields equal ``match``."""
        while True:
            ev = self.next_event()
            if ev["event"] == name and all(ev.get(k) == v for k, v in match.items()):
                return ev

    def finish(self) -> dict:
        """Wait for the driver to exit; return the JSON result it wrote."""
        try:
            self.proc.wait(timeout=max(1.0, self.deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            self.proc.kill()
            raise AssertionError("GUI driver did not exit in time") from None
        if self.proc.returncode != 0:
            err = self.stderr_path.read_text()
            raise AssertionError(f"GUI driver failed ({self.proc.returncode}):\n{err[-3000:]}")
        return json.loads(self.result_path.read_text())

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
