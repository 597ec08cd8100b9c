"""The table f(v, m, mu) -> log d: build it with the batched simulator, save, load, interpolate.

Axes: ``speeds`` (m/s, evenly spaced), ``masses`` (kg) and ``frictions`` (sliding
coefficient), both log-spaced; ``log_d`` holds the natural log of the canonical box's
displacement (metres), shape (speeds, masses, frictions). Interpolation is a
tensor-product cubic spline in (v, log m, log mu); queries outside the table's range
raise :class:`OutOfRangeError` instead of extrapolating.

The simulator's contact solver leaves sub-millimetre jitter in cells where d barely
changes with v or mu. The saved ``log_d`` is the raw table projected onto tables that
increase with speed and decrease with friction (alternating isotonic regressions);
``log_d_raw`` keeps the simulator's values and the metadata records how far the
projection moved any cell.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from scipy.interpolate import RegularGridInterpolator
from scipy.optimize import isotonic_regression

from imply.io import write_npz
from imply.sim.pushes import simulate_pushes
from imply.sim.scene import SceneConfig

log = logging.getLogger("imply.table")


class TableError(ValueError):
    """A table file is missing, unreadable or not a push table."""


class OutOfRangeError(ValueError):
    """A query lies outside the table's range."""


@dataclass(frozen=True)
class TableGrid:
    """Axes of the table (config key ``table``)."""

    speed_min: float = 0.15
    speed_max: float = 1.05
    n_speeds: int = 19
    mass_min: float = 0.2
    mass_max: float = 2.0
    n_masses: int = 25
    friction_min: float = 0.1
    friction_max: float = 0.6
    n_frictions: int = 21

    @classmethod
    def from_dict(cls, cfg: dict[str, Any]) -> TableGrid:
        return cls(
            speed_min=cfg["speeds"]["min"], speed_max=cfg["speeds"]["max"], n_speeds=cfg["speeds"]["n"],
            mass_min=cfg["masses"]["min"], mass_max=cfg["masses"]["max"], n_masses=cfg["masses"]["n"],
            friction_min=cfg["frictions"]["min"], friction_max=cfg["frictions"]["max"],
            n_frictions=cfg["frictions"]["n"],
        )  # fmt: skip

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
    log_d_raw: np.ndarray | None = None

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

    def log_displacement(self, speeds, masses, frictions) -> np.ndarray:
        """Interpolated log d at scattered points (broadcast together)."""
        v, m, mu = np.broadcast_arrays(
            np.asarray(speeds, float), np.asarray(masses, float), np.asarray(frictions, float)
        )
        self.check_range(v, m, mu)
        pts = np.stack([v.ravel(), np.log(m).ravel(), np.log(mu).ravel()], axis=-1)
        return self._interpolator(pts).reshape(v.shape)

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
            speeds=self.speeds, masses=self.masses, frictions=self.frictions, log_d=self.log_d,
            meta=np.array(json.dumps(self.meta, sort_keys=True)),
        )  # fmt: skip
        if self.log_d_raw is not None:
            arrays["log_d_raw"] = self.log_d_raw
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
                raw = z["log_d_raw"] if "log_d_raw" in z.files else None
                return cls(
                    speeds=z["speeds"].astype(float), masses=z["masses"].astype(float),
                    frictions=z["frictions"].astype(float), log_d=z["log_d"].astype(float),
                    meta=meta, log_d_raw=raw,
                )  # fmt: skip
        except TableError:
            raise
        except Exception as exc:  # zip, pickle or JSON errors: all mean "not a table"
            raise TableError(f"cannot read table {path}: {exc}") from exc


def monotone_projection(log_d: np.ndarray, max_passes: int = 100) -> tuple[np.ndarray, int]:
    """Project log_d onto tables non-decreasing in speed and non-increasing in friction.

    Alternates isotonic regressions along the two axes until neither changes anything.
    Returns the projected table and the number of passes used.
    """
    out = np.array(log_d, dtype=float)
    for passes in range(1, max_passes + 1):
        before = out.copy()
        for j in range(out.shape[1]):
            for k in range(out.shape[2]):
                out[:, j, k] = isotonic_regression(out[:, j, k], increasing=True).x
        for i in range(out.shape[0]):
            for j in range(out.shape[1]):
                out[i, j, :] = isotonic_regression(out[i, j, :], increasing=False).x
        if np.array_equal(before, out):
            return out, passes
    return out, max_passes


def config_digest(obj: Any) -> str:
    """Short stable hash of a JSON-able config subset."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True).encode()).hexdigest()[:16]


def build_table(scene: SceneConfig, grid: TableGrid, *, nthread: int = 0, progress: bool = False) -> PushTable:
    """Simulate every (speed, mass, friction) cell with the canonical box and tabulate log d."""
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
    raw = np.log(result.displacement.reshape(v.shape))
    raw_violations = int((np.diff(raw, axis=0) <= 0).sum() + (np.diff(raw, axis=2) >= 0).sum())
    projected, passes = monotone_projection(raw)
    meta = {
        "scene": scene.to_dict(),
        "grid": grid.__dict__,
        "mujoco_version": mujoco.__version__,
        "config_digest": config_digest({"scene": scene.to_dict(), "grid": grid.__dict__}),
        "monotone_projection": {
            "raw_violations": raw_violations,
            "passes": passes,
            "max_abs_change": float(np.abs(projected - raw).max()),
            "rms_change": float(np.sqrt(np.mean((projected - raw) ** 2))),
        },
        "displacement_range_m": [float(np.exp(raw.min())), float(np.exp(raw.max()))],
    }
    log.info("table built: %s", meta["monotone_projection"])
    return PushTable(speeds, masses, frictions, projected, meta=meta, log_d_raw=raw)
