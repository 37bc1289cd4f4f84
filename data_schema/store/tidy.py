"""The tidy trial log's rows (:data:`data_schema.trial_log.ALL_COLUMNS`) built from the store's records: the
family's columns asked of the family (:meth:`data_schema.families.base.TrialFamily.tidy_columns`)."""

from __future__ import annotations

from collections.abc import Sequence

from .. import families
from ..trial_log import ADAPTIVE_COLUMNS, ALL_COLUMNS, TIMING_COLUMNS


def adaptive_columns(row) -> dict:
    """The tidy log's adaptive columns (:data:`ADAPTIVE_COLUMNS`) of an adaptive trial (an :class:`AdaptiveRow`
    or a row of :meth:`Store.adaptive_rows`), and ``condition``: the varied condition (in a choice family's
    trials too)."""
    get = row.get if isinstance(row, dict) else (lambda k: getattr(row, k))
    out = {c: get(c) for c in ADAPTIVE_COLUMNS}
    out["correct"] = int(out["correct"])
    out["condition"] = get("procedure").rsplit("@", 1)[0]
    return out


def tidy_row(participant: str, session: str, block: str, scene: str, trial: int, family: str,
             conditions: Sequence[str], chosen: str, chosen_2: str, response, rt_s, kind: str,
             fps_check_slow: bool = False) -> dict:
    """One row of the tidy log (:data:`ALL_COLUMNS`; ``""`` where a column does not apply to the family).
    ``fps_check_slow``: a condition shown was below ``min_fps`` in the session's frame-rate check (run with
    ``--accept-slow``: :meth:`Store.fps_check`'s ``accepted_slow``)."""
    row = dict.fromkeys(ALL_COLUMNS, "")
    row.update(participant=participant, session=session, block=block, scene=scene, trial=trial, family=family,
               chosen=chosen, chosen_2=chosen_2, response=response, rt_s=rt_s,
               practice=int(kind == "practice"), catch=int(kind == "catch"), fps_check_slow=int(fps_check_slow))
    row.update(families.get(family).tidy_columns(conditions))
    return row


def tidy_frame(rows: Sequence[dict]):
    """Tidy rows (:func:`tidy_row`) as a DataFrame with the dtypes documented in :func:`read_trials`."""
    import pandas as pd

    df = pd.DataFrame(list(rows), columns=list(ALL_COLUMNS))
    for c in ("trial", "practice", "catch", "fps_check_slow"):
        df[c] = df[c].astype("int64")
    for c in ("response", "rt_s", *TIMING_COLUMNS, "level", "intensity", "correct", "estimate_mean", "estimate_sd"):
        df[c] = pd.to_numeric(df[c], errors="coerce").astype("float64")
    return df
