"""Reading a study's trial log (the tidy layout of :mod:`data_schema.trial_log`) for the analysis.

A log may be a CSV file, a Parquet file or a study database (SQLite, read through
:func:`data_schema.store.read_trials`). Text columns become pandas categoricals so that a
log of 10^7 trials fits in a few hundred MB; large CSV files are parsed with pyarrow when it
is installed (falls back to pandas' C parser otherwise).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from data_schema.trial_log import FAMILIES, FAMILY_COLUMNS, REQUIRED
from data_schema.errors import UserError

__all__ = ["LogError", "read_log", "validate_log"]

TEXT_COLUMNS = ("participant", "session", "block", "scene", "family", "condition", "condition_a",
                "condition_b", "conditions", "chosen", "chosen_2")
INT_COLUMNS = ("trial", "practice", "catch")
DB_SUFFIXES = (".db", ".sqlite", ".sqlite3")


class LogError(UserError):
    """A log that cannot be analysed; the message names the file and the problem in one line."""


def _read_csv(path: Path) -> pd.DataFrame:
    try:
        import pyarrow as pa
        from pyarrow import csv as pacsv
    except ImportError:  # pragma: no cover - pyarrow is in the analysis extra
        head = pd.read_csv(path, nrows=0)
        dtypes = {c: "category" for c in head.columns if c in TEXT_COLUMNS}
        return pd.read_csv(path, dtype=dtypes, keep_default_na=False, na_values=[""])
    import csv

    with open(path, encoding="utf-8-sig", newline="") as fh:
        names = [c.strip() for c in next(csv.reader(fh), [])]
    types = {c: pa.dictionary(pa.int32(), pa.string()) for c in names if c in TEXT_COLUMNS}
    table = pacsv.read_csv(
        path,
        convert_options=pacsv.ConvertOptions(column_types=types, strings_can_be_null=False,
                                             null_values=["", "NA", "NaN", "nan"]),
    )
    return table.to_pandas()


def read_log(path: Any) -> pd.DataFrame:
    """Read a trial log from CSV, Parquet or a study database and validate it.

    Parameters
    ----------
    path : str or Path
        ``*.csv``, ``*.parquet`` or a study database (``*.db``, ``*.sqlite``).

    Returns
    -------
    DataFrame
        The tidy log (see :mod:`data_schema.trial_log`), text columns as categoricals, with
        practice and catch trials removed; missing optional columns are added (``block`` and
        ``session`` as ``""``).

    Raises
    ------
    LogError
        Unreadable file, missing columns, unknown trial family, non-numeric response.
    """
    path = Path(path)
    if not path.exists():
        raise LogError(f"{path}: no such file")
    suffix = path.suffix.lower()
    try:
        if suffix in DB_SUFFIXES:
            from data_schema import store  # the session store (SQLite)

            df = store.read_trials(path)
        elif suffix == ".parquet":
            df = pd.read_parquet(path)
        elif suffix in (".csv", ".txt"):
            df = _read_csv(path)
        else:
            raise LogError(f"{path}: unknown log format {suffix or '(none)'!r}: use .csv, .parquet or .db")
    except LogError:
        raise
    except (ImportError, AttributeError) as exc:
        raise LogError(f"{path}: cannot read a study database here ({exc})") from None
    except Exception as exc:  # parser errors of pyarrow/pandas/sqlite: one line naming the file
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise LogError(f"{path}: cannot read the log: {msg}") from None
    return validate_log(df, str(path))


def validate_log(df: pd.DataFrame, name: str = "log") -> pd.DataFrame:
    """Check the columns and values of a tidy log; return it cleaned (see :func:`read_log`)."""
    if not isinstance(df, pd.DataFrame):
        raise LogError(f"{name}: expected a table, got {type(df).__name__}")
    missing = [c for c in REQUIRED if c not in df.columns]
    if missing:
        raise LogError(f"{name}: missing required column(s) {', '.join(missing)}")
    if len(df) == 0:
        raise LogError(f"{name}: the log has no trials")
    df = df.copy()
    for c in TEXT_COLUMNS:
        if c in df.columns and not isinstance(df[c].dtype, pd.CategoricalDtype):
            col = df[c]
            if not (pd.api.types.is_object_dtype(col) or pd.api.types.is_string_dtype(col)):
                col = col.astype("string")
            df[c] = col.astype("category")
    for c in ("block", "session"):
        if c not in df.columns:
            df[c] = pd.Categorical([""] * len(df))
        elif df[c].isna().any():
            df[c] = df[c].cat.add_categories([""]).fillna("") if "" not in df[c].cat.categories \
                else df[c].fillna("")
    families = [f for f in df["family"].cat.categories if (df["family"] == f).any()]
    unknown = [f for f in families if f not in FAMILIES]
    if unknown:
        raise LogError(f"{name}: unknown trial family {unknown[0]!r}: allowed {', '.join(FAMILIES)}")
    if df["family"].isna().any():
        raise LogError(f"{name}: column family has empty values")
    for fam in families:
        need = [c for c in FAMILY_COLUMNS[fam] if c not in df.columns]
        if need:
            raise LogError(f"{name}: {fam} trials need column(s) {', '.join(need)}")
    if "response" in df.columns:
        resp = df["response"]
        if not pd.api.types.is_numeric_dtype(resp) or pd.api.types.is_bool_dtype(resp):
            num = pd.to_numeric(resp.astype("string") if pd.api.types.is_bool_dtype(resp) else resp,
                                errors="coerce")
            bad = num.isna() & resp.notna()
            if bad.any():
                raise LogError(f"{name}: column response must be numeric (0/1), found {resp[bad].iloc[0]!r}")
            df["response"] = num.astype(float)
    for c in INT_COLUMNS:
        if c in df.columns:
            df[c] = pd.to_numeric(df[c], errors="coerce").fillna(0).astype(np.int64)
    drop = np.zeros(len(df), dtype=bool)
    for c in ("practice", "catch"):
        if c in df.columns:
            drop |= df[c].to_numpy() != 0
    if drop.any():
        df = df.loc[~drop]
        if len(df) == 0:
            raise LogError(f"{name}: the log has only practice/catch trials")
    if df["participant"].isna().any():
        raise LogError(f"{name}: column participant has empty values")
    return df.reset_index(drop=True)
