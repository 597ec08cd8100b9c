"""Effect tables: how each tabulated effect changes log d, on a coarse grid, cached on disk.

For a ``model`` effect (:mod:`imply.sim.effects`) at level s, the table holds
Delta(v, m, mu; s) = log d_effect - log d_baseline on a coarse (speed, mass, friction)
grid spanning the baseline table's range, simulated with the same scene (the baseline
table's ``meta['scene']``) and the same batched simulator. The augmented model is the
baseline table plus Delta: cubic in (v, log m, log mu) on the coarse grid, linear in s
between the tabulated levels (0 is a level with Delta = 0). Differencing two runs of
the same simulator on the same grid cancels most of its solver jitter, and Delta is
smooth, so a coarse grid carries it: 7 x 6 x 6 cells per level cost about a second.

Tables are cached per effect key as ``effects-<key>-<digest>.npz`` in a cache folder,
the digest covering the scene, the coarse grid, the key's levels, MuJoCo's version and
the baseline table's own digest; a changed setting builds a new file. The build also measures the
baseline table's own accuracy (:func:`model_floor`: its interpolation error combined with
the simulator's numerical error that the table file records), which the diagnostic uses
as the smallest gap it will attribute to an effect.
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import ClassVar

import mujoco
import numpy as np
from scipy.interpolate import RegularGridInterpolator
from tqdm.auto import tqdm

from imply.io import write_json, write_npz
from imply.options import Config
from imply.sim.effects import MODEL, Effect, effect_model
from imply.sim.pushes import simulate_pushes
from imply.sim.scene import SceneConfig
from imply.table import PushTable, config_digest

log = logging.getLogger("imply.diagnose")


@dataclass(frozen=True, kw_only=True)
class CoarseGrid(Config):
    """Points per axis of the effect tables (config ``gap.effect_grid``)."""

    config_key: ClassVar[str] = "gap.effect_grid"

    n_speeds: int = 7
    n_masses: int = 6
    n_frictions: int = 6

    def __post_init__(self) -> None:
        if min(self.n_speeds, self.n_masses, self.n_frictions) < 4:
            raise ValueError("effect tables need at least 4 points per axis (cubic interpolation)")

    def axes(self, table: PushTable) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        (v0, v1), (m0, m1), (u0, u1) = table.speed_range, table.mass_range, table.friction_range
        return (
            np.linspace(v0, v1, self.n_speeds),
            np.geomspace(m0, m1, self.n_masses),
            np.geomspace(u0, u1, self.n_frictions),
        )


def table_levels(effects: list[Effect]) -> dict[str, tuple[float, ...]]:
    """Tabulated levels per table key (effects sharing a key share its levels)."""
    out: dict[str, set[float]] = {}
    for e in effects:
        if e.kind == MODEL:
            out.setdefault(e.table_key, set()).update(float(x) for x in e.levels)
    return {k: tuple(sorted(v | {0.0})) for k, v in sorted(out.items())}


@dataclass(frozen=True)
class EffectTables:
    """Delta tables per key: ``levels[key]`` (L,), ``deltas[key]`` (L, nv, nm, nu)."""

    axes: tuple[np.ndarray, np.ndarray, np.ndarray]
    levels: dict[str, np.ndarray]
    deltas: dict[str, np.ndarray]
    meta: dict

    @cached_property
    def _interp(self) -> dict[str, list[RegularGridInterpolator]]:
        v, m, u = self.axes
        pts = (v, np.log(m), np.log(u))
        return {k: [RegularGridInterpolator(pts, d, method="cubic") for d in self.deltas[k]] for k in self.deltas}

    def delta(self, key: str, v, m, mu, s) -> np.ndarray:
        """Delta log d at points (v, m, mu) with per-point level s (clipped to the tabulated range)."""
        levels = self.levels[key]
        v, m, mu, s = np.broadcast_arrays(*(np.asarray(x, float) for x in (v, m, mu, s)))
        s = np.clip(s, levels[0], levels[-1])
        j = np.clip(np.searchsorted(levels, s, side="right") - 1, 0, levels.size - 2)
        w = (s - levels[j]) / (levels[j + 1] - levels[j])
        pts = np.stack([v.ravel(), np.log(m).ravel(), np.log(mu).ravel()], axis=-1)
        out = np.zeros(v.size)
        jr, wr = j.ravel(), w.ravel()
        for lev, interp in enumerate(self._interp[key]):
            # weight of level `lev` for each point (linear blend of the two bracketing levels)
            wt = np.where(jr == lev, 1.0 - wr, 0.0) + np.where(jr + 1 == lev, wr, 0.0)
            used = wt != 0
            if used.any() and np.any(self.deltas[key][lev] != 0):
                out[used] += wt[used] * interp(pts[used])
        return out.reshape(v.shape)


def model_floor(table: PushTable, scene: SceneConfig, n: int = 200, seed: int = 0, nthread: int = 0) -> dict:
    """The table's own accuracy as a model of real pushes, RMS log d, and its two parts.

    interpolation_rms: simulated minus interpolated log d at random off-grid pushes (the
      same simulator, so this is the interpolation's error alone);
    numerical_rms: the simulator's own error against a much finer reference, as measured
      when the table was built (``meta['numerical_error']``, see
      :func:`imply.table.check_table`); 0 with a warning if the table has none;
    rms: the two combined in quadrature. An effect that changes log d by less than this
      cannot be told from the table's error, so the diagnostic does not attribute gaps
      that small.
    """
    rng = np.random.default_rng(seed)
    (v0, v1), (m0, m1), (u0, u1) = table.speed_range, table.mass_range, table.friction_range
    v = rng.uniform(v0, v1, n)
    m = np.exp(rng.uniform(np.log(m0), np.log(m1), n))
    mu = np.exp(rng.uniform(np.log(u0), np.log(u1), n))
    res = simulate_pushes(v, m, mu, scene=scene, nthread=nthread)
    ok = res.ok & (res.displacement > 0)
    err = np.log(res.displacement[ok]) - table.log_displacement(v[ok], m[ok], mu[ok])
    interpolation = float(np.sqrt(np.mean(err**2)))
    measured = table.meta.get("numerical_error") or {}
    numerical = measured.get("rms_log_d")
    if numerical is None:
        log.warning("the table records no measured numerical error; the model floor counts interpolation only")
    combined = float(np.hypot(interpolation, numerical or 0.0))
    return {"rms": combined, "interpolation_rms": interpolation, "numerical_rms": numerical}


def _digest(table: PushTable, grid: CoarseGrid, extra: dict) -> tuple[str, dict]:
    meta = {
        "scene": table.meta.get("scene", SceneConfig().to_dict()),
        "coarse_grid": grid.to_dict(),
        "mujoco_version": mujoco.__version__,
        "baseline": table.meta.get("config_digest", config_digest(table.log_d.round(6).tolist())),
        "ranges": [table.speed_range, table.mass_range, table.friction_range],
        **extra,
    }
    return config_digest(meta), meta


def load_or_build(
    table: PushTable,
    effects: list[Effect],
    grid: CoarseGrid,
    cache_dir: str | os.PathLike | None,
    *,
    nthread: int = 0,
    progress: bool = False,
) -> EffectTables:
    """The effect tables for ``effects`` against ``table``, from the cache or simulated.

    Each table key is cached in its own file (``effects-<key>-<digest>.npz``) and the
    table's model floor in ``floor-<digest>.json``, so any subset of the library reuses
    what was built before.
    """
    levels = table_levels(effects)
    axes = grid.axes(table)
    cache = Path(cache_dir) if cache_dir else None
    scene = SceneConfig.from_dict(table.meta.get("scene", SceneConfig().to_dict()))
    v, m, mu = (x.ravel() for x in np.meshgrid(*axes, indexing="ij"))
    shape = tuple(a.size for a in axes)
    base: np.ndarray | None = None
    deltas: dict[str, np.ndarray] = {}
    meta: dict = {"keys": {}}
    todo = []
    for key, lv in levels.items():
        digest, kmeta = _digest(table, grid, {"key": key, "levels": list(lv)})
        path = cache / f"effects-{key}-{digest}.npz" if cache else None
        if path is not None and path.is_file():
            with np.load(path, allow_pickle=False) as z:
                deltas[key] = z["delta"]
                meta["keys"][key] = json.loads(str(z["meta"]))
        else:
            todo.append((key, lv, path, kmeta))
    if todo:
        log.info(
            "building effect tables for %s (%d cells per level) in %s", ", ".join(k for k, *_ in todo), v.size, cache
        )
        base = np.log(simulate_pushes(v, m, mu, scene=scene, nthread=nthread).displacement).reshape(shape)
        bar = tqdm(total=sum(len(lv) - 1 for _, lv, _, _ in todo), desc="effect tables", unit="level",
                   disable=not progress, leave=False)  # fmt: skip
        for key, lv, path, kmeta in todo:
            rows, failed = [], {}
            for s in lv:
                if s == 0.0:
                    rows.append(np.zeros(shape))
                    continue
                res = simulate_pushes(v, m, mu, model=effect_model(scene, key, s), nthread=nthread)
                failed[f"{s:g}"] = int((~res.ok).sum())
                rows.append(np.log(np.maximum(res.displacement, 1e-6)).reshape(shape) - base)
                bar.update(1)
            deltas[key] = np.stack(rows)
            meta["keys"][key] = {**kmeta, "failed_cells": failed}
            if path is not None:
                write_npz(path, delta=deltas[key], meta=np.array(json.dumps(meta["keys"][key], sort_keys=True)))
        bar.close()
    digest, fmeta = _digest(
        table,
        CoarseGrid(),
        {"model_floor": {"n": 200, "seed": 0}, "numerical_error": table.meta.get("numerical_error")},
    )
    fpath = cache / f"floor-{digest}.json" if cache else None
    if fpath is not None and fpath.is_file():
        with open(fpath) as fh:
            floor = json.load(fh)["model_floor"]
    else:
        floor = model_floor(table, scene, nthread=nthread)
        if fpath is not None:
            write_json(fpath, {**fmeta, "model_floor": floor})
    meta["model_floor_rms"] = floor["rms"]
    meta["model_floor"] = floor
    return EffectTables(axes=axes, levels={k: np.array(v) for k, v in levels.items()}, deltas=deltas, meta=meta)
