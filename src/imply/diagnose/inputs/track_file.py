"""Reading the box's track beside a push log: where each pushed box was over time, one row per frame.

Format: a CSV or parquet file of long rows, ``object_id,push,t,x,y`` and optionally ``yaw``:

- ``push``: which push of the log the frame belongs to: the value of the log's ``push``
  column where the log has one, else the push's row number in the log (1 for its first
  data row);
- ``object_id``: the pushed object, as in the log (checked against the push's);
- ``t``: seconds from the start of the push (the pusher's first motion), increasing
  within a push; any rate, and rates may differ between pushes;
- ``x``, ``y``: the box's position in the table plane (m), in the frame the log's
  ``direction`` is measured in (any origin); ``yaw`` (rad) is read and checked, not used.

Long rows, not one file per push or a column of arrays: a motion-capture or tracking
export is already a table of frames; each push may have its own number of frames and
rate; CSV and parquet both hold it without nesting; and a bad frame has a row number.

From each push's track the diagnostic takes the times at which the box has covered the
fractions :data:`imply.sim.track.FRACTIONS` of its own final travel along the push
(:func:`imply.sim.track.crossing_times`), the summaries the effect tables hold.

Checks, each refused with one line naming the row: the cells are finite numbers; a
push's frames are consecutive rows with increasing ``t``; the first frame comes with the
push (0 <= t <= :data:`MAX_START`, the box has not yet moved far); a track has at least
:data:`MIN_FRAMES` frames; its final travel along the push agrees with the log's
displacement within a factor :data:`TRAVEL_FACTOR`, give or take :data:`TRAVEL_SLACK`
(else it is another push's track, another unit or another frame); every push of the log has a track once any has; a track names a push the
log has, with that push's object; every fraction of a push's travel is crossed at a positive time. A push that
moved less than :data:`TRAVEL_SLACK` cannot be timed from its track: there the whole track is left out, and the
report says so (``PushLog.track_note``).
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

import numpy as np

from imply.diagnose.inputs.pushlog import PushLog
from imply.input_files import InputError, read_table_lines, row_error, row_label
from imply.sim.track import FRACTIONS, crossing_times

REQUIRED = ["object_id", "push", "t", "x", "y"]
OPTIONAL_NUMERIC = ["yaw"]
MAX_START = 0.1  # s: a track's first frame is at most this long after the push starts
MIN_FRAMES = 5
# a track's final travel must be within this factor of the log's displacement, give or take TRAVEL_SLACK (m): loose
# enough for a camera's few millimetres and a readout's gross outlier, tight enough to catch millimetres for metres,
# a track filmed in another frame than the log's directions, or most other pushes' tracks
TRAVEL_FACTOR = 3.0
TRAVEL_SLACK = 0.005


def push_numbers(pushlog: PushLog) -> np.ndarray:
    """(n,) the number a track file uses for each push of the log: its ``push`` column, else its row number."""
    if "push" in pushlog.frame:
        return pushlog.frame["push"].to_numpy(float)
    return np.arange(1, pushlog.n + 1, dtype=float)


def read_track(path: str | os.PathLike, pushlog: PushLog) -> PushLog:
    """The push log with its tracks' crossing times (:attr:`PushLog.crossing_times`), checked against it.

    Raises :class:`imply.input_files.InputError` naming the track file's row (or the push
    log's row, for a push without a track) for every check of the module's docstring.
    """
    frame, lines = read_table_lines(path, REQUIRED, ["push", "t", "x", "y"], OPTIONAL_NUMERIC)
    log_numbers = push_numbers(pushlog)  # unique: read_pushlog checks the column
    where = {float(p): i for i, p in enumerate(log_numbers)}
    push = frame["push"].to_numpy(float)
    t = frame["t"].to_numpy(float)
    x, y = frame["x"].to_numpy(float), frame["y"].to_numpy(float)
    ids = frame["object_id"].to_numpy(str)
    # a push's frames are consecutive rows: each new push value starts a block
    starts = np.flatnonzero(np.r_[True, push[1:] != push[:-1]])
    ends = np.r_[starts[1:], push.size]
    seen: dict[float, int] = {}
    times = np.full((pushlog.n, len(FRACTIONS)), np.nan)
    for a, b in zip(starts, ends, strict=True):
        p = float(push[a])
        if p in seen:
            raise row_error(
                path,
                a,
                "push",
                f"push {p:g} continues here after other pushes' frames (from "
                f"{row_label(path, seen[p], lines)}); a push's frames must be consecutive rows",
                lines,
            )
        seen[p] = a
        if p not in where:
            raise row_error(path, a, "push", f"{p:g} is not a push of {pushlog.path}", lines)
        i = where[p]
        wrong = np.flatnonzero(ids[a:b] != pushlog.objects[pushlog.obj[i]])
        if wrong.size:
            r = a + int(wrong[0])
            raise row_error(
                path,
                r,
                "object_id",
                f"{str(ids[r])!r}, but push {p:g} of the log is of {pushlog.objects[pushlog.obj[i]]!r}",
                lines,
            )
        back = np.flatnonzero(np.diff(t[a:b]) <= 0)
        if back.size:
            r = a + int(back[0]) + 1
            raise row_error(
                path,
                r,
                "t",
                f"{t[r]:g} does not come after the frame before it ({t[r - 1]:g}); times must increase within a push",
                lines,
            )
        if not 0.0 <= t[a] <= MAX_START:
            raise row_error(
                path,
                a,
                "t",
                f"the track of push {p:g} starts at {t[a]:g} s; it must start with the "
                f"push (0 <= t <= {MAX_START:g} s from the pusher's first motion)",
                lines,
            )
        if b - a < MIN_FRAMES:
            raise row_error(
                path,
                a,
                "push",
                f"the track of push {p:g} has {b - a} frame(s); at least {MIN_FRAMES} are needed",
                lines,
            )
        phi = pushlog.direction[i]
        travel = (x[a:b] - x[a]) * np.cos(phi) + (y[a:b] - y[a]) * np.sin(phi)
        final, d = round(float(travel[-1]), 6), float(pushlog.displacement[i])
        if not d / TRAVEL_FACTOR - TRAVEL_SLACK <= final <= d * TRAVEL_FACTOR + TRAVEL_SLACK:
            raise row_error(
                path,
                b - 1,
                "x",
                f"the track of push {p:g} ends {final:.4g} m along the push from where "
                f"it starts; the log's displacement is {d:.4g} m: is it this push's track, in metres, "
                "in the frame of the log's direction?",
                lines,
            )
        times[i] = crossing_times(t[a:b], travel, np.array([final]))[0]
    missing = [i for i, p in enumerate(log_numbers) if float(p) not in seen]
    if missing:
        raise InputError(
            f"{pushlog.path}: {row_label(pushlog.path, missing[0])}: push {log_numbers[missing[0]]:g} "
            f"has no track in {path} while {len(seen)} other push(es) have one; give every push a "
            "track or none"
        )
    bad = np.flatnonzero(~np.all(np.isfinite(times) & (times > 0), axis=1))
    if bad.size:
        i = int(bad[0])
        if float(pushlog.displacement[i]) < TRAVEL_SLACK:
            # a box that barely moves (less than a camera's few millimetres) has a track of noise: no time can be
            # read from it, and the fits take every push's crossing times or none, so the track is left out
            return replace(
                pushlog,
                track_note=f"the track was left out: push {log_numbers[i]:g} moved {pushlog.displacement[i]:.2g} m, "
                "too little for its track to time",
            )
        raise row_error(
            path,
            seen[float(log_numbers[i])],
            "t",
            f"the track of push {log_numbers[i]:g} gives no "
            "positive crossing time of every fraction of its travel (it starts already moved, or "
            "never moves)",
            lines,
        )
    return replace(pushlog, crossing_times=times, track_path=str(path))


def track_beside(log_path: str | os.PathLike) -> str | None:
    """The track file that goes with a push log by name (``<stem>.track.csv`` or ``.parquet`` beside it), or None."""
    p = Path(log_path)
    for suffix in (".csv", ".parquet"):
        candidate = p.with_name(f"{p.stem}.track{suffix}")
        if candidate.is_file():
            return str(candidate)
    return None
