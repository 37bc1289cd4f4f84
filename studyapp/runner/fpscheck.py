"""The frame-rate check before the first trial of a live session (issue 26, item 2).

Each condition x scene of a live protocol is rendered for ``stimulus.fps_check_s`` seconds (default
:data:`~studyapp.runner.protocol.FPS_CHECK_S`; 0: no check; the whole check at most :data:`MAX_TOTAL_S`) at the
session's render size on the session's backend, in the open window. The table (frame rate p5/p50 from the
rendered-frame intervals and the gaze-to-flip latency p50, :mod:`data_schema.timing`) is stored with the
session (a ``fps_check`` event) and printed to the experimenter's console; a condition whose median rate is
below ``min_fps`` stops the session before its first trial (:class:`TooSlow`) unless the run accepts slow
conditions (``run --accept-slow``).

This module is pure: the window's side (render, draw, flip one frame) is a callable handed to
:func:`sample_frames`, so the check is tested with a fake renderer and clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from data_schema.errors import UserError
from data_schema.timing import format_fps, summary

#: The bound of the whole check, seconds.
MAX_TOTAL_S = 60.0


class TooSlow(UserError):
    """A condition renders below the protocol's ``min_fps``: the session stops before its first trial."""


def cells(protocol) -> list[tuple[str, str]]:
    """The (condition, scene) pairs the check renders: every rendered condition in every scene of the design."""
    return [(c, s) for c in protocol.timed_conditions() for s in protocol.scenes]


def seconds_per_cell(protocol) -> float:
    """How long each cell is rendered: ``stimulus.fps_check_s`` (0: no check), shortened so that the whole check
    stays within :data:`MAX_TOTAL_S`."""
    want = float(protocol.fps_check_s)
    n = len(cells(protocol))
    return 0.0 if want <= 0 or not n else min(want, MAX_TOTAL_S / n)


def sample_frames(frame: Callable[[], tuple[float, float | None, float | None]], clock: Callable[[], float],
                  seconds: float) -> tuple[list, list, list, list]:
    """Render frames for ``seconds`` (at least one): ``frame()`` renders, shows and flips one frame and returns
    ``(flip time, render seconds, time of the gaze sample used or None)``; ``clock()`` is the flips' clock.

    Returns the rows :func:`data_schema.timing.summary` takes: flip times (the first is the start, so one slow
    frame still gives one interval), render times, gaze times, dropped flags."""
    t0 = clock()
    flips, renders, gaze = [t0], [0.0], [None]
    while True:
        flip, render_s, gaze_t = frame()
        flips.append(flip)
        renders.append(render_s)
        gaze.append(gaze_t)
        if flip - t0 >= seconds:
            return flips, renders, gaze, [False] * len(flips)


def measure(protocol, scale: float, render_cell: Callable, seconds: float) -> list[dict]:
    """The check's table: ``render_cell(live_stimulus, seconds)`` returns :func:`sample_frames`' rows for one
    cell (the window's :func:`studyapp.presentation.live_window.fps_check_frames`). One dict per cell:
    condition, scene, fps_p5, fps_p50, latency_p50_ms (NaN: no gaze sample), frames."""
    from .live import live_stimulus

    rows = []
    for cond, scene in cells(protocol):
        flips, renders, gaze, dropped = render_cell(live_stimulus(protocol, cond, scene, scale), seconds)
        t = summary(flips, renders, gaze, dropped)
        rows.append({"condition": cond, "scene": scene, "fps_p5": t["fps_p5"], "fps_p50": t["fps_median"],
                     "latency_p50_ms": t["latency_p50_ms"], "frames": len(flips) - 1})
    return rows


def too_slow(rows: list[dict], min_fps: float | None) -> list[dict]:
    """The rows whose median frame rate is below ``min_fps`` (none without a floor)."""
    return [r for r in rows if min_fps and not r["fps_p50"] >= min_fps]


def table_lines(rows: list[dict], min_fps: float | None) -> list[str]:
    """The table for the experimenter's console (columns as wide as the longest condition and scene name: an
    adaptive level such as ``LaFR_150ms(1.2)`` keeps the columns aligned)."""
    floor = f" (min_fps {min_fps:g})" if min_fps else ""
    cw = max([14, *(len(r["condition"]) for r in rows)])
    sw = max([14, *(len(r["scene"]) for r in rows)])
    out = [f"frame-rate check{floor}:",
           f"  {'condition':<{cw}} {'scene':<{sw}} {'fps p5':>8} {'fps p50':>8} {'lat p50':>8} {'frames':>6}"]
    for r in rows:
        lat = r["latency_p50_ms"]
        out.append(f"  {r['condition']:<{cw}} {r['scene']:<{sw}} {format_fps(r['fps_p5']):>8} "
                   f"{format_fps(r['fps_p50']):>8} {'-' if math.isnan(lat) else f'{lat:.0f}ms':>8} {r['frames']:>6}"
                   + ("  BELOW min_fps" if r in too_slow(rows, min_fps) else ""))
    return out


def refusal(slow: list[dict], min_fps: float) -> str:
    """The one line that stops a session whose conditions render too slowly."""
    worst = {}
    for r in slow:  # each condition at its slowest scene
        if r["condition"] not in worst or not r["fps_p50"] >= worst[r["condition"]]["fps_p50"]:
            worst[r["condition"]] = r
    named = ", ".join(f"{c} {format_fps(r['fps_p50'])} fps ({r['scene']})" for c, r in worst.items())
    return (f"frame-rate check: {named}: below the protocol's min_fps {min_fps:g} at this size and backend; "
            "use a smaller --scale or a faster machine, or add --accept-slow to run anyway (its trials are flagged)")


def trial_flags(idx: int, conditions, scene: str, per_stimulus: list[float], min_fps: float | None) -> list[str]:
    """The console lines of a finished live trial whose stimuli rendered below ``min_fps`` (``per_stimulus``:
    the median rate of each stimulus, NaN where it had fewer than two rendered frames)."""
    if not min_fps:
        return []
    return [f"trial {idx} ({c}, {scene}): {format_fps(f)} fps, below min_fps {min_fps:g}"
            for c, f in zip(conditions, per_stimulus) if not f >= min_fps]
