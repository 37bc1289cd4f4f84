"""Exporter: the tidy trial log as CSV (``studyapp export --format csv``)."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable
from pathlib import Path

from ..atomic import write_text
from ..trial_log import ALL_COLUMNS
from .opening import open_store


def _fmt(value) -> str:
    if value is None or value == "":
        return ""
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(round(value, 6))
    return str(value)


def tidy_csv_text(rows: Iterable[dict]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(ALL_COLUMNS)
    for r in rows:
        w.writerow([_fmt(r[c]) for c in ALL_COLUMNS])
    return buf.getvalue()


def export_csv(db_path, out) -> Path:
    """Write the tidy trial log as CSV (UTF-8, no BOM, ``\\n`` line ends, empty cell = not applicable)."""
    with open_store(db_path) as st:
        return write_text(out, tidy_csv_text(st.tidy_rows()))
