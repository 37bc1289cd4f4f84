"""What the analysis reads from a study database: the tidy trial log as a DataFrame and the protocol's
analysis plan."""

from __future__ import annotations

from .opening import open_store
from .tables import StoreError
from .tidy import tidy_frame


def read_trials(db_path):
    """The tidy trial log of a study database as a pandas DataFrame (columns
    :data:`data_schema.trial_log.ALL_COLUMNS`).

    Text columns are strings (``""`` where a column does not apply to the trial family), ``trial``,
    ``practice``, ``catch`` and ``fps_check_slow`` are int64, ``response`` is float64 (1.0/0.0 for a family that
    logs a yes/no response, NaN for the other families) and ``rt_s`` float64 (NaN when not measured); the
    adaptive ``level``, ``intensity``, ``correct`` (1.0/0.0), ``estimate_mean`` and ``estimate_sd`` are float64,
    NaN outside adaptive trials.
    """
    with open_store(db_path) as st:
        if not st.meta():
            raise StoreError(f"{db_path}: the study database is empty")
        rows = st.tidy_rows()
    return tidy_frame(rows)


def read_analysis_plan(db_path) -> dict | None:
    """The ``analysis`` block of the protocol a study database was written with (None if it has none).

    Added unless the block sets them: ``family`` and ``protocol`` (name, for information) and ``conditions``
    (the design's conditions in protocol order: the order of the tables).
    """
    with open_store(db_path) as st:
        proto = st.protocol_json()
    if not proto:
        return None
    plan = proto.get("analysis")
    if plan is None:
        return None
    out = dict(plan)
    out.setdefault("family", proto.get("family"))
    out.setdefault("protocol", proto.get("name"))
    conds = proto.get("conditions") or {}
    design = (proto.get("design") or {}).get("conditions") or [
        n for n, c in conds.items() if (c or {}).get("role", "main") == "main"]
    if len(design) >= 2:
        out.setdefault("conditions", list(design))  # the table order of the protocol
    return out
