"""The one progress display of the CLI (tqdm, on stderr): counted work, step messages, long single steps.

- :class:`Bar` — counted work with the time left (``prepare``'s frames, a session's trials, a cluster's
  futures): ``bar(done, total)`` is the callback the runner and the stimulus builder call.
- :func:`status` / :func:`end_status` — one line naming the current step of a long command (``analyze``,
  ``lightcuts tables``, the demo), redrawn in place.
- :func:`ticker` — elapsed time while one long step runs (a single ``render``).

On a terminal the lines are redrawn in place; in a log or a pipe a counted bar writes a line per 10 %, and step
messages and tickers write nothing, so logs stay readable and stdout stays clean for ``--json``.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time


def _is_tty(stream) -> bool:
    return bool(getattr(stream, "isatty", None) and stream.isatty())


class Bar:
    """Counted work: ``frames: |#####     | 12/288 [00:40<03:20]`` (tqdm's bar and time left).

    Call ``bar(done, total[, seconds_left])`` after each unit (``seconds_left``, when known, replaces tqdm's
    estimate from the rate, e.g. when cached frames cost nothing); the bar closes when ``done == total``.
    """

    FORMAT = "{desc}: |{bar}| {n_fmt}/{total_fmt} [{elapsed}<{remaining}]"

    def __init__(self, what: str, stream=None, tty: bool | None = None) -> None:
        self.what, self.stream = what, stream or sys.stderr
        self.tty = _is_tty(self.stream) if tty is None else tty
        self._bar = None
        self._decile = -1
        self._t0 = time.perf_counter()

    def __call__(self, done: int, total: int, seconds_left: float = float("nan")) -> None:
        from tqdm import tqdm

        if self.tty:
            if self._bar is None or self._bar.total != total:
                self.close()
                self._bar = tqdm(total=total, desc=self.what, file=self.stream, bar_format=self.FORMAT,
                                 dynamic_ncols=True, mininterval=0.2)
            self._bar.update(done - self._bar.n)
            if done >= total:
                self.close()
            return
        decile = (10 * done) // max(1, total)
        if decile != self._decile or done == total:  # a line per 10 % in a log or a pipe
            self._decile = decile
            elapsed = time.perf_counter() - self._t0
            rate = None if seconds_left != seconds_left or done >= total else (
                (total - done) / seconds_left if seconds_left > 0 else None)
            line = tqdm.format_meter(done, total, elapsed, ncols=72, prefix=self.what, ascii=" #", rate=rate,
                                     bar_format=self.FORMAT)
            print(line, file=self.stream, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


_STATUS = {"bar": None}


def status(msg: str, prefix: str = "") -> None:
    """One step message, redrawn in place on a terminal (nothing in a log or a pipe)."""
    if not _is_tty(sys.stderr):
        return
    bar = _STATUS["bar"]
    if bar is None:
        from tqdm import tqdm

        bar = _STATUS["bar"] = tqdm(total=None, file=sys.stderr, leave=False, bar_format="{desc} {elapsed}")
    bar.set_description_str(f"{prefix}{msg}"[:150])


def end_status() -> None:
    """Clear the step line."""
    bar = _STATUS["bar"]
    if bar is not None:
        bar.close()
        _STATUS["bar"] = None


@contextlib.contextmanager
def ticker(label: str, after_s: float = 2.0):
    """While the block runs longer than ``after_s``, show ``label`` and the elapsed time (terminal only)."""
    stop = threading.Event()

    def run():
        if stop.wait(after_s) or not _is_tty(sys.stderr):
            return
        t0 = time.perf_counter() - after_s
        while not stop.wait(0.25):
            status(f"{label} {time.perf_counter() - t0:.1f} s")
        end_status()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
