"""Reading user CSV (or parquet) tables with errors that name the row and column.

Row numbers in messages count data rows from 1 (the header and blank lines are not
rows); for CSV the file's line number is given beside them, for parquet there is none.
Text cells (every column not read as numbers) are stripped of surrounding whitespace,
so ``"a "`` and ``"a"`` name the same object in every command.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

PARQUET_SUFFIXES = (".parquet", ".pq")


class InputError(ValueError):
    """A user table is unreadable or has a bad cell; the message names it."""


def read_table(
    path: str | Path, required: list[str], numeric: list[str], optional_numeric: Sequence[str] = ()
) -> pd.DataFrame:
    """Read a CSV/parquet file, check required columns and numeric cells (see :func:`read_table_lines`)."""
    return read_table_lines(path, required, numeric, optional_numeric)[0]


def read_table_lines(
    path: str | Path, required: list[str], numeric: list[str], optional_numeric: Sequence[str] = ()
) -> tuple[pd.DataFrame, np.ndarray | None]:
    """Read a CSV/parquet file, check required columns and numeric cells.

    Columns in ``numeric`` (and those of ``optional_numeric`` that are present) must hold
    finite numbers in every row. Other columns are kept as stripped strings. Returns the
    frame and each row's line in a CSV file (None for parquet), for :func:`row_error`.
    The lines are not kept in the frame's ``attrs``: pandas deep-copies those into every
    frame it derives, which made a groupby over many objects run out of memory.
    """
    import pandas as pd

    path = Path(path)
    parquet = path.suffix.lower() in PARQUET_SUFFIXES
    if path.is_dir():
        raise InputError(f"{path}: is a directory, not a table")
    lines = None
    if parquet and importlib.util.find_spec("pyarrow") is None:
        raise ModuleNotFoundError(f"{path}: reading parquet needs pyarrow", name="pyarrow")
    try:
        if parquet:
            frame = pd.read_parquet(path)
        else:
            frame, lines = _read_csv(path)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"{path}: cannot read as a {'parquet file' if parquet else 'CSV table'}: {exc}") from exc
    frame.columns = [str(c).strip() for c in frame.columns]
    missing = [c for c in required if c not in frame.columns]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)} (have: {', '.join(frame.columns)})")
    if frame.empty:
        raise InputError(f"{path}: no data rows")
    numeric_cols = list(numeric) + [c for c in optional_numeric if c in frame.columns]
    for col in frame.columns:
        if col not in numeric_cols:
            frame[col] = frame[col].str.strip() if not parquet else _text_column(frame[col])
    if not parquet:
        # blank lines are skipped, but only after their line numbers are known
        blank = (frame.iloc[:, 0] == "").to_numpy(copy=True)
        if blank.any():
            blank[blank] = (frame.loc[blank] == "").all(axis=1).to_numpy()
        if blank.any():
            frame = frame.loc[~blank].reset_index(drop=True)
            lines = lines[~blank]
            if frame.empty:
                raise InputError(f"{path}: no data rows")
    for col in numeric_cols:
        frame[col] = _numeric_column(frame[col], col, path, lines)
    return frame, lines


def _read_csv(path: Path) -> tuple[pd.DataFrame, np.ndarray]:
    import pandas as pd

    frame = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True, skip_blank_lines=False)
    # with blank lines kept, row i starts on line i + 2, unless quoted cells span lines
    lines = np.arange(len(frame), dtype=np.int64) + 2
    with open(path, "rb") as fh:
        newlines = fh.read().count(b"\n")
    if newlines > len(frame) + 1:
        extra = np.zeros(len(frame), dtype=np.int64)
        for col in frame.columns:
            extra += frame[col].str.count("\n").to_numpy(dtype=np.int64)
        lines[1:] += np.cumsum(extra)[:-1]
    return frame, lines


def _text_column(values: pd.Series) -> pd.Series:
    # parquet ids may be numbers or nulls; a null is an empty cell
    return values.map(lambda x: "" if x is None or (isinstance(x, float) and np.isnan(x)) else str(x).strip())


def _numeric_column(values: pd.Series, col: str, path: Path, lines: np.ndarray | None) -> pd.Series:
    import pandas as pd

    as_num = pd.to_numeric(values, errors="coerce")
    bad = ~np.isfinite(as_num.to_numpy(dtype=float))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        cell = values.iloc[i]
        shown = repr(cell) if isinstance(cell, str) else str(cell)
        raise row_error(path, i, col, f"{shown} is not a finite number", lines)
    return as_num.astype(float)


def row_label(path: str | Path, index: int, lines: np.ndarray | None = None) -> str:
    """``"row N (line L)"`` for data row ``index`` (0-based); parquet files have no lines."""
    label = f"row {index + 1}"
    if Path(path).suffix.lower() in PARQUET_SUFFIXES:
        return label
    line = int(lines[index]) if lines is not None else index + 2
    return f"{label} (line {line})"


def row_error(path: str | Path, index: int, col: str, message: str, lines: np.ndarray | None = None) -> InputError:
    """An error naming data row ``index`` (0-based) and column ``col``.

    ``lines`` is what :func:`read_table_lines` returns beside the frame: where each row
    sits in the file when blank lines were skipped.
    """
    return InputError(f"{path}: {row_label(path, index, lines)}, column {col}: {message}")


@dataclass(frozen=True)
class Coded:
    """A text column as codes into its distinct values (in order of first appearance)."""

    codes: np.ndarray  # (n,) int64
    values: list[str]


def read_plain_csv(path: str | Path, text: list[str], numeric: list[str]) -> dict[str, Coded | np.ndarray] | None:
    """The fast path of :func:`read_table` for a plainly valid CSV file, or None.

    Parses with pyarrow straight into arrays (no pandas, whose import alone costs more
    than reading 200,000 rows this way): ``text`` columns as :class:`Coded` (cells
    stripped as :func:`read_table` strips them), ``numeric`` ones as float arrays.
    Returns None for anything short of a clean file -- parquet, a missing or padded
    header name, a cell that is not a finite number, ragged rows, blank lines -- and
    the caller falls back to :func:`read_table`, whose errors name the row and line.
    It never accepts a file that :func:`read_table` refuses.
    """
    path = Path(path)
    if path.suffix.lower() in PARQUET_SUFFIXES or not path.is_file():
        return None
    try:
        import pyarrow as pa
        import pyarrow.compute as pc
        import pyarrow.csv as pacsv
    except ImportError:
        return None
    types = {c: pa.string() for c in text} | {c: pa.float64() for c in numeric}
    try:
        table = pacsv.read_csv(
            path,
            # blank lines are left in, so that a file with any goes the careful way (line numbers)
            parse_options=pacsv.ParseOptions(ignore_empty_lines=False),
            convert_options=pacsv.ConvertOptions(
                column_types=types, include_columns=list(types), strings_can_be_null=False
            ),
        )
    except (pa.ArrowException, OSError, ValueError):
        return None
    if table.num_rows == 0:
        return None
    out: dict[str, Coded | np.ndarray] = {}
    for col in numeric:
        arr = table.column(col).combine_chunks()
        if arr.null_count:
            return None
        # through the buffer: Array.to_numpy would import pandas
        values = np.frombuffer(arr.buffers()[1], dtype=np.float64, count=len(arr), offset=arr.offset * 8)
        if not np.isfinite(values).all():
            return None
        out[col] = values.copy()
    for col in text:
        enc = pc.dictionary_encode(table.column(col).combine_chunks())
        idx = enc.indices
        raw = np.frombuffer(idx.buffers()[1], dtype=np.int32, count=len(idx), offset=idx.offset * 4)
        # strip each distinct value with Python's own str.strip, exactly as read_table does,
        # then merge values that were distinct only by surrounding whitespace
        stripped = [v.strip() for v in enc.dictionary.to_pylist()]
        first: dict[str, int] = {}
        remap = np.array([first.setdefault(v, len(first)) for v in stripped], dtype=np.int64)
        out[col] = Coded(codes=remap[raw], values=list(first))
    return out
