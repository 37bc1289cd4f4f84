"""Frame timing of live trials: the per-trial summary the exports, ``studyapp sessions`` and the reports use.

From one row per flip (flip time, render time of a new frame or none, gaze sample time, dropped flag):

- frame rate: new frames per second between consecutive rendered flips, median and 5th percentile;
- dropped-frame share: dropped flips / flips;
- latency: gaze age at the flip (flip time - gaze sample time), milliseconds, median and 95th percentile.

Undefined values (no rendered frame pair, no gaze sample) are NaN; they are never 0.
"""

from __future__ import annotations

import numpy as np

#: The tidy log's live columns, in order.
COLUMNS = ("fps_median", "fps_p5", "dropped_share", "latency_p50_ms", "latency_p95_ms")


def summary(flip_s, render_s, gaze_t, dropped) -> dict:
    """The summary of one trial's flips (sequences of equal length; ``render_s``/``gaze_t`` None or NaN where
    absent). Returns :data:`COLUMNS` -> float."""
    flip = np.asarray(flip_s, dtype=float)
    rendered = np.array([r is not None and r == r for r in render_s], dtype=bool)
    gaps = np.diff(flip[rendered])
    fps = 1.0 / gaps[gaps > 0] if gaps.size else np.array([])
    g = np.array([np.nan if t is None else t for t in gaze_t], dtype=float)
    lat = (flip - g)[np.isfinite(g)] * 1000.0
    nan = float("nan")
    return {"fps_median": float(np.median(fps)) if fps.size else nan,
            "fps_p5": float(np.percentile(fps, 5)) if fps.size else nan,
            "dropped_share": float(np.mean(np.asarray(dropped, dtype=bool))) if flip.size else nan,
            "latency_p50_ms": float(np.percentile(lat, 50)) if lat.size else nan,
            "latency_p95_ms": float(np.percentile(lat, 95)) if lat.size else nan}
