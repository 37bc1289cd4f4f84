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

from data_schema.errors import UserError
from data_schema.trial_log import FAMILIES, FAMILY_COLUMNS, REQUIRED, TIMING_COLUMNS

__all__ = ["LogError", "read_log", "validate_log"]

TEXT_COLUMNS = ("participant", "session", "block", "scene", "family", "condition", "condition_a",
                "condition_b", "conditions", "chosen", "chosen_2")
DB_SUFFIXES = (".db", ".sqlite", ".sqlite3")
#: Measured columns: finite numbers or empty (NaN).
FLOAT_COLUMNS = ("rt_s", *TIMING_COLUMNS)


class LogError(UserError):
    """A log that cannot be analysed; the message names the file and the problem in one line."""


def _check_unique_columns(names, name: str) -> None:
    seen: dict[str, int] = {}
    for i, c in enumerate(names):
        if c in seen:
            raise LogError(f"{name}: column {c!r} appears twice in the header (columns {seen[c] + 1} and {i + 1})")
        seen[c] = i


def _read_csv(path: Path) -> pd.DataFrame:
    import csv

    with open(path, encoding="utf-8-sig", newline="") as fh:
        names = [c.strip() for c in next(csv.reader(fh), [])]
    _check_unique_columns(names, str(path))
    try:
        import pyarrow as pa
        from pyarrow import csv as pacsv
    except ImportError:  # pragma: no cover - pyarrow is in the analysis extra
        dtypes = {c: "category" for c in names if c in TEXT_COLUMNS}
        return pd.read_csv(path, dtype=dtypes, keep_default_na=False, na_values=[""])
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
        Unreadable file, a column named twice, missing columns, unknown trial family, a yes/no response
        other than 0 or 1, a ``practice``/``catch`` flag other than 0 or 1, a ``trial`` that is not a whole
        number in [0, 2**63), a non-finite ``rt_s`` or timing value, an empty participant or scene. Values are
        checked before practice and catch trials are dropped; the message names the file, the column, the first bad line
        (CSV; header = line 1) or row (other formats, 1-based) and its value.
    """
    from data_schema.atomic import input_file

    path = input_file(Path(path), "log file", LogError)  # a FIFO would block the reader
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
    return validate_log(df, str(path), first_line=2 if suffix in (".csv", ".txt") else None)


def _where(i: int, first_line: int | None) -> str:
    """Position of data row ``i`` (0-based): a file line for text logs, else a 1-based row number."""
    return f"line {i + first_line}" if first_line is not None else f"row {i + 1}"


def _numbers(values: pd.Series) -> tuple[np.ndarray, pd.Series]:
    """``values`` as float64 (NaN for empty and for text that is not a number) and the raw values (empty: NA)."""
    raw = values
    if pd.api.types.is_bool_dtype(raw):
        num = raw.astype("float64").to_numpy(dtype=float, na_value=np.nan)
    elif pd.api.types.is_numeric_dtype(raw):
        num = raw.to_numpy(dtype=float, na_value=np.nan)
    else:
        text = raw.astype("string").str.strip()
        raw = text.mask(text == "")
        with np.errstate(over="ignore"):  # a 400-digit number is inf, refused by the callers' checks
            num = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float, na_value=np.nan)
    return num, raw


def _refuse_first(bad: np.ndarray, raw: pd.Series, column: str, name: str, first_line: int | None,
                  problem: str) -> None:
    """A LogError naming the first row of ``bad`` (if any), the column and the value (cut to 40 characters)."""
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        v = raw.iloc[i]
        v = v.item() if isinstance(v, np.generic) else v
        v = int(v) if isinstance(v, float) and v.is_integer() and abs(v) < 2 ** 63 else v
        text = repr(v) if len(repr(v)) <= 42 else f"{repr(v)[:39]}... ({len(str(v)):,} characters)"
        raise LogError(f"{name}: {_where(i, first_line)}: column {column} {problem}, found {text}")


def _binary_column(values: pd.Series, column: str, name: str, first_line: int | None, what: str,
                   rows: np.ndarray | None = None) -> np.ndarray:
    """``values`` as floats that are 0 or 1 (NaN kept), or a LogError naming the first other value.

    ``rows`` (bool mask) restricts the check to some rows (the others are returned unchecked).
    """
    num, raw = _numbers(values)
    bad = raw.notna().to_numpy() & ~((num == 0.0) | (num == 1.0))
    if rows is not None:
        bad &= rows
    _refuse_first(bad, raw, column, name, first_line, f"{what} must be 0 or 1")
    return num


def _trial_column(values: pd.Series, name: str, first_line: int | None) -> np.ndarray:
    """Trial indexes as int64: whole numbers in [0, 2**63) (empty: 0), or a LogError naming the first other."""
    num, raw = _numbers(values)
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(num) & (num >= 0) & (num < 2.0 ** 63) & (np.floor(num) == num)
    _refuse_first(raw.notna().to_numpy() & ~ok, raw, "trial", name, first_line,
                  "(the 0-based trial index) must be a whole number in [0, 2**63)")
    return np.where(ok, num, 0).astype(np.int64)


def _float_column(values: pd.Series, column: str, name: str, first_line: int | None) -> np.ndarray:
    """A measured column (``rt_s``, the live timing) as float64: finite numbers, empty as NaN."""
    num, raw = _numbers(values)
    _refuse_first(raw.notna().to_numpy() & ~np.isfinite(num), raw, column, name, first_line,
                  "must be a finite number (or empty)")
    return num


def validate_log(df: pd.DataFrame, name: str = "log", first_line: int | None = None) -> pd.DataFrame:
    """Check the columns and values of a tidy log; return it cleaned (see :func:`read_log`).

    ``first_line`` is the file line of the first data row (2 for a CSV with a header); messages then name
    lines, otherwise 1-based rows.
    """
    if not isinstance(df, pd.DataFrame):
        raise LogError(f"{name}: expected a table, got {type(df).__name__}")
    _check_unique_columns([str(c) for c in df.columns], name)
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
        scored = [f for f in FAMILIES if "response" in FAMILY_COLUMNS[f]]  # the families that log a yes/no
        df["response"] = _binary_column(df["response"], "response", name, first_line,
                                        f"of a {'/'.join(scored)} trial", rows=df["family"].isin(scored).to_numpy())
    for c in ("practice", "catch"):
        if c in df.columns:
            flag = _binary_column(df[c], c, name, first_line, "(a flag)")
            df[c] = np.nan_to_num(flag, nan=0.0).astype(np.int64)  # an empty flag is 0
    if "trial" in df.columns:
        df["trial"] = _trial_column(df["trial"], name, first_line)
    for c in FLOAT_COLUMNS:
        if c in df.columns:
            df[c] = _float_column(df[c], c, name, first_line)
    drop = np.zeros(len(df), dtype=bool)
    for c in ("practice", "catch"):
        if c in df.columns:
            drop |= df[c].to_numpy() != 0
    for c in ("participant", "scene"):  # of the analysed trials: an empty one would be a participant/scene ""
        text = df[c].astype("string").str.strip()
        _refuse_first(~drop & text.fillna("").eq("").to_numpy(), df[c], c, name, first_line, "must not be empty")
    if drop.any():
        df = df.loc[~drop]
        if len(df) == 0:
            raise LogError(f"{name}: the log has only practice/catch trials")
    return df.reset_index(drop=True)
