"""Scoring a user's rollouts file (``imply score``): read and check it, group rows into sets, score them.

The file has one row per push, ``object_id,role,speed,displacement`` (role
``calibration`` or ``rollout``; metres), CSV or parquet. :func:`read_rollouts` checks it
(every problem named by row and column), :func:`score_rows` scores every object's set at
once (:class:`imply.score.Scorer`), giving the columns of :data:`SCORE_COLUMNS`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from imply.score import Scorer
    from imply.table import PushTable

SCORE_COLUMNS = [
    "object_id",
    "n_rollouts",
    "self_disagreement",
    "anchored_disagreement",
    "mass_hat",
    "friction_hat",
    "anchored_mass_hat",
    "anchored_friction_hat",
]
ROLES = ("calibration", "rollout")


@dataclass(frozen=True)
class RolloutRows:
    """A checked rollouts file as arrays, one entry per row (see :func:`read_rollouts`)."""

    objects: list[str]  # object ids in order of first appearance
    codes: np.ndarray  # (n,) each row's index into objects
    is_rollout: np.ndarray  # (n,) bool: rollout, else calibration
    speed: np.ndarray
    displacement: np.ndarray


def read_rollouts(path: str | Path, table: PushTable) -> RolloutRows:
    """Read and check a rollouts CSV (or parquet) file for scoring (see ``imply score``).

    Refused, with the row and column named: unknown roles, negative displacements,
    speeds outside the table, empty object ids, objects with fewer than 2 rollouts, and
    two rows of one object with the same role and speed (a rollout set holds one
    prediction per speed). A plainly valid CSV file is read and checked without pandas
    (:func:`imply.input_files.read_plain_csv`); any problem sends it through
    :func:`imply.input_files.read_table`, whose messages give the line in the file.
    """
    from imply.input_files import InputError, read_plain_csv

    plain = read_plain_csv(path, ["object_id", "role"], ["speed", "displacement"])
    if plain is not None:
        roles, ids = plain["role"], plain["object_id"]
        role_ok = np.array([r in ROLES for r in roles.values], dtype=bool)
        is_rollout = np.array([r == "rollout" for r in roles.values], dtype=bool)[roles.codes]
        rows = RolloutRows(ids.values, ids.codes, is_rollout, plain["speed"], plain["displacement"])
        try:
            if role_ok.all() and "" not in ids.values:
                _check_rollouts(path, rows, table, None)
                return rows
        except InputError:
            pass  # read again below, for a message that names the line
    return _read_rollouts_carefully(path, table)


def _read_rollouts_carefully(path: str | Path, table: PushTable) -> RolloutRows:
    import pandas as pd

    from imply.input_files import read_table_lines, row_error

    frame, lines = read_table_lines(path, ["object_id", "role", "speed", "displacement"], ["speed", "displacement"])
    roles = frame["role"].to_numpy()
    bad_role = ~np.isin(roles, ROLES)
    if bad_role.any():
        i = int(np.flatnonzero(bad_role)[0])
        raise row_error(path, i, "role", f"{roles[i]!r} is not 'calibration' or 'rollout'", lines)
    ids = frame["object_id"].to_numpy()
    if (ids == "").any():
        raise row_error(path, int(np.flatnonzero(ids == "")[0]), "object_id", "is empty", lines)
    codes, objects = pd.factorize(frame["object_id"], sort=False)
    rows = RolloutRows(
        [str(o) for o in objects],
        codes.astype(np.int64),
        roles == "rollout",
        frame["speed"].to_numpy(float),
        frame["displacement"].to_numpy(float),
    )
    _check_rollouts(path, rows, table, lines)
    return rows


def _check_rollouts(path: str | Path, rows: RolloutRows, table: PushTable, lines: np.ndarray | None) -> None:
    """The checks on values, vectorised: 200,000 rows take a few milliseconds."""
    from imply.input_files import InputError, row_error, row_label

    d, v, codes = rows.displacement, rows.speed, rows.codes
    if (d < 0).any():
        i = int(np.flatnonzero(d < 0)[0])
        raise row_error(path, i, "displacement", f"{d[i]:g} is negative", lines)
    lo, hi = table.speed_range
    out = (v < lo * (1 - 1e-9)) | (v > hi * (1 + 1e-9))
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise row_error(path, i, "speed", f"{v[i]:g} is outside the table's speed range [{lo:g}, {hi:g}]", lines)
    n_rollouts = np.bincount(codes[rows.is_rollout], minlength=len(rows.objects))
    if (n_rollouts < 2).any():
        # codes number objects in order of first appearance: the smallest is the first in the file
        obj = int(np.flatnonzero(n_rollouts < 2)[0])
        raise row_error(
            path,
            int(np.flatnonzero(codes == obj)[0]),
            "object_id",
            f"object {rows.objects[obj]!r} has {n_rollouts[obj]} rollout(s); at least 2 are needed",
            lines,
        )
    order = np.lexsort((v, rows.is_rollout, codes))
    same = (np.diff(codes[order]) == 0) & (np.diff(rows.is_rollout[order]) == 0) & (np.diff(v[order]) == 0)
    if same.any():
        # of all repeated pairs, the one whose second row comes first in the file
        pairs = np.flatnonzero(same)
        j = pairs[np.argmin(order[pairs + 1])]
        first, second = sorted((int(order[j]), int(order[j + 1])))
        role = "rollout" if rows.is_rollout[first] else "calibration"
        raise InputError(
            f"{path}: {row_label(path, first, lines)} and {row_label(path, second, lines)}: object "
            f"{rows.objects[codes[first]]!r} has two {role} rows at speed {v[first]:g}; a rollout set holds "
            "one prediction per speed, so remove one of them"
        )


def pad_sets(codes: np.ndarray, speeds: np.ndarray, displacements: np.ndarray, n_sets: int):
    """Rows grouped into NaN-padded (n_sets, K) speeds and displacements, in file order within a set.

    A stable sort by set puts each set's rows together; a row's column is its rank in
    its set. K is the largest set; absent terms have NaN displacements (and speeds,
    which the caller replaces).
    """
    counts = np.bincount(codes, minlength=n_sets)
    width = max(int(counts.max(initial=0)), 1)
    order = np.argsort(codes, kind="stable")
    sorted_codes = codes[order]
    starts = np.cumsum(counts) - counts
    column = np.arange(order.size) - starts[sorted_codes]
    v = np.full((n_sets, width), np.nan)
    d = np.full((n_sets, width), np.nan)
    v[sorted_codes, column] = speeds[order]
    d[sorted_codes, column] = displacements[order]
    return v, d


def score_rows(rows: RolloutRows, scorer: Scorer) -> dict[str, Any]:
    """Scores of every object, in order of first appearance, as the columns of SCORE_COLUMNS."""
    n = len(rows.objects)
    v, d, roll = rows.speed, rows.displacement, rows.is_rollout
    rv, rd = pad_sets(rows.codes[roll], v[roll], d[roll], n)
    # absent terms need a valid speed for the range check; their displacement stays NaN
    rv[np.isnan(rv)] = v[0]
    has_cal = not roll.all()
    cv = cd = None
    if has_cal:
        cv, cd = pad_sets(rows.codes[~roll], v[~roll], d[~roll], n)
        cv[np.isnan(cv)] = v[0]
    scores = scorer.score(rv, rd, cv, cd)
    out: dict[str, Any] = {"object_id": rows.objects, **{c: getattr(scores, c) for c in SCORE_COLUMNS[1:]}}
    if has_cal:
        # objects without calibration rows get no anchored score
        no_cal = ~np.isfinite(cd).any(axis=1)
        for c in ("anchored_disagreement", "anchored_mass_hat", "anchored_friction_hat"):
            out[c] = np.where(no_cal, np.nan, out[c])
    return out
