"""Exporter: paired comparisons in pwcmp's layout (``studyapp export --format pwcmp``), for the families that
declare it (:attr:`data_schema.families.base.TrialFamily.export_columns`)."""

from __future__ import annotations

import csv
import io
from pathlib import Path

from .. import families
from ..atomic import write_text
from .opening import open_store
from .tables import StoreError

#: The layout's name in a family's ``export_columns`` and its header (pwcmp's column names).
LAYOUT = "pwcmp"
HEADER = ("observer", "session", "scene", "condition_1", "condition_2", "selection")


def pwcmp_columns(family: str) -> tuple[str, ...] | None:
    """The tidy-log columns of a trial of ``family`` in the layout: the condition shown first/left, the one shown
    second/right, the one chosen (None: the family's trials are not pairs)."""
    return families.get(family).export_columns.get(LAYOUT)


def export_pwcmp(db_path, out) -> Path:
    """Write the paired-comparison trials (not practice or catch) in pwcmp's layout.

    Columns ``observer, session, scene, condition_1, condition_2, selection``; ``selection`` is 1 when
    ``condition_1`` (shown first/left) was chosen, 2 when ``condition_2`` was.
    """
    with open_store(db_path) as st:
        rows = [r for r in st.tidy_rows() if pwcmp_columns(r["family"]) and not r["practice"] and not r["catch"]]
    if not rows:
        names = " or ".join(f.name for f in families.FAMILIES.values() if LAYOUT in f.export_columns)
        names = names or "paired-comparison"
        raise StoreError(f"{db_path}: no {names} trials to export in the pwcmp layout")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(HEADER)
    for r in rows:
        first, second, chosen = pwcmp_columns(r["family"])
        w.writerow((r["participant"], r["session"], r["scene"], r[first], r[second],
                    1 if r[chosen] == r[first] else 2))
    return write_text(out, buf.getvalue())
