"""Atomic file output and per-step logging shared by every entry point.

Every writer goes to a temporary file in the destination folder and renames it into
place, so a crash or a refused input never leaves a half-written output behind.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import os
import secrets
import shutil
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success. On failure, a Ctrl-C included,
    nothing is left beside ``path`` (:func:`_make_sibling`)."""
    path = Path(path)
    suffix = suffix if suffix is not None else "".join(path.suffixes)
    made: list[Path] = []
    try:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = _make_sibling(path, made, suffix=suffix)
        except OSError as exc:
            # name the output the user asked for, not the temporary file beside it
            raise OSError(exc.errno, f"cannot write here: {exc.strerror}", str(path)) from exc
        yield tmp
        os.replace(tmp, path)
    finally:
        _remove(made)


def _make_sibling(path: Path, made: list[Path], *, suffix: str = "", folder: bool = False) -> Path:
    """Make a new, empty file (or ``folder``) beside ``path``, with the usual umask permissions, and return its path.

    Its name goes into ``made`` before it is made, so the caller's cleanup (:func:`_remove`) knows it wherever a Ctrl-C
    lands; a name returned only once the file exists (``tempfile.mkstemp``) left an empty file behind when the
    interrupt came just after the call."""
    base = path.name if folder else path.stem
    while True:
        made.append(path.parent / f".{base}.{os.getpid()}.{secrets.token_hex(4)}{suffix}")  # path may be "."
        try:
            if folder:
                os.mkdir(made[-1], 0o777)
            else:
                os.close(os.open(made[-1], os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            return made[-1]
        except FileExistsError:  # another writer's: not ours to remove
            made.pop()


def _remove(made: list[Path]) -> None:
    """Remove what :func:`_make_sibling` made and is still there (a temporary renamed into place is not)."""
    for tmp in made:
        if tmp.is_dir() and not tmp.is_symlink():
            shutil.rmtree(tmp)
        elif tmp.exists() or tmp.is_symlink():
            tmp.unlink()


def write_text(path: str | os.PathLike, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_json(path: str | os.PathLike, obj: Any) -> None:
    write_text(path, json.dumps(obj, indent=2, sort_keys=True, default=_json_default) + "\n")


def write_npz(path: str | os.PathLike, *, compressed: bool = False, **arrays: Any) -> None:
    """Write ``arrays`` as an .npz atomically (zip-deflated with ``compressed``), byte-stable.

    The same arrays give the same bytes: ``np.savez`` opens each entry by name, and
    zipfile stamps such entries with its fixed default date (1980-01-01), not the clock.
    Entries are in argument order. Written through a buffer because ``np.savez``
    appends .npz to a path without it.
    """
    buf = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buf, **arrays)
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.getvalue())


def write_csv(path: str | os.PathLike, frame) -> None:
    """Write a pandas DataFrame atomically, with a fixed float format for stable bytes."""
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False, float_format="%.10g")


def write_columns(path: str | os.PathLike, columns: dict[str, Any], float_format: str = "%.10g") -> None:
    """Write equal-length columns as CSV atomically, byte for byte as :func:`write_csv` would.

    For commands that should not pay for importing pandas: floats as ``float_format``
    with NaN as an empty cell, integers as integers, text quoted where CSV needs it.
    """
    import csv

    cells = []
    for values in columns.values():
        arr = np.asarray(values)
        if arr.dtype.kind == "f":
            cells.append(["" if x != x else float_format % x for x in arr.tolist()])
        else:
            cells.append([str(x) for x in values])
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(list(columns))
        writer.writerows(zip(*cells, strict=True))


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def setup_logging(log_file: str | os.PathLike | None = None, level: int = logging.INFO) -> logging.Logger:
    """Log to stderr and, when given, to ``log_file`` (a rule's ``log:``)."""
    logger = logging.getLogger("imply")
    logger.setLevel(level)
    logger.handlers.clear()
    fmt = logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s")
    stream = logging.StreamHandler()
    stream.setFormatter(fmt)
    logger.addHandler(stream)
    if log_file:
        Path(log_file).parent.mkdir(parents=True, exist_ok=True)
        handler = logging.FileHandler(log_file, mode="w")
        handler.setFormatter(fmt)
        logger.addHandler(handler)
    return logger


# -- report folders -------------------------------------------------------------------

MANIFEST = ".imply-manifest.json"


class OutputError(ValueError):
    """An output folder that cannot be written without destroying what it holds."""


def read_manifest(folder: str | os.PathLike) -> set[str]:
    """Names of the files a previous :func:`write_folder` put in ``folder`` (empty if none).

    Only plain file names are trusted: a manifest can never make us delete anything
    outside the folder.
    """
    path = Path(folder) / MANIFEST
    try:
        names = json.loads(path.read_text())["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return set()
    return {n for n in names if isinstance(n, str) and n == Path(n).name and n not in ("", ".", "..", MANIFEST)}


def check_folder(
    folder: str | os.PathLike, names: Iterable[str], force: bool, inputs: Iterable[str | os.PathLike] = ()
) -> None:
    """Refuse to write files ``names`` into ``folder`` where that would destroy something.

    A folder that does not exist or is empty is fine. A non-empty one needs ``force``,
    and even then each name it already holds must be one that a previous run listed in
    the folder's manifest, and no input may be among the files to be replaced.
    """
    folder = Path(folder)
    if not folder.exists():
        return
    if not folder.is_dir():
        raise OutputError(f"{folder} is a file, not a folder")
    if not any(folder.iterdir()):
        return
    if not force:
        raise OutputError(
            f"{folder} is not empty; give a new folder, or --force to replace a report written there before "
            "(other files are kept)"
        )
    ours = read_manifest(folder)
    for name in [*names, MANIFEST]:
        target = folder / name
        if (target.exists() or target.is_symlink()) and name != MANIFEST and name not in ours:
            raise OutputError(f"{target} exists and was not written by a previous report; move it first")
        for src in inputs:
            if src is not None and target.exists() and os.path.samefile(target, src):
                raise OutputError(f"{target} is an input and would be replaced by the report")


def write_folder(folder: str | os.PathLike, write: Callable[[Path], None], force: bool = False) -> list[str]:
    """Run ``write(tmp)`` in a temporary sibling folder, then move its files into ``folder``.

    A new or empty ``folder`` is replaced by the temporary one in one rename. Otherwise
    (``force``, checked by :func:`check_folder`) each file is renamed into place and the
    files the previous manifest lists but this run did not write are removed; nothing
    else in the folder is touched. A manifest of the files written is kept in the folder.
    Returns the names written.
    """
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    made: list[Path] = []
    try:
        tmp = _make_sibling(folder, made, folder=True)
        write(tmp)
        names = sorted(p.name for p in tmp.iterdir() if p.is_file())
        (tmp / MANIFEST).write_text(json.dumps({"written_by": "imply", "files": names}, indent=2) + "\n")
        if not folder.exists() or (folder.is_dir() and not any(folder.iterdir())):
            os.replace(tmp, folder)
            return names
        stale = read_manifest(folder) - set(names)
        for name in names:
            os.replace(tmp / name, folder / name)
        for name in stale:
            with contextlib.suppress(FileNotFoundError):
                (folder / name).unlink()
        os.replace(tmp / MANIFEST, folder / MANIFEST)
        return names
    finally:
        _remove(made)
