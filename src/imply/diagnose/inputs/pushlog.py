"""Reading a push log: one row per observed push, checked cell by cell.

Columns (CSV or parquet): ``object_id,speed,displacement`` are required (speed in
m/s, displacement in metres, both positive); optional ``direction`` (push direction
in the table plane, radians, within [-2 pi, 2 pi]), ``stop_time`` (s, > 0: from the
start of the push until the box's speed falls below 1 cm/s), ``pusher_speed`` (m/s, > 0:
the pusher's mean speed over its stroke, from its encoders: the stroke length over the
time from the start of the push until the pusher reached the end of its stroke),
``size_x,size_y,size_z`` (box half-extents, m, > 0; all three or none), ``mass`` (kg,
> 0) and ``friction`` (> 0) where measured, and ``ok`` (true/false, as written by
``imply sim pushes``), and ``push`` (a number naming each push, unique: what a track file
refers to; without it, a push is its row number). Other columns are kept and ignored.

The box's track over time, where recorded, comes in a second file of long rows
(:mod:`imply.diagnose.inputs.track_file`); the diagnostic reads from it the times at which the box
covers fractions of its travel (:attr:`PushLog.crossing_times`).

Measured ``mass`` and ``friction`` must be constant within an object and inside the
table's range; the diagnostic then holds them fixed instead of fitting them (see
:class:`imply.diagnose.inference.fit.Problem`), which removes the aliasing of effects with the
(m, mu) fit.

Nothing is dropped: a bad cell raises :class:`imply.input_files.InputError` naming its
row and column, including a push whose ``ok`` is false and an object with too few
pushes to fit its mass and friction (at least 3 pushes at 2 or more speeds).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from imply.input_files import InputError, read_table_lines, row_error
from imply.sim.track import FRACTIONS

if TYPE_CHECKING:
    from imply.diagnose.inputs.probes import Probes

REQUIRED = ["object_id", "speed", "displacement"]
SIZE_COLUMNS = ["size_x", "size_y", "size_z"]
OPTIONAL_NUMERIC = ["direction", "stop_time", "pusher_speed", *SIZE_COLUMNS, "mass", "friction", "push"]
# the observables a track gives: log of the time the box takes to cover each fraction of its travel
TRACK_OBSERVABLES = tuple(f"crossing_{round(100 * q)}" for q in FRACTIONS)


@dataclass(frozen=True)
class PushLog:
    """A checked push log as arrays (one entry per push) plus the frame it came from."""

    path: str
    frame: pd.DataFrame
    objects: list[str]  # in order of first appearance
    obj: np.ndarray  # (n,) index into objects
    speed: np.ndarray
    displacement: np.ndarray
    direction: np.ndarray  # zeros where the log has no direction column
    has_direction: bool
    mass: np.ndarray | None = None  # measured mass per object, where the log has it
    friction: np.ndarray | None = None  # measured friction per object, where the log has it
    stop_time: np.ndarray | None = None  # (n,) seconds from the start of the push to the stop, where logged
    pusher_speed: np.ndarray | None = None  # (n,) the pusher's measured mean speed over the stroke (m/s), where logged
    crossing_times: np.ndarray | None = None  # (n, Q) from the box's track: when it covered each of FRACTIONS (s)
    track_path: str | None = None  # the track file they were read from
    track_note: str | None = None  # why the log's track was left out, where it was
    probes: Probes | None = (
        None  # the calibration probes beside the log (imply.diagnose.inputs.probes), where it has them
    )
    # where the log's observables are measured against a reference session (imply.diagnose.reference): by
    # observable name ("displacement", or one of the aux observables), the (n,) sd of the baseline taken out of
    # each push's log value, which a fit counts beside the noise (None: the table is the only baseline)
    baseline_sd: dict[str, np.ndarray] | None = None

    def aux(self, name: str) -> np.ndarray | None:
        """(n,) the log of an observable beside the displacement (``stop_time``, ``pusher_speed``, or one of
        :data:`TRACK_OBSERVABLES`), or None where the log lacks it."""
        if name in TRACK_OBSERVABLES:
            ct = self.crossing_times
            return None if ct is None else np.log(ct[:, TRACK_OBSERVABLES.index(name)])
        values = getattr(self, name)
        return None if values is None else np.log(values)

    @property
    def n(self) -> int:
        return int(self.speed.size)

    @property
    def log_d(self) -> np.ndarray:
        return np.log(self.displacement)


def read_pushlog(
    path: str | os.PathLike,
    speed_range: tuple[float, float] | None = None,
    min_pushes: int = 3,
    mass_range: tuple[float, float] | None = None,
    friction_range: tuple[float, float] | None = None,
) -> PushLog:
    """Read and check a push log; the ranges are the table's (values outside them are errors)."""
    frame, lines = read_table_lines(path, REQUIRED, ["speed", "displacement"], OPTIONAL_NUMERIC)
    # read_table strips text cells, as it does for `imply score`: "a " and "a" are one object
    ids = frame["object_id"]
    if (ids == "").any():
        raise row_error(path, int(np.flatnonzero((ids == "").to_numpy())[0]), "object_id", "is empty", lines)

    def first_bad(mask: np.ndarray, col: str, message) -> None:
        if mask.any():
            i = int(np.flatnonzero(mask)[0])
            raise row_error(path, i, col, message(frame[col].iloc[i]), lines)

    d = frame["displacement"].to_numpy()
    first_bad(d < 0, "displacement", lambda x: f"{x:g} is negative")
    first_bad(
        d == 0,
        "displacement",
        lambda x: "is 0; displacements must be positive (their log is fitted)",
    )
    v = frame["speed"].to_numpy()
    first_bad(v <= 0, "speed", lambda x: f"{x:g} must be positive")
    if speed_range is not None:
        lo, hi = speed_range
        first_bad(
            (v < lo * (1 - 1e-9)) | (v > hi * (1 + 1e-9)),
            "speed",
            lambda x: f"{x:g} is outside the table's speed range [{lo:g}, {hi:g}]",
        )
    if "direction" in frame:
        phi = frame["direction"].to_numpy()
        first_bad(
            np.abs(phi) > 2 * np.pi + 1e-9,
            "direction",
            lambda x: f"{x:g} is not an angle in radians in [-2 pi, 2 pi]",
        )
    if "stop_time" in frame:
        first_bad(
            frame["stop_time"].to_numpy() < 0,
            "stop_time",
            lambda x: f"{x:g} is negative",
        )
        first_bad(
            frame["stop_time"].to_numpy() == 0,
            "stop_time",
            lambda x: "is 0; stop times must be positive (their log is fitted)",
        )
    if "pusher_speed" in frame:
        p = frame["pusher_speed"].to_numpy()
        first_bad(p <= 0, "pusher_speed", lambda x: f"{x:g} must be positive (the pusher's mean speed, m/s)")
        # a pusher cannot average more than it was commanded by much: a column of another unit or another push
        first_bad(
            p > 2.0 * v,
            "pusher_speed",
            lambda x: f"{x:g} m/s is more than twice the commanded speed; is it in m/s and of this push?",
        )
    for col in [*SIZE_COLUMNS, "mass", "friction"]:
        if col in frame:
            first_bad(frame[col].to_numpy() <= 0, col, lambda x: f"{x:g} must be positive")
    present = [c for c in SIZE_COLUMNS if c in frame]
    if present and len(present) < 3:
        missing = [c for c in SIZE_COLUMNS if c not in frame]
        raise InputError(f"{path}: size columns come as a set; missing {', '.join(missing)}")
    if "ok" in frame:
        ok = frame["ok"].astype(str).str.strip().str.lower()
        first_bad(
            ~ok.isin(["true", "false", "1", "0"]).to_numpy(),
            "ok",
            lambda x: f"{x!r} is not true/false",
        )
        first_bad(
            ok.isin(["false", "0"]).to_numpy(),
            "ok",
            lambda x: "the push failed the simulator's checks (ok=false); remove the row or fix the model",
        )
    if "push" in frame:
        first_bad(
            frame["push"].duplicated().to_numpy(),
            "push",
            lambda x: f"{x:g} names an earlier push too; push numbers must be unique (a track refers to them)",
        )

    objects = list(dict.fromkeys(frame["object_id"]))
    index = {o: i for i, o in enumerate(objects)}
    obj = frame["object_id"].map(index).to_numpy()
    for o, i in index.items():
        rows = np.flatnonzero(obj == i)
        if rows.size < min_pushes or np.unique(v[rows]).size < 2:
            raise row_error(
                path,
                int(rows[0]),
                "object_id",
                f"object {o!r} has {rows.size} push(es) at {np.unique(v[rows]).size} speed(s); at least "
                f"{min_pushes} pushes at 2 or more speeds are needed to fit its mass and friction",
                lines,
            )
    measured: dict[str, np.ndarray | None] = {"mass": None, "friction": None}
    for col, rng in (("mass", mass_range), ("friction", friction_range)):
        if col not in frame:
            continue
        vals = frame[col].to_numpy(float)
        per_obj = np.empty(len(objects))
        for i in range(len(objects)):
            rows = np.flatnonzero(obj == i)
            if np.ptp(vals[rows]) > 1e-9 * abs(vals[rows[0]]):
                bad = rows[np.flatnonzero(vals[rows] != vals[rows[0]])[0]]
                raise row_error(
                    path,
                    int(bad),
                    col,
                    f"differs from the object's first row ({vals[rows[0]]:g}); "
                    "a measured value must be the same on every push of an object",
                    lines,
                )
            per_obj[i] = vals[rows[0]]
        if rng is not None:
            lo, hi = rng
            first_bad(
                (vals < lo * (1 - 1e-9)) | (vals > hi * (1 + 1e-9)),
                col,
                lambda x, lo=lo, hi=hi: f"{x:g} is outside the table's range [{lo:g}, {hi:g}]",
            )
        measured[col] = per_obj
    has_dir = "direction" in frame
    return PushLog(
        path=str(path),
        frame=frame,
        objects=objects,
        obj=obj,
        speed=v.astype(float),
        displacement=d.astype(float),
        direction=frame["direction"].to_numpy(float) if has_dir else np.zeros(v.size),
        has_direction=has_dir,
        mass=measured["mass"],
        friction=measured["friction"],
        stop_time=frame["stop_time"].to_numpy(float) if "stop_time" in frame else None,
        pusher_speed=frame["pusher_speed"].to_numpy(float) if "pusher_speed" in frame else None,
    )
