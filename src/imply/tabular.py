"""Reading user CSV (or parquet) tables with errors that name the row and column.

Row numbers in messages count data rows from 1 (the header is not a row); the file's
line number is given beside them for CSV.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd


class InputError(ValueError):
    """A user table is unreadable or has a bad cell; the message names it."""


def read_table(
    path: str | Path, required: list[str], numeric: list[str], optional_numeric: list[str] = ()
) -> pd.DataFrame:
    """Read a CSV/parquet file, check required columns and numeric cells.

    Columns in ``numeric`` (and those of ``optional_numeric`` that are present) must hold
    finite numbers in every row. String columns are kept as strings.
    """
    path = Path(path)
    try:
        if path.suffix.lower() in (".parquet", ".pq"):
            frame = pd.read_parquet(path)
        else:
            frame = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except Exception as exc:
        raise InputError(f"{path}: cannot read as a table: {exc}") from exc
    frame.columns = [str(c).strip() for c in frame.columns]
    missing = [c for c in required if c not in frame.columns]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)} (have: {', '.join(frame.columns)})")
    if frame.empty:
        raise InputError(f"{path}: no data rows")
    for col in list(numeric) + [c for c in optional_numeric if c in frame.columns]:
        frame[col] = _numeric_column(frame[col], col, path)
    return frame


def _numeric_column(values: pd.Series, col: str, path: Path) -> pd.Series:
    as_num = pd.to_numeric(values, errors="coerce")
    bad = ~np.isfinite(as_num.to_numpy(dtype=float))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{path}: row {i + 1} (line {i + 2}), column {col}: {values.iloc[i]!r} is not a finite number")
    return as_num.astype(float)


def row_error(path: str | Path, index: int, col: str, message: str) -> InputError:
    """An error naming data row ``index`` (0-based) and column ``col``."""
    return InputError(f"{path}: row {index + 1} (line {index + 2}), column {col}: {message}")
