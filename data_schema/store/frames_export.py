"""Exporter: every flip of the live trials, one row each (``studyapp export --format frames``), streamed."""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

from ..atomic import atomic_path
from .integrity import damage_is_refused
from .opening import open_store
from .session import Store
from .tables import COLUMNS, StoreError


#: Rows ``export --format frames`` reads and converts at a time (as Python objects, ~1 KB a row) ...
FRAMES_BLOCK_ROWS = 32768
#: ... and rows per Parquet row group (held as Arrow columns, ~140 bytes a row; a larger group compresses
#: better): memory is bounded by these, not by the table (docs/benchmarks.md, "Frames export").
FRAMES_ROW_GROUP_ROWS = 262144


def export_frames(db_path, out) -> Path:
    """Write the frames of every live trial (one row per flip) as Parquet (``.parquet``) or CSV.

    Columns: the frames table's, ``idx`` named ``trial``, and ``gaze_age_ms`` (flip time - gaze sample time).
    Streamed: :data:`FRAMES_BLOCK_ROWS` rows at a time from a cursor, written as runs of CSV lines or gathered
    into Parquet row groups of :data:`FRAMES_ROW_GROUP_ROWS`, so memory does not grow with the table. The file
    is the one ``DataFrame.to_csv``/``to_parquet`` of the whole table gives (Parquet: the same bytes up to one
    row group, the same schema and values beyond).
    """
    out = Path(out)
    with open_store(db_path) as st, damage_is_refused(st.path):
        blocks = _frame_blocks(st, FRAMES_BLOCK_ROWS)
        first = next(blocks, None)
        if first is None:
            raise StoreError(f"{db_path}: no live-trial frames to export")
        with atomic_path(out) as tmp:
            if out.suffix.lower() == ".csv":
                with open(tmp, "w", encoding="utf-8", newline="") as fh:
                    for i, rows in enumerate(itertools.chain([first], blocks)):
                        _frames_table(db_path, rows).to_csv(fh, header=i == 0, index=False, lineterminator="\n")
            else:
                import pyarrow as pa
                import pyarrow.parquet as pq

                tables = (pa.Table.from_pandas(_frames_table(db_path, rows), preserve_index=False)
                          for rows in itertools.chain([first], blocks))
                writer = None
                try:
                    for group in _row_groups(tables, FRAMES_ROW_GROUP_ROWS):
                        if writer is None:  # what DataFrame.to_parquet writes: its schema, snappy
                            writer = pq.ParquetWriter(tmp, group.schema, compression="snappy")
                        writer.write_table(group, row_group_size=group.num_rows)
                finally:
                    if writer is not None:
                        writer.close()
    return out


def _row_groups(tables: Iterable, size: int) -> Iterator:
    """Arrow tables joined into tables of at least ``size`` rows (the last may have fewer)."""
    import pyarrow as pa

    pending: list = []
    for t in tables:
        pending.append(t)
        if sum(p.num_rows for p in pending) >= size:
            yield pa.concat_tables(pending)
            pending = []
    if pending:
        yield pa.concat_tables(pending)


def _frame_blocks(st: Store, size: int) -> Iterator[list[tuple]]:
    """The frames table in key order, ``size`` rows at a time, each row checked by :meth:`Store.iter_frames`
    (one cursor: nothing held but the block)."""
    rows = st.iter_frames()
    while block := [tuple(r.values()) for r in itertools.islice(rows, size)]:
        yield block


def _frames_table(db_path, rows: Sequence[tuple]):
    """One block of frame rows as the export's DataFrame: fixed dtypes, so that every block has the same
    schema (text ``participant``, int64 counts, float64 reals with NaN for NULL), ``idx`` named ``trial``, and
    ``gaze_age_ms``."""
    import numpy as np
    import pandas as pd

    data = {}
    for name, values in zip(COLUMNS["frames"], zip(*rows)):
        types = _FRAME_TYPES.get(name, (float, int, type(None)))
        if not all(type(v) in types for v in values):  # exact conversions only (numpy would parse "5", cut 1.5)
            bad = next(v for v in values if type(v) not in types)
            raise StoreError(f"{db_path}: a row of frames holds {name}={bad!r:.40}, not a value studyapp logs: the "
                             "database was not written by studyapp (restore its last good copy)")
        if name == "participant":
            data[name] = list(values)
        else:
            data["trial" if name == "idx" else name] = np.array(values, np.float64 if float in types else np.int64)
    df = pd.DataFrame(data)
    df["gaze_age_ms"] = (df["flip_s"] - df["gaze_t"]) * 1000.0
    return df


#: The Python types SQLite returns for the frames table's columns as studyapp writes them (default: a real,
#: NULL allowed; SQLite may return a whole real as int).
_FRAME_TYPES = {"participant": (str,), "idx": (int,), "frame": (int,), "stimulus": (int,), "dropped": (int,)}
