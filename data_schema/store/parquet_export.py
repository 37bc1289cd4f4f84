"""Exporter: the tidy trial log as Parquet (``studyapp export --format parquet``)."""

from __future__ import annotations

from pathlib import Path

from ..atomic import atomic_path
from .readers import read_trials


def export_parquet(db_path, out) -> Path:
    """Write the tidy trial log as Parquet (types as in :func:`read_trials`)."""
    df = read_trials(db_path)
    with atomic_path(out) as tmp:
        df.to_parquet(tmp, index=False)
    return Path(out)
