"""The PsychoPy window and the psychtoolbox keyboard: opened for a :class:`~data_schema.geometry.Display`,
with the measured facts of the window (refresh rate, size, software versions), key polling that loses no key, and
the back buffer as an array.

PsychoPy is imported inside :func:`open_window` only, so importing this module costs nothing and fails only
when a window is really asked for.
"""

from __future__ import annotations

import collections

import numpy as np

from data_schema.geometry import Display

from .base import PresentationError


def _has_display() -> bool:
    import os
    import sys

    return not sys.platform.startswith("linux") or bool(
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )


class Window:
    """An open PsychoPy window (:attr:`win`) and its keyboard (:attr:`kb`); made by :func:`open_window`.

    :attr:`now` is the clock of ``win.flip()``'s time stamps, :attr:`frame_period` the measured refresh period
    (seconds), :attr:`facts` what was measured at opening; :attr:`core`, :attr:`visual`, :attr:`logging` are
    PsychoPy's modules, for the parts that draw into this window.
    """

    def __init__(self, display: Display, win, kb, core, visual, logging, frame_period: float, facts: dict):
        self.display, self.win, self.kb = display, win, kb
        self.core, self.visual, self.logging = core, visual, logging
        self.now = logging.defaultClock.getTime
        self.frame_period = frame_period
        self.facts = facts
        self._handled = collections.deque(maxlen=256)  # key presses already acted on (see poll_keys)

    def location(self) -> tuple[int, int]:
        """Top-left corner of the window on its screen, pixels (0, 0 in fullscreen)."""
        if self.display.fullscreen:
            return (0, 0)
        return tuple(self.win.winHandle.get_location())

    def poll_keys(self, key_list: list[str] | None) -> list:
        """Key presses since the last poll, each once, in the order they went down.

        ``Keyboard.getKeys(waitRelease=False)`` skips a press that was already released when polled (a tap
        shorter than the time between two polls is lost), and ``waitRelease=True`` reports a press only once
        it is released; so both are polled, and a press seen before (still down last time, released now) is
        dropped by identity.
        """
        kb = self.kb
        got = kb.getKeys(keyList=key_list, waitRelease=False, clear=True) + kb.getKeys(
            keyList=key_list, waitRelease=True, clear=True
        )
        fresh = []
        for k in got:
            if not any(k is h for h in self._handled) and not any(k is f for f in fresh):
                fresh.append(k)
        self._handled.extend(fresh)
        return sorted(fresh, key=lambda k: k.tDown)

    def wait_keys(self, key_list: list[str] | None) -> str:
        """Forget the keys pressed so far, then wait for one of ``key_list`` (None: any); return its name."""
        self.kb.clearEvents()
        while True:
            keys = self.poll_keys(key_list)
            if keys:
                return keys[0].name
            self.core.wait(0.005, hogCPUperiod=0)

    def screenshot(self) -> np.ndarray:
        """The back buffer as an ``(H, W, 3)`` uint8 RGB array, row 0 at the top (call before ``flip``)."""
        im = self.win.getMovieFrame(buffer="back")
        self.win.movieFrames.clear()
        return np.asarray(im.convert("RGB"))

    def close(self) -> None:
        self.win.close()


def open_window(display: Display) -> Window:
    """Open the window and the psychtoolbox keyboard for ``display``; measure its refresh rate.

    Raises :class:`PresentationError` if PsychoPy cannot open a window or if the keyboard backend is not
    psychtoolbox (PsychoPy silently falls back to a polling backend whose key names and times differ).
    """
    try:
        import psychopy
        from psychopy import core, logging, monitors, visual
        from psychopy.hardware import keyboard
    except Exception as exc:  # no display, missing package...
        hint = " (no DISPLAY: run under a display or Xvfb, e.g. xvfb-run -a)" if not _has_display() else ""
        raise PresentationError(
            f"cannot import PsychoPy's window modules: {type(exc).__name__}: {exc}{hint}"
        ) from None
    import pyglet

    n_screens = len(pyglet.canvas.get_display().get_screens())
    if display.screen >= n_screens:  # PsychoPy would silently open the window on screen 0
        raise PresentationError(
            f"display.screen={display.screen} does not exist: this machine has {n_screens} screen(s), "
            f"0..{n_screens - 1}"
        )
    mon = monitors.Monitor("studyapp", width=display.width_cm, distance=display.distance_cm)
    mon.setSizePix([display.width_px, display.height_px])
    try:
        win = visual.Window(size=(display.width_px, display.height_px), fullscr=display.fullscreen,
                            screen=display.screen, monitor=mon, units="pix", color=(-1, -1, -1),
                            colorSpace="rgb", allowGUI=not display.fullscreen, checkTiming=False, waitBlanking=True)
    except Exception as exc:
        raise PresentationError(f"cannot open a PsychoPy window: {type(exc).__name__}: {exc}") from None
    kb = keyboard.Keyboard()
    backend = kb.getBackend()
    if backend != "ptb":
        win.close()
        raise PresentationError(
            f"keyboard backend is {backend!r}, not 'ptb': psychtoolbox did not load (on Debian install "
            "libjack-jackd2-0); refusing to run with imprecise reaction times"
        )
    win.mouseVisible = False  # no pointer over the stimuli (MouseGaze still follows the mouse)
    measured = win.getActualFrameRate(nIdentical=10, nMaxFrames=120, nWarmUpFrames=10, threshold=1)
    period = 1.0 / (measured or display.refresh_hz)
    win.refreshThreshold = 1.2 * period
    try:
        from importlib.metadata import version

        ptb_version = version("psychtoolbox")
    except Exception:
        ptb_version = None
    window = Window(display, win, kb, core, visual, logging, period, {})
    window.facts = {
        "presenter": "PsychoPyPresenter",
        "software": {"psychopy": psychopy.__version__, "pyglet": pyglet.version, "psychtoolbox": ptb_version},
        "refresh_hz": float(measured) if measured else None,
        "refresh_hz_nominal": float(display.refresh_hz),
        "keyboard_backend": backend,
        "psychopy_version": psychopy.__version__,
        "pyglet_version": pyglet.version,
        "window_size_px": [int(v) for v in win.size],
        "window_pos_px": [int(v) for v in window.location()],
        "window_matches_display": [int(v) for v in win.size] == [display.width_px, display.height_px],
        "fullscreen": bool(display.fullscreen),
        "screen": int(display.screen),
        "pixels_per_degree": display.ppd,
        "fov_y_deg": display.fov_y_deg,
        "gl_renderer": pyglet.gl.gl_info.get_renderer(),
        "eyetracker": None,
    }
    return window
