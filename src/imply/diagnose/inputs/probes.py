"""Reading the calibration probes beside a push log: what a lab measures besides its pushes, one row per probe.

Format: a CSV or parquet file beside the push log, ``<stem>.probes.csv`` (or ``.parquet``),
with a ``probe`` column naming each row's kind and the cells that kind needs (the
others left empty):

- ``free_stroke``: the pusher's stroke with no box. ``speed`` (the commanded speed, m/s,
  > 0) and ``pusher_speed`` (its measured mean speed over the stroke, m/s, > 0, at most
  twice the command). It measures the pusher alone: a speed gain or offset, with no
  contact involved;
- ``friction``: a friction measurement of one object (a pull test: the force that drags
  it slowly at a steady speed, over its weight). ``object_id`` (an object of the log),
  ``friction`` (> 0) and ``friction_sd`` (its stated standard uncertainty, absolute, > 0;
  empty: :data:`DEFAULT_FRICTION_SD`, the within-lab spread of a standard friction test),
  and where known ``speed`` (the drag's speed, m/s, > 0; any speed, not only the table's)
  and ``direction`` (the drag's direction, radians, table frame). A prior for the object's
  friction, not a value to hold fixed: on a robot, what a test reads is not what the
  simulator's friction parameter means. What the test reads under each hypothesis's
  effects (a tilt along the drag, a viscous force at its speed, anisotropic friction along
  its direction) is predicted where the row says the speed and direction
  (:mod:`imply.diagnose.physics.probe_fit`);
- ``added_mass``: a push of an object of the log with a weighed load on it. ``object_id``,
  ``speed``, ``displacement`` (as a push), ``added_mass`` (kg, > 0: the load), and where
  measured ``direction``, ``stop_time`` and ``pusher_speed``.

Checks, each refused with one line naming the row and column: a known kind; the cells
that kind needs present and finite, positive where stated; a push's or a free stroke's
speed inside the table's range; an object the log has; one friction measurement per
object; a loaded box inside the table's mass range where the log weighs its objects.
Columns other than those named are kept and ignored.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imply.input_files import read_table_lines, row_error

KINDS = ("free_stroke", "friction", "added_mass")
DEFAULT_FRICTION_SD = 0.06  # absolute: about the within-lab spread of a standard friction test (ASTM D2534)
# m/s: a recommended pull test's drag, slow and steady, as a friction test drags (the benchmark worlds keep their own:
# they never import the diagnostic)
DEFAULT_PULL_SPEED = 0.1
# the cells each kind needs, and those it may have
NEEDS = {
    "free_stroke": ("speed", "pusher_speed"),
    "friction": ("object_id", "friction"),
    "added_mass": ("object_id", "speed", "displacement", "added_mass"),
}
MAY = {
    "free_stroke": (),
    "friction": ("friction_sd", "speed", "direction"),
    "added_mass": ("direction", "stop_time", "pusher_speed"),
}
NUMERIC = ("speed", "pusher_speed", "friction", "friction_sd", "displacement", "added_mass", "direction", "stop_time")


@dataclass(frozen=True)
class Probes:
    """A log's checked probes as arrays.

    free_stroke_speed, free_stroke_pusher_speed: (k,) commanded and measured mean speed (m/s).
    friction, friction_sd: (n_obj,) each object's measured friction and its uncertainty (NaN: not measured);
    friction_speed, friction_direction: (n_obj,) its pull test's drag speed (m/s) and direction (rad), NaN where the
    row does not say.
    added_obj: (a,) index into the log's objects; added_speed, added_displacement, added_mass: (a,) m/s, m, kg;
    added_direction, added_stop_time, added_pusher_speed: (a,) where measured (NaN otherwise).
    """

    path: str
    free_stroke_speed: np.ndarray
    free_stroke_pusher_speed: np.ndarray
    friction: np.ndarray
    friction_sd: np.ndarray
    friction_speed: np.ndarray
    friction_direction: np.ndarray
    added_obj: np.ndarray
    added_speed: np.ndarray
    added_displacement: np.ndarray
    added_mass: np.ndarray
    added_direction: np.ndarray
    added_stop_time: np.ndarray
    added_pusher_speed: np.ndarray

    @property
    def n_added(self) -> int:
        return int(self.added_obj.size)

    def counts(self) -> dict[str, int]:
        """How many probes of each kind."""
        return {
            "free_stroke": int(self.free_stroke_speed.size),
            "friction": int(np.isfinite(self.friction).sum()),
            "added_mass": self.n_added,
        }


def read_probes(
    path: str | os.PathLike,
    *,
    objects: list[str],
    log_path: str,
    mass: np.ndarray | None = None,
    speed_range: tuple[float, float] | None = None,
    mass_range: tuple[float, float] | None = None,
) -> Probes:
    """Read and check the probes of the push log at ``log_path`` (its ``objects``, and their weighed ``mass`` where
    it has them; the ranges are the table's); InputError names the bad row."""
    frame, lines = read_table_lines(path, ["probe"], [])
    kinds = np.array([str(k) for k in frame["probe"].tolist()], dtype=object)
    for i, kind in enumerate(kinds):
        if kind not in KINDS:
            raise row_error(path, i, "probe", f"{kind!r} is not a probe ({', '.join(KINDS)})", lines)
    values: dict[str, np.ndarray] = {}
    for col in NUMERIC:
        cells = [str(c) for c in frame[col].tolist()] if col in frame else [""] * len(frame)
        out = np.full(len(frame), np.nan)
        for i, cell in enumerate(cells):
            if cell == "":
                continue
            if col not in NEEDS[kinds[i]] + MAY[kinds[i]]:
                continue  # a cell this kind does not read
            try:
                out[i] = float(cell)
            except ValueError:
                raise row_error(path, i, col, f"{cell!r} is not a number", lines) from None
            if not np.isfinite(out[i]):
                raise row_error(path, i, col, f"{cell!r} is not a finite number", lines)
        values[col] = out
    ids = [str(c) for c in frame["object_id"].tolist()] if "object_id" in frame else [""] * len(frame)
    index = {o: k for k, o in enumerate(objects)}
    for i, kind in enumerate(kinds):
        for col in NEEDS[kind]:
            if col == "object_id":
                if ids[i] == "":
                    raise row_error(path, i, col, f"is empty; a {kind} probe names its object", lines)
                if ids[i] not in index:
                    raise row_error(path, i, col, f"{ids[i]!r} is not an object of {log_path}", lines)
            elif np.isnan(values[col][i]):
                raise row_error(path, i, col, f"is empty; a {kind} probe needs it", lines)
        for col in ("speed", "pusher_speed", "friction", "friction_sd", "displacement", "added_mass", "stop_time"):
            if values[col][i] <= 0:
                raise row_error(path, i, col, f"{values[col][i]:g} must be positive", lines)
        v = values["speed"][i]
        if (
            kind != "friction"  # a pull test drags at its own speed, slower than any push
            and speed_range is not None
            and not np.isnan(v)
            and not speed_range[0] * (1 - 1e-9) <= v <= speed_range[1] * (1 + 1e-9)
        ):
            raise row_error(
                path,
                i,
                "speed",
                f"{v:g} is outside the table's speed range [{speed_range[0]:g}, {speed_range[1]:g}]",
                lines,
            )
        if values["pusher_speed"][i] > 2.0 * v:
            raise row_error(
                path,
                i,
                "pusher_speed",
                f"{values['pusher_speed'][i]:g} m/s is more than twice the "
                "commanded speed; is it in m/s and of this probe?",
                lines,
            )
        if abs(values["direction"][i]) > 2 * np.pi + 1e-9:
            raise row_error(
                path, i, "direction", f"{values['direction'][i]:g} is not an angle in radians in [-2 pi, 2 pi]", lines
            )
    n_obj = len(objects)
    friction, friction_sd = np.full(n_obj, np.nan), np.full(n_obj, np.nan)
    friction_speed, friction_direction = np.full(n_obj, np.nan), np.full(n_obj, np.nan)
    for i in np.flatnonzero(kinds == "friction"):
        k = index[ids[i]]
        if np.isfinite(friction[k]):
            raise row_error(
                path,
                int(i),
                "object_id",
                f"{ids[i]!r} has a friction measurement in an earlier row; "
                "give one per object (their mean, with its uncertainty)",
                lines,
            )
        friction[k] = values["friction"][i]
        friction_sd[k] = values["friction_sd"][i] if np.isfinite(values["friction_sd"][i]) else DEFAULT_FRICTION_SD
        friction_speed[k], friction_direction[k] = values["speed"][i], values["direction"][i]
    added = np.flatnonzero(kinds == "added_mass")
    added_obj = np.array([index[ids[i]] for i in added], int)
    if mass is not None and mass_range is not None and added.size:
        loaded = np.asarray(mass, float)[added_obj] + values["added_mass"][added]
        over = np.flatnonzero(loaded > mass_range[1] * (1 + 1e-9))
        if over.size:
            i = int(added[over[0]])
            raise row_error(
                path,
                i,
                "added_mass",
                f"the loaded box weighs {loaded[over[0]]:g} kg, above the "
                f"table's mass range [{mass_range[0]:g}, {mass_range[1]:g}]",
                lines,
            )
    free = kinds == "free_stroke"
    return Probes(
        path=str(path),
        free_stroke_speed=values["speed"][free],
        free_stroke_pusher_speed=values["pusher_speed"][free],
        friction=friction,
        friction_sd=friction_sd,
        friction_speed=friction_speed,
        friction_direction=friction_direction,
        added_obj=added_obj,
        added_speed=values["speed"][added],
        added_displacement=values["displacement"][added],
        added_mass=values["added_mass"][added],
        added_direction=values["direction"][added],
        added_stop_time=values["stop_time"][added],
        added_pusher_speed=values["pusher_speed"][added],
    )


def probes_beside(log_path: str | os.PathLike) -> str | None:
    """The probes file that goes with a push log by name (``<stem>.probes.csv`` or ``.parquet``), or None."""
    p = Path(log_path)
    for suffix in (".csv", ".parquet"):
        candidate = p.with_name(f"{p.stem}.probes{suffix}")
        if candidate.is_file():
            return str(candidate)
    return None
