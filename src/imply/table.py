"""The table f(v, m, mu) -> log d: build it with the batched simulator, save, load, interpolate.

Axes: ``speeds`` (m/s, evenly spaced), ``masses`` (kg) and ``frictions`` (sliding
coefficient), both log-spaced; ``log_d`` holds the natural log of the canonical box's
displacement (metres), shape (speeds, masses, frictions). Interpolation is a
tensor-product cubic spline in (v, log m, log mu); queries outside the table's range
raise :class:`OutOfRangeError` instead of extrapolating.

``log_d`` is the simulator's converged answer as it is (no smoothing); the metadata
records the simulator's stepping, the table's numerical error as measured by
:func:`check_table` against a much finer reference, and the few cells where the
physics itself is not monotone.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import time
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import mujoco
import numpy as np
from scipy.interpolate import NdBSpline, RegularGridInterpolator

from imply.io import write_npz
from imply.options import Axis, Config, option
from imply.sim.pushes import simulate_pushes
from imply.sim.reference import ReferencePushes, reference_log_d
from imply.sim.scene import SceneConfig

log = logging.getLogger("imply.table")


class TableError(ValueError):
    """A table file is missing, unreadable or not a push table."""


class OutOfRangeError(ValueError):
    """A query lies outside the table's range."""


def spline_of(interp: RegularGridInterpolator):
    """The B-spline a cubic ``interp`` evaluates, to be called directly: the same values without the
    interpolator's per-call checks, which cost a quarter of a small call (the gap diagnostic makes tens
    of thousands). ``interp`` itself where SciPy keeps its spline elsewhere. Callers keep the points
    inside the grid: the spline extrapolates where the interpolator would raise."""
    spline = getattr(interp, "_spline", None)
    return spline if callable(spline) else interp


def spline_columns(*parts: tuple[Any, list[int]]):
    """One spline reading, side by side, the value columns ``cols`` of each ``(spline, cols)`` of ``parts``
    (splines from :func:`spline_of` on the same knots): the same values as concatenating each ``spline(pts)[...,
    cols]``. Scipy's tensor-product spline sums every column at each point, and most of its time goes to each point's
    basis: a caller that needs a few columns of several tables on one grid (the diagnostic's effect tables hold every
    observable at every level) reads them in one pass."""
    if all(isinstance(spline, NdBSpline) for spline, _ in parts):
        first = parts[0][0]
        if all(all(np.array_equal(a, b) for a, b in zip(spline.t, first.t, strict=True)) for spline, _ in parts):
            coefficients = [
                spline.c.reshape(*spline.c.shape[: len(spline.t)], -1)[..., list(cols)] for spline, cols in parts
            ]
            c = np.ascontiguousarray(np.concatenate(coefficients, axis=-1))
            return NdBSpline(first.t, c, first.k, extrapolate=first.extrapolate)
    index = [np.asarray(cols, int) for _, cols in parts]
    return lambda pts: np.concatenate([spline(pts)[..., i] for (spline, _), i in zip(parts, index, strict=True)], -1)


@dataclass(frozen=True, kw_only=True)
class TableConfig(Config):
    """Config section ``table``: the grid of the push table f(v, m, mu) -> log d."""

    config_key: ClassVar[str] = "table"

    speeds: Axis = option(Axis(min=0.15, max=1.05, n=19), doc="push speeds (m/s), evenly spaced", required=True)
    masses: Axis = option(Axis(min=0.2, max=2.0, n=25), doc="masses (kg), log-spaced", required=True)
    frictions: Axis = option(Axis(min=0.1, max=0.6, n=21), doc="frictions, log-spaced", required=True)

    def grid(self) -> TableGrid:
        """The table's axes as :func:`build_table` takes them."""
        return TableGrid(
            speed_min=self.speeds.min,
            speed_max=self.speeds.max,
            n_speeds=self.speeds.n,
            mass_min=self.masses.min,
            mass_max=self.masses.max,
            n_masses=self.masses.n,
            friction_min=self.frictions.min,
            friction_max=self.frictions.max,
            n_frictions=self.frictions.n,
        )


