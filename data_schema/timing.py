"""Frame timing of live trials: the per-trial summary the exports, ``studyapp sessions`` and the reports use.

From one row per flip (flip time, render time of a new frame or none, gaze sample time, dropped flag):

- frame rate: new frames per second between consecutive rendered flips of the same stimulus (the pause between
  a 2AFC trial's A and B is no frame interval), median and 5th percentile;
- dropped-frame share: dropped flips / flips;
- latency: gaze age at the flip (flip time - gaze sample time), milliseconds, median and 95th percentile.

Undefined values (no rendered frame pair, no gaze sample) are NaN; they are never 0.
"""

from __future__ import annotations

import numpy as np

#: The tidy log's live columns, in order.
COLUMNS = ("fps_median", "fps_p5", "dropped_share", "latency_p50_ms", "latency_p95_ms")


def summary(flip_s, render_s, gaze_t, dropped, stimulus=None) -> dict:
    """The summary of one trial's flips (sequences of equal length; ``render_s``/``gaze_t`` None or NaN where
    absent; ``stimulus``: which of the trial's stimuli each flip showed, None: one stimulus). Returns
    :data:`COLUMNS` -> float."""
    return pooled([(flip_s, render_s, gaze_t, dropped, stimulus)])


def pooled(trials) -> dict:
    """The summary of the flips of several trials together (a session's figures): every trial counts, also one
    with fewer than two rendered frames (no frame rate of its own, but its flips, drops and latencies).

    ``trials`` holds ``(flip_s, render_s, gaze_t, dropped[, stimulus])`` per trial; frame rates are taken
    between consecutive rendered flips of the same stimulus of the same trial, never across stimuli or trials.
    Returns :data:`COLUMNS` -> float."""
    fps, lat, drops = [], [], []
    for flip_s, render_s, gaze_t, dropped, *stimulus in trials:
        fps.append(rates(flip_s, render_s, stimulus[0] if stimulus else None))
        flip = np.asarray(flip_s, dtype=float)
        g = np.array([np.nan if t is None else t for t in gaze_t], dtype=float)
        lat.append((flip - g)[np.isfinite(g)] * 1000.0)
        drops.append(np.asarray(dropped, dtype=bool))
    fps_all = np.concatenate(fps) if fps else np.array([])
    lat_all = np.concatenate(lat) if lat else np.array([])
    drop_all = np.concatenate(drops) if drops else np.array([], dtype=bool)
    nan = float("nan")
    return {"fps_median": float(np.median(fps_all)) if fps_all.size else nan,
            "fps_p5": float(np.percentile(fps_all, 5)) if fps_all.size else nan,
            "dropped_share": float(np.mean(drop_all)) if drop_all.size else nan,
            "latency_p50_ms": float(np.percentile(lat_all, 50)) if lat_all.size else nan,
            "latency_p95_ms": float(np.percentile(lat_all, 95)) if lat_all.size else nan}


def rates(flip_s, render_s, stimulus=None) -> np.ndarray:
    """New frames per second between consecutive rendered flips of the same stimulus of one trial (empty where
    no stimulus has two rendered flips: the trial has no frame rate)."""
    flip = np.asarray(flip_s, dtype=float)
    rendered = np.array([r is not None and r == r for r in render_s], dtype=bool)
    gaps = np.diff(flip[rendered])
    if stimulus is not None and gaps.size:  # an interval only between two flips of one stimulus
        shown = np.asarray(stimulus)[rendered]
        gaps = gaps[shown[1:] == shown[:-1]]
    return 1.0 / gaps[gaps > 0] if gaps.size else np.array([])


def format_fps(fps: float) -> str:
    """A frame rate for a console: one decimal, two significant digits below 1 fps (a trial that showed frames is
    never printed as 0.0), ``-`` where undefined."""
    if fps != fps:
        return "-"
    return f"{fps:.1f}" if fps >= 1 else f"{fps:.2g}"