@dataclass(frozen=True)
class TableGrid:
    """Axes of the table, flat (recorded so in a table's metadata); built by :meth:`TableConfig.grid`."""

    speed_min: float
    speed_max: float
    n_speeds: int
    mass_min: float
    mass_max: float
    n_masses: int
    friction_min: float
    friction_max: float
    n_frictions: int

    @classmethod
    def from_dict(cls, cfg: dict[str, Any]) -> TableGrid:
        """From the config section ``table`` (``{speeds: {min, max, n}, ...}``)."""
        return TableConfig.from_dict(cfg).grid()

    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return (
            np.linspace(self.speed_min, self.speed_max, self.n_speeds),
            np.geomspace(self.mass_min, self.mass_max, self.n_masses),
            np.geomspace(self.friction_min, self.friction_max, self.n_frictions),
        )


@dataclass(frozen=True)
class PushTable:
    """A tabulated f(v, m, mu) -> log d with its metadata."""

    speeds: np.ndarray
    masses: np.ndarray
    frictions: np.ndarray
    log_d: np.ndarray
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        shape = (self.speeds.size, self.masses.size, self.frictions.size)
        if self.log_d.shape != shape:
            raise TableError(f"log_d has shape {self.log_d.shape}, expected {shape} from the axes")
        if not np.all(np.isfinite(self.log_d)):
            raise TableError("log_d has non-finite cells")
        for name in ("speeds", "masses", "frictions"):
            axis = getattr(self, name)
            if axis.size < 4 or np.any(np.diff(axis) <= 0):
                raise TableError(f"table axis {name} must increase strictly and have at least 4 points")

    # -- ranges ---------------------------------------------------------------
    @property
    def speed_range(self) -> tuple[float, float]:
        return float(self.speeds[0]), float(self.speeds[-1])

    @property
    def mass_range(self) -> tuple[float, float]:
        return float(self.masses[0]), float(self.masses[-1])

    @property
    def friction_range(self) -> tuple[float, float]:
        return float(self.frictions[0]), float(self.frictions[-1])

    def check_range(self, speeds=None, masses=None, frictions=None) -> None:
        """Raise :class:`OutOfRangeError` naming the first quantity outside the table."""
        tol = 1e-9
        for name, values, (lo, hi) in (
            ("speed", speeds, self.speed_range),
            ("mass", masses, self.mass_range),
            ("friction", frictions, self.friction_range),
        ):
            if values is None:
                continue
            arr = np.asarray(values, dtype=float)
            bad = ~((arr >= lo * (1 - tol)) & (arr <= hi * (1 + tol)))
            if np.any(bad):
                first = float(arr[bad].ravel()[0])
                raise OutOfRangeError(f"{name} {first:g} is outside the table's range [{lo:g}, {hi:g}]")

    # -- interpolation ----------------------------------------------------------
    @cached_property
    def _interpolator(self) -> RegularGridInterpolator:
        return RegularGridInterpolator(
            (self.speeds, np.log(self.masses), np.log(self.frictions)),
            self.log_d,
            method="cubic",
            # scipy's default solver tolerance leaves ~1e-5 errors even at the nodes
            solver_args={"atol": 1e-12, "rtol": 1e-12},
        )

    @cached_property
    def _spline(self):
        return spline_of(self._interpolator)

    def log_displacement(self, speeds, masses, frictions) -> np.ndarray:
        """Interpolated log d at scattered points (broadcast together)."""
        v, m, mu = np.broadcast_arrays(
            np.asarray(speeds, float), np.asarray(masses, float), np.asarray(frictions, float)
        )
        self.check_range(v, m, mu)
        pts = np.stack([v.ravel(), np.log(m).ravel(), np.log(mu).ravel()], axis=-1)
        return self._spline(pts).reshape(v.shape)

    def log_displacement_at(self, pts: np.ndarray) -> np.ndarray:
        """Interpolated log d (n,) at points ``pts`` (n, 3) of (v, log m, log mu) that the caller keeps inside the
        table's range (unchecked: the spline extrapolates outside it); :meth:`log_displacement`'s values."""
        return self._spline(pts)

    def fine_axes(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Log-mass and log-friction axes of an n x n search grid over the table's range."""
        return (
            np.linspace(np.log(self.masses[0]), np.log(self.masses[-1]), n),
            np.linspace(np.log(self.frictions[0]), np.log(self.frictions[-1]), n),
        )

    def on_fine_grid(self, speeds, n: int) -> np.ndarray:
        """log d for each speed over the n x n (log m, log mu) grid: (len(speeds), n * n)."""
        speeds = np.atleast_1d(np.asarray(speeds, float))
        self.check_range(speeds=speeds)
        lm, lu = self.fine_axes(n)
        grid = np.stack(np.meshgrid(speeds, lm, lu, indexing="ij"), axis=-1)
        return self._interpolator(grid.reshape(-1, 3)).reshape(speeds.size, n * n)

    # -- files ----------------------------------------------------------------
    def save(self, path: str | os.PathLike) -> None:
        arrays = dict(
            speeds=self.speeds,
            masses=self.masses,
            frictions=self.frictions,
            log_d=self.log_d,
            meta=np.array(json.dumps(self.meta, sort_keys=True)),
        )
        write_npz(path, **arrays)

    @classmethod
    def load(cls, path: str | os.PathLike) -> PushTable:
        path = Path(path)
        if not path.is_file():
            raise TableError(f"table file {path} does not exist")
        try:
            with np.load(path, allow_pickle=False) as z:
                missing = [k for k in ("speeds", "masses", "frictions", "log_d") if k not in z.files]
                if missing:
                    raise TableError(f"{path} is not a push table: missing array(s) {', '.join(missing)}")
                meta = json.loads(str(z["meta"])) if "meta" in z.files else {}
                return cls(
                    speeds=z["speeds"].astype(float),
                    masses=z["masses"].astype(float),
                    frictions=z["frictions"].astype(float),
                    log_d=z["log_d"].astype(float),
                    meta=meta,
                )
        except TableError:
            raise
        except Exception as exc:  # zip, pickle or JSON errors: all mean "not a table"
            raise TableError(f"cannot read table {path}: {exc}") from exc


def config_digest(obj: Any) -> str:
    """Short stable hash of a JSON-able config subset."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True).encode()).hexdigest()[:16]


def build_table(scene: SceneConfig, grid: TableGrid, *, nthread: int = 0, progress: bool = False) -> PushTable:
    """Simulate every (speed, mass, friction) cell with the canonical box and tabulate log d.

    The metadata records the simulator's stepping, the MuJoCo steps taken and the cells
    where log d does not increase with speed or decrease with friction (the converged
    scene has a few such cells: light, rough boxes at low speed; :func:`check_table`
    confirms them against the reference).
    """
    speeds, masses, frictions = grid.axes()
    v, m, mu = np.meshgrid(speeds, masses, frictions, indexing="ij")
    log.info("simulating %d table cells", v.size)
    result = simulate_pushes(v.ravel(), m.ravel(), mu.ravel(), scene=scene, nthread=nthread, progress=progress)
    if not result.ok.all():
        bad = np.flatnonzero(~result.ok)[0]
        raise RuntimeError(
            f"{int((~result.ok).sum())} table cells failed (first: v={v.ravel()[bad]:g}, "
            f"m={m.ravel()[bad]:g}, mu={mu.ravel()[bad]:g}); adjust the scene or the ranges"
        )
    log_d = np.log(result.displacement.reshape(v.shape))
    drop_speed = np.diff(log_d, axis=0)
    rise_friction = np.diff(log_d, axis=2)
    meta = {
        "scene": scene.to_dict(),
        "grid": grid.__dict__,
        "mujoco_version": mujoco.__version__,
        "config_digest": config_digest({"scene": scene.to_dict(), "grid": grid.__dict__}),
        "stepping": {
            "push_step_s": scene.timestep / scene.push_substeps,
            "slide_step_s": scene.timestep,
            "release_window_s": scene.release_window,
            "slide_steps": scene.slide_steps,
            "slow_push_speed": scene.slow_push_speed,
            "integrator": "Euler",
            "substeps_total": int(result.substeps.sum()),
        },
        "monotonicity": {
            "cells_decreasing_in_speed": int((drop_speed <= 0).sum()),
            "largest_decrease_in_speed": float(max(0.0, -drop_speed.min())),
            "cells_increasing_in_friction": int((rise_friction >= 0).sum()),
            "largest_increase_in_friction": float(max(0.0, rise_friction.max())),
        },
        "displacement_range_m": [float(np.exp(log_d.min())), float(np.exp(log_d.max()))],
        "numerical_error": None,
    }
    log.info("table built: %s", meta["monotonicity"])
    return PushTable(speeds, masses, frictions, log_d, meta=meta)


@dataclass(frozen=True, kw_only=True)
class TableCheckConfig(Config):
    """How :func:`check_table` measures a table's numerical error (config key ``table_check``).

    cells: grid nodes compared (the 8 corners of the range, then distinct random nodes);
      0 skips the check.
    seed: which random nodes.
    reference_substeps: the reference's uniform step is the table's timestep divided by this.
    """

    config_key: ClassVar[str] = "table_check"

    cells: int = option(200, doc="grid nodes compared (0: skip the check)", minimum=0)
    seed: int = option(0, doc="which random nodes", minimum=0)
    reference_substeps: int = option(64, doc="the reference's step is the table's timestep / this", minimum=2)

    def __post_init__(self) -> None:
        if self.cells < 0 or self.reference_substeps < 2:
            raise ValueError("table_check needs cells >= 0 and reference_substeps >= 2")


def check_nodes(shape: tuple[int, int, int], cells: int, seed: int) -> np.ndarray:
    """Flat indices of ``cells`` distinct grid nodes: the corners first, then random ones."""
    total = int(np.prod(shape))
    corners = np.ravel_multi_index(
        np.array(np.meshgrid(*[[0, n - 1] for n in shape], indexing="ij")).reshape(3, -1), shape
    )
    corners = np.unique(corners)[: min(cells, total)]
    rest = np.setdiff1d(np.arange(total), corners)
    rng = np.random.default_rng(seed)
    extra = rng.choice(rest, size=min(max(cells - corners.size, 0), rest.size), replace=False)
    return np.concatenate([corners, np.sort(extra)])


def reference_at_nodes(
    table: PushTable, settings: TableCheckConfig, *, nthread: int = 0, progress: bool = False
) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ReferencePushes]:
    """The sampled nodes' indices (i, j, k) and the reference log d at them."""
    scene = SceneConfig.from_dict(table.meta.get("scene"))
    nodes = check_nodes(table.log_d.shape, settings.cells, settings.seed)
    i, j, k = np.unravel_index(nodes, table.log_d.shape)
    step = scene.timestep / settings.reference_substeps
    ref = reference_log_d(
        table.speeds[i],
        table.masses[j],
        table.frictions[k],
        scene=scene,
        step=step,
        nthread=nthread,
        progress=progress,
    )
    return (i, j, k), ref


def error_against(
    table: PushTable, values: np.ndarray, nodes: tuple[np.ndarray, ...], ref: ReferencePushes, seed: int
) -> dict[str, Any]:
    """Summary of ``values`` (log d at ``nodes``) against the reference: max, RMS, worst node, method."""
    i, j, k = nodes
    diff = values - ref.log_d
    worst = int(np.argmax(np.abs(diff)))
    return {
        "max_abs_log_d": float(np.abs(diff).max()),
        "rms_log_d": float(np.sqrt(np.mean(diff**2))),
        "mean_log_d": float(diff.mean()),
        "cells": int(diff.size),
        "worst_cell": {
            "speed": float(table.speeds[i[worst]]),
            "mass": float(table.masses[j[worst]]),
            "friction": float(table.frictions[k[worst]]),
            "difference": float(diff[worst]),
        },
        "reference_step_s": ref.step,
        "reference_error_max": float(ref.error_estimate.max()),
        "reference_error_rms": float(np.sqrt(np.mean(ref.error_estimate**2))),
        "method": (
            f"{diff.size} grid nodes (8 corners + random, seed {seed}) against the same scene stepped uniformly "
            f"at {ref.step * 1e6:.4g} us from start to rest (imply.sim.reference); the reference's own error is "
            f"estimated as its difference from a run at twice that step"
        ),
    }


def check_table(
    table: PushTable, settings: TableCheckConfig | None = None, *, nthread: int = 0, progress: bool = False
) -> dict[str, Any]:
    """Numerical error of a table: its log d at sampled nodes against a much finer reference.

    The reference (:func:`imply.sim.reference.reference_log_d`) steps the same scene
    uniformly at ``timestep / reference_substeps`` on its own code path, and estimates its
    own error from a second run at twice that step. Returns max and RMS of
    |table - reference| over the nodes, the reference's own error estimate, the worst node,
    and how it was measured.
    """
    settings = settings or TableCheckConfig()
    t0 = time.perf_counter()
    nodes, ref = reference_at_nodes(table, settings, nthread=nthread, progress=progress)
    error = error_against(table, table.log_d[nodes], nodes, ref, settings.seed)
    # the time it took is logged, not stored: the same table must give the same bytes
    log.info("numerical error measured in %.1f s", time.perf_counter() - t0)
    return error


def with_numerical_error(table: PushTable, error: dict[str, Any]) -> PushTable:
    """The same table with its measured numerical error recorded in the metadata."""
    return PushTable(
        table.speeds, table.masses, table.frictions, table.log_d, meta={**table.meta, "numerical_error": error}
    )
