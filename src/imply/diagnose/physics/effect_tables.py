"""Effect tables: how each tabulated effect changes log d and log stop time, on a coarse grid, cached on disk.

For a ``model`` effect (:mod:`imply.sim.effects`) at level s, the table holds
Delta(v, m, mu; s) = log d_effect - log d_baseline on a coarse (speed, mass, friction)
grid spanning the baseline table's range, simulated with the same scene (the baseline
table's ``meta['scene']``) and the same batched simulator (:func:`imply.sim.pushes.run_pushes`);
and the same for log stop time. The augmented model is the baseline plus Delta: cubic in
(v, log m, log mu) on the coarse grid, linear in s between the tabulated levels (0 is a
level with Delta = 0). Differencing two runs of the same simulator on the same grid
cancels most of its solver jitter, and Delta is smooth, so a coarse grid carries it.

Besides the library's keys, the diagnostic tabulates ``slope_across``: the table sloping
across the push (gravity tilted toward the scene's +y), which a tilt in any direction
other than along the push brings (the diagnostic's ``tilt`` candidate uses both).

Observables beside the displacement (:data:`AUX`): log stop time, log of the pusher's
mean speed over its stroke (what a robot's encoders give) and log of the times at which the
box covers fractions of its travel (what a camera's track gives; :mod:`imply.sim.track`). The push
table holds displacements only, so their baselines, f_a(v, m, mu), are tabulated here too,
on their own grid (:class:`CoarseGrid` ``stop_*``), and every effect table carries each
effect's change of them beside its change of log d. A push's stop time is when the box's
speed in the table plane falls below :data:`STOP_SPEED` (measured from the start of the
push), read from the box's positions recorded every millisecond (speeds from successive
positions, the crossing interpolated). MuJoCo's soft contacts end a slide in an exponential tail
of a few milliseconds, in which a lower threshold's crossing would move with every
numerical detail.

Tables are cached per effect key as ``effects-<key>-<digest>.npz`` in a cache folder,
the digest covering the scene, the coarse grid, the key's levels, MuJoCo's version and
the baseline table's own digest; a changed setting builds a new file. The build also
measures the model's own accuracy (:func:`model_floor`: for displacement, the baseline
table's interpolation error combined with the simulator's numerical error that the table
file records; for stop time, the stop-time table's interpolation error combined with the
simulator's own convergence, measured against a run at a quarter of the scene's
timestep; the same for the pusher's speed), which the diagnostic uses as the smallest gap it will
attribute to an effect.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import ClassVar

import mujoco
import numpy as np
from mujoco import batch as mjbatch
from scipy.interpolate import RegularGridInterpolator
from tqdm.auto import tqdm

from imply.diagnose.inputs.pushlog import TRACK_OBSERVABLES
from imply.io import write_json, write_npz
from imply.options import Config, option
from imply.sim.effects import MODEL, Effect, effect_spec
from imply.sim.pushes import run_pushes
from imply.sim.scene import SceneConfig, build_model
from imply.sim.track import STOP_HORIZON, STOP_SPEED, crossing_times, pusher_speed, stop_frame_times, stop_times
from imply.table import PushTable, config_digest, spline_columns, spline_of

log = logging.getLogger("imply.diagnose")

# bump when the files' content changes meaning
FORMAT = 5

# the observables beside log d that the tables hold, in the order of their last axis: log stop
# time, log of the pusher's mean speed over the stroke, and log of the times the box takes to
# cover fractions of its travel (imply.sim.track; named as the push log names them)
AUX = ("stop_time", "pusher_speed", *TRACK_OBSERVABLES)

# tabulated keys the diagnostic adds to the library's scene edits
ACROSS = "slope_across"
ACROSS_LEVELS = (0.005, 0.015, 0.03)


def _slope_across(spec: mujoco.MjSpec, s: float) -> None:
    # the table slopes down by angle s toward the scene's +y, across the push
    g = float(np.linalg.norm(np.array(spec.option.gravity, float)))
    spec.option.gravity = [0.0, g * np.sin(s), -g * np.cos(s)]


@dataclass(frozen=True, kw_only=True)
class CoarseGrid(Config):
    """Points per axis of the effect tables and of the stop-time table (config ``gap.effect_grid``)."""

    config_key: ClassVar[str] = "gap.effect_grid"

    n_speeds: int = option(7, doc="speeds of the effect tables", minimum=4)
    n_masses: int = option(6, doc="masses of the effect tables", minimum=4)
    n_frictions: int = option(6, doc="frictions of the effect tables", minimum=4)
    stop_speeds: int = option(10, doc="speeds of the stop-time table", minimum=4)
    stop_masses: int = option(8, doc="masses of the stop-time table", minimum=4)
    stop_frictions: int = option(8, doc="frictions of the stop-time table", minimum=4)
    floor_pushes: int = option(200, doc="random pushes that measure the model's own accuracy", minimum=4)

    def axes(self, table: PushTable, stop: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        (v0, v1), (m0, m1), (u0, u1) = table.speed_range, table.mass_range, table.friction_range
        nv, nm, nu = (
            (self.stop_speeds, self.stop_masses, self.stop_frictions)
            if stop
            else (self.n_speeds, self.n_masses, self.n_frictions)
        )
        return np.linspace(v0, v1, nv), np.geomspace(m0, m1, nm), np.geomspace(u0, u1, nu)


def table_levels(effects: list[Effect], across: bool = False) -> dict[str, tuple[float, ...]]:
    """Tabulated levels per table key (effects sharing a key share its levels)."""
    out: dict[str, set[float]] = {}
    for e in effects:
        if e.kind == MODEL:
            out.setdefault(e.table_key, set()).update(float(x) for x in e.levels)
    if across:
        out.setdefault(ACROSS, set()).update(ACROSS_LEVELS)
    return {k: tuple(sorted(v | {0.0})) for k, v in sorted(out.items())}


def _spec_model(scene: SceneConfig, key: str, value: float) -> mujoco.MjModel:
    if key == ACROSS:
        spec = effect_spec(scene, "slope", 0.0)
        if value != 0.0:
            _slope_across(spec, float(value))
        return spec.compile()
    return effect_spec(scene, key, value).compile()


@dataclass(frozen=True)
class PushObservables:
    """log displacement and log stop time of n pushes (NaN where the push failed); beside them what a robot
    records: log of the pusher's mean speed over the stroke (n,) and log of the times the box takes to cover
    :data:`imply.sim.track.FRACTIONS` of its displacement (n, Q)."""

    log_d: np.ndarray
    log_t: np.ndarray
    ok: np.ndarray
    log_p: np.ndarray | None = None
    log_tq: np.ndarray | None = None


def simulate_observables(
    model: mujoco.MjModel, speeds, masses, frictions, *, nthread: int = 0, max_frame_time: float | None = None
) -> PushObservables:
    """log d and log stop time of pushes on ``model`` (the table's simulator, positions recorded every ms)."""
    speeds, masses, frictions = (np.asarray(x, float).ravel() for x in (speeds, masses, frictions))
    n = speeds.size
    batch = mjbatch.Batch(model, n, nthread=nthread)
    box = model.body("box").id
    batch.body("box").mass = masses[:, None]
    batch.body("box").inertia = model.body_inertia[box][None, :] * (masses / float(model.body_mass[box]))[:, None]
    fr = np.tile(model.geom_friction[model.geom("box").id], (n, 1))
    fr[:, 0] = frictions
    batch.geom("box").friction = fr
    batch.set_const()
    # slides in the table's range last about a second; a push still sliding at the last
    # frame has no stop time (NaN)
    end = (
        max_frame_time
        if max_frame_time is not None
        else min(STOP_HORIZON, float(np.asarray(model.numeric("max_time").data)[0]))
    )
    run = run_pushes(batch, model, speeds, frame_times=stop_frame_times(end))
    res = run.result
    t = stop_times(run.frames_box_qpos[:, :, :2], run.frames_time)
    ok = res.ok & np.isfinite(t) & (res.displacement > 0)
    log_d = np.where(ok, np.log(np.maximum(res.displacement, 1e-9)), np.nan)
    log_t = np.where(ok, np.log(np.where(np.isfinite(t) & (t > 0), t, 1.0)), np.nan)
    stroke = float(np.asarray(model.numeric("stroke").data)[0])
    with np.errstate(invalid="ignore", divide="ignore"):
        log_p = np.where(ok, np.log(pusher_speed(stroke, res.stroke_time)), np.nan)
        travel = run.frames_box_qpos[:, :, 0] - run.frames_box_qpos[:, :1, 0]
        tq = crossing_times(run.frames_time, travel, res.displacement)
        log_tq = np.where(ok[:, None] & (tq > 0), np.log(tq), np.nan)
    return PushObservables(log_d, log_t, ok, log_p, log_tq)


def aux_values(obs: PushObservables) -> np.ndarray:
    """(n, K) the observables of :data:`AUX` of simulated pushes."""
    return np.concatenate([obs.log_t[:, None], obs.log_p[:, None], obs.log_tq], -1)


def _fill(values: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """Reshape to the grid, filling failed cells (NaN) from their nearest finite neighbour along speed."""
    if values.ndim == 2:  # (n, K): each observable on its own
        return np.stack([_fill(values[:, a], shape) for a in range(values.shape[1])], -1)
    grid = values.reshape(shape).copy()
    bad = ~np.isfinite(grid)
    if bad.any():
        idx = np.argwhere(bad)
        good = np.argwhere(~bad)
        for i, j, k in idx:
            d = np.abs(good - np.array([i, j, k])).sum(1)
            gi = good[np.argmin(d)]
            grid[i, j, k] = grid[tuple(gi)]
    return grid


def _points(axes, v, m, mu) -> tuple[np.ndarray, tuple[int, ...]]:
    """(n, 3) interpolation points (v, log m, log mu) clipped to ``axes``, and the broadcast shape."""
    v, m, mu = np.broadcast_arrays(*(np.asarray(x, float) for x in (v, m, mu)))
    pts = np.stack(
        [
            np.clip(v.ravel(), axes[0][0], axes[0][-1]),
            np.clip(np.log(m).ravel(), np.log(axes[1][0]), np.log(axes[1][-1])),
            np.clip(np.log(mu).ravel(), np.log(axes[2][0]), np.log(axes[2][-1])),
        ],
        -1,
    )
    return pts, v.shape


@dataclass(frozen=True)
class EffectTables:
    """Delta tables per key: ``levels[key]`` (L,), ``deltas[key]`` (L, nv, nm, nu) on log d and
    ``deltas_t[key]`` (L, nv, nm, nu, K) on the K observables :data:`AUX` beside it; their baseline
    ``aux_base`` (nv', nm', nu', K) on ``aux_axes`` (None: the tables hold log d alone)."""

    axes: tuple[np.ndarray, np.ndarray, np.ndarray]
    levels: dict[str, np.ndarray]
    deltas: dict[str, np.ndarray]
    meta: dict
    deltas_t: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    aux_axes: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    aux_base: np.ndarray | None = None

    @property
    def aux(self) -> tuple[str, ...]:
        """The observables beside log d these tables hold (:data:`AUX`, or none)."""
        return AUX if self.aux_base is not None else ()

    def aux_index(self, name: str) -> int:
        return self.aux.index(name)

    @cached_property
    def _interp(self) -> dict[str, Callable[[np.ndarray], np.ndarray]]:
        """One interpolator per key over every level of every observable (values (nv, nm, nu, (1 + K) L))."""
        v, m, u = self.axes
        pts = (v, np.log(m), np.log(u))
        out = {}
        for k, d in self.deltas.items():
            parts = [d]
            dt = self.deltas_t.get(k)
            if dt is not None and self.aux:
                parts += [dt[..., a] for a in range(dt.shape[-1])]
            stacked = np.moveaxis(np.concatenate(parts), 0, -1)
            out[k] = spline_of(RegularGridInterpolator(pts, stacked, method="cubic"))
        return out

    @cached_property
    def _aux_interp(self) -> RegularGridInterpolator | None:
        if self.aux_base is None or self.aux_axes is None:
            return None
        v, m, u = self.aux_axes
        return RegularGridInterpolator(
            (v, np.log(m), np.log(u)), self.aux_base, method="cubic", solver_args={"atol": 1e-12, "rtol": 1e-12}
        )

    @cached_property
    def _aux_linear(self) -> RegularGridInterpolator | None:
        if self.aux_base is None or self.aux_axes is None:
            return None
        v, m, u = self.aux_axes
        return RegularGridInterpolator((v, np.log(m), np.log(u)), self.aux_base, method="linear")

    def aux_interpolation_indicator(self, v, m, mu) -> np.ndarray:
        """(..., K) |cubic - linear| interpolation of the observables' baseline: where it is unsure."""
        pts, shape = _points(self.aux_axes, v, m, mu)
        return np.abs(self._aux_interp(pts) - self._aux_linear(pts)).reshape(*shape, -1)

    def relative_error(self, key: str, which: str = "d") -> float:
        """The key's table error relative to the effect's size on log d (``'d'``) or on an observable of
        :attr:`aux`, as measured when it was built (0 if not)."""
        acc = (self.meta.get("keys", {}).get(key) or {}).get("accuracy") or {}
        return float((acc.get("log_d" if which == "d" else which) or {}).get("relative", 0.0))

    def aux_log(self, v, m, mu) -> np.ndarray:
        """(..., K) the observables' baseline (log stop time, log pusher speed) at points (v, m, mu), clipped."""
        interp = self._aux_interp
        if interp is None:
            raise ValueError("these effect tables hold no observables beside log d")
        pts, shape = _points(self.aux_axes, v, m, mu)
        return self._aux_spline(pts).reshape(*shape, -1)

    @cached_property
    def _aux_spline(self) -> Callable[[np.ndarray], np.ndarray]:
        return spline_of(self._aux_interp)

    @cached_property
    def _column_splines(self) -> dict[tuple, Callable[[np.ndarray], np.ndarray]]:
        """The splines :meth:`aux_log_at` and :meth:`read_levels` read, restricted to the columns asked for, built
        once per request and shared by every problem on these tables (a few hundred over a benchmark's logs)."""
        return {}

    @cached_property
    def _bounds(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """(3,) lower and upper bounds of (v, log m, log mu) of the effect tables' axes (``"effects"``) and the
        observables' baseline axes (``"aux"``): where :func:`_points` clips."""
        out = {}
        for name, axes in (("effects", self.axes), ("aux", self.aux_axes)):
            if axes is not None:
                v, m, mu = axes
                lo = np.array([v[0], np.log(m[0]), np.log(mu[0])])
                hi = np.array([v[-1], np.log(m[-1]), np.log(mu[-1])])
                out[name] = (lo, hi)
        return out

    def aux_log_at(self, pts: np.ndarray, cols: tuple[int, ...]) -> np.ndarray:
        """(n, len(cols)) the observables ``cols`` (indices into :attr:`aux`) of the baseline at points ``pts``
        (n, 3) of (v, log m, log mu), clipped to the axes: :meth:`aux_log`'s values, read for those columns alone."""
        spline = self._column_splines.get(("aux", cols))
        if spline is None:
            spline = self._column_splines[("aux", cols)] = spline_columns((self._aux_spline, list(cols)))
        lo, hi = self._bounds["aux"]
        return spline(np.minimum(np.maximum(pts, lo), hi))

    def effect_points(self, pts: np.ndarray) -> np.ndarray:
        """Points (n, 3) of (v, log m, log mu) clipped to the effect tables' axes, for :meth:`read_levels`."""
        lo, hi = self._bounds["effects"]
        return np.minimum(np.maximum(pts, lo), hi)

    def read_levels(self, reads: tuple[tuple[str, tuple[int, ...]], ...], pts: np.ndarray, cols: tuple[int, ...]):
        """(n, sum over reads of (1 + K) l) the tabulated values of each ``(key, levels)`` of ``reads`` (l level
        indices, ascending) at points ``pts`` (n, 3) inside :attr:`axes`: log d at those levels, then each observable
        of ``cols`` (K indices into :attr:`aux`) at them, side by side in one pass (the tables share their grid). The
        same values as :meth:`level_values`' columns: a prediction reads the levels its points' levels fall between,
        not every tabulated one."""
        spline = self._column_splines.get((reads, cols))
        if spline is None:
            parts = []
            for key, levels in reads:
                L = self.levels[key].size
                parts.append(
                    (self._interp[key], [L * part + level for part in (0, *(1 + a for a in cols)) for level in levels])
                )
            spline = self._column_splines[(reads, cols)] = spline_columns(*parts)
        return spline(pts)

    def delta_both(self, key: str, v, m, mu, s) -> tuple[np.ndarray, np.ndarray]:
        """Delta log d (...) and Delta of every observable of :attr:`aux` (..., K) at points (v, m, mu)
        with per-point level s (clipped to the tabulated range; linear between the two bracketing levels)."""
        v, m, mu, s = np.broadcast_arrays(*(np.asarray(x, float) for x in (v, m, mu, s)))
        pts, shape = _points(self.axes, v, m, mu)
        d, t = self.mix_levels(key, self.level_values(key, pts), s.ravel())
        return d.reshape(shape), t.reshape(*shape, t.shape[-1])

    def level_values(self, key: str, pts: np.ndarray) -> np.ndarray:
        """(n, (1 + K) L) every tabulated level of log d and of the K observables at interpolation points
        ``pts`` (n, 3) of (v, log m, log mu) inside :attr:`axes` (clipped as :meth:`delta_both` clips)."""
        return self._interp[key](pts)

    def points(self, v, m, mu) -> np.ndarray:
        """(n, 3) the interpolation points of :meth:`level_values` for flat v, m, mu (n,), clipped to the axes."""
        return _points(self.axes, v, m, mu)[0]

    def mix_levels(self, key: str, vals: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Delta log d (n,) and Delta of every observable (n, K) at per-point levels ``s`` (n,) (clipped to the
        tabulated range; linear between the two bracketing levels) from :meth:`level_values`' ``vals``."""
        lower, weight = self.brackets(key, s)
        return mix_between(vals, lower, weight, self.levels[key].size)

    def brackets(self, key: str, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each point's bracketing levels of ``key`` at its level ``s`` (n,), clipped to the tabulated range: the lower
        level's index (n,) and the upper level's weight (n,)."""
        levels = self.levels[key]
        s = np.minimum(np.maximum(s, levels[0]), levels[-1])
        j = np.minimum(np.maximum(np.searchsorted(levels, s, side="right") - 1, 0), levels.size - 2)
        return j, (s - levels[j]) / (levels[j + 1] - levels[j])

    def delta(self, key: str, v, m, mu, s, which: str = "d") -> np.ndarray:
        """Delta log d (``which='d'``) or of the observable ``which`` of :attr:`aux`, see :meth:`delta_both`."""
        d, t = self.delta_both(key, v, m, mu, s)
        return d if which == "d" else t[..., self.aux_index(which)]


def mix_between(
    vals: np.ndarray, lower: np.ndarray, weight: np.ndarray, n_levels: int
) -> tuple[np.ndarray, np.ndarray]:
    """Delta log d (n,) and Delta of each observable (n, K), linear between two levels, from ``vals`` (n, (1 + K)
    n_levels) (log d at ``n_levels`` levels, then each observable at them): the points' lower levels' positions
    ``lower`` (n,) among those (the upper ones next) and the upper levels' weights ``weight`` (n,)."""
    n = lower.size
    by_level = vals.reshape(n, -1, n_levels)
    rows = np.arange(n)
    both = (1.0 - weight[:, None]) * by_level[rows, :, lower] + weight[:, None] * by_level[rows, :, lower + 1]
    return both[:, 0], both[:, 1:]


CHECK_PUSHES = 24  # off-grid pushes per key for its table's accuracy


def _key_accuracy(scene, key, levels, axes, delta, delta_t, pushes, base: PushObservables, nthread: int) -> dict:
    """A key's table against off-grid pushes midway between its levels: error relative to the effect's size."""
    v, m, mu = pushes
    # midway between tabulated levels, where the interpolation in level is least sure
    mids = 0.5 * (levels[1:] + levels[:-1])
    s = mids[np.arange(v.size) % mids.size]
    obs_d, obs_t = np.full(v.size, np.nan), np.full((v.size, len(AUX)), np.nan)
    for lev in np.unique(np.round(s, 12)):
        sel = np.round(s, 12) == lev
        res = simulate_observables(_spec_model(scene, key, float(lev)), v[sel], m[sel], mu[sel], nthread=nthread)
        obs_d[sel], obs_t[sel] = res.log_d - base.log_d[sel], aux_values(res) - aux_values(base)[sel]
    tmp = EffectTables(
        axes=axes,
        levels={key: levels},
        deltas={key: delta},
        meta={},
        deltas_t={key: delta_t},
        aux_axes=axes,
        aux_base=np.zeros((*delta.shape[1:], len(AUX))),
    )
    out = {}
    for name, obs, which in (("log_d", obs_d, "d"), *((a, obs_t[:, i], a) for i, a in enumerate(AUX))):
        pred = tmp.delta(key, v, m, mu, s, which)
        ok = np.isfinite(obs)
        size = float(np.sqrt(np.mean(obs[ok] ** 2))) if ok.any() else 0.0
        err = float(np.sqrt(np.mean((obs[ok] - pred[ok]) ** 2))) if ok.any() else 0.0
        out[name] = {"rms_error": err, "rms_effect": size, "relative": err / size if size > 0 else 0.0}
    return out


def _random_pushes(table: PushTable, n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    (v0, v1), (m0, m1), (u0, u1) = table.speed_range, table.mass_range, table.friction_range
    return (
        rng.uniform(v0, v1, n),
        np.exp(rng.uniform(np.log(m0), np.log(m1), n)),
        np.exp(rng.uniform(np.log(u0), np.log(u1), n)),
    )


def model_floor(
    table: PushTable,
    scene: SceneConfig,
    stop: EffectTables | None = None,
    n: int = 200,
    seed: int = 0,
    nthread: int = 0,
) -> dict:
    """The model's own accuracy as a model of real pushes (RMS), per observable, and its parts.

    interpolation_rms: simulated minus interpolated log d at random off-grid pushes (the
      same simulator, so this is the interpolation's error alone);
    numerical_rms: the simulator's own error against a much finer reference, as measured
      when the table was built (``meta['numerical_error']``, see
      :func:`imply.table.check_table`); 0 with a warning if the table has none;
    rms: the two combined in quadrature. An effect that changes log d by less than this
      cannot be told from the table's error, so the diagnostic does not attribute gaps
      that small.
    stop_time, pusher_speed: the same for each observable beside log d against its table, its
      numerical part the change of 40 of those pushes' values at a quarter of the scene's timestep.
    """
    v, m, mu = _random_pushes(table, n, seed)
    model = build_model(scene)
    obs = simulate_observables(model, v, m, mu, nthread=nthread)
    ok = obs.ok
    err = obs.log_d[ok] - table.log_displacement(v[ok], m[ok], mu[ok])
    interpolation = float(np.sqrt(np.mean(err**2)))
    measured = table.meta.get("numerical_error") or {}
    numerical = measured.get("rms_log_d")
    if numerical is None:
        log.warning("the table records no measured numerical error; the model floor counts interpolation only")
    combined = float(np.hypot(interpolation, numerical or 0.0))
    out = {"rms": combined, "interpolation_rms": interpolation, "numerical_rms": numerical}
    if stop is not None and stop.aux:
        values = aux_values(obs)
        err_t = values[ok] - stop.aux_log(v[ok], m[ok], mu[ok])
        k = min(40, n)
        finer = dataclasses.replace(scene, timestep=scene.timestep / 4)
        fine = simulate_observables(build_model(finer), v[:k], m[:k], mu[:k], nthread=nthread)
        both = ok[:k] & fine.ok
        fine_values = aux_values(fine)
        for a, name in enumerate(stop.aux):
            interp_t = float(np.sqrt(np.mean(err_t[:, a] ** 2)))
            diff = values[:k][both, a] - fine_values[both, a]
            num_t = float(np.sqrt(np.mean(diff**2))) if both.any() else 0.0
            out[name] = {"rms": float(np.hypot(interp_t, num_t)), "interpolation_rms": interp_t, "numerical_rms": num_t}
        out["stop_time"]["stop_speed"] = STOP_SPEED
    return out


def _digest(table: PushTable, grid: CoarseGrid, extra: dict) -> tuple[str, dict]:
    meta = {
        "format": FORMAT,
        "scene": table.meta.get("scene", SceneConfig().to_dict()),
        "coarse_grid": {k: getattr(grid, k) for k in ("n_speeds", "n_masses", "n_frictions")},
        "mujoco_version": mujoco.__version__,
        "baseline": table.meta.get("config_digest", config_digest(table.log_d.round(6).tolist())),
        "ranges": [table.speed_range, table.mass_range, table.friction_range],
        "stop_speed": STOP_SPEED,
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
    across: bool = False,
    aux: bool = True,
) -> EffectTables:
    """The effect tables for ``effects`` against ``table``, from the cache or simulated.

    Each table key is cached in its own file (``effects-<key>-<digest>.npz``), the stop-time
    baseline in ``stoptime-<digest>.npz`` and the model floor in ``floor-<digest>.json``, so
    any subset of the library reuses what was built before. ``across``: also tabulate the
    slope across the push (for the ``tilt`` candidate).
    """
    levels = table_levels(effects, across=across)
    axes = grid.axes(table)
    cache = Path(cache_dir) if cache_dir else None
    scene = SceneConfig.from_dict(table.meta.get("scene", SceneConfig().to_dict()))
    v, m, mu = (x.ravel() for x in np.meshgrid(*axes, indexing="ij"))
    shape = tuple(a.size for a in axes)
    deltas: dict[str, np.ndarray] = {}
    deltas_t: dict[str, np.ndarray] = {}
    meta: dict = {"keys": {}, "stop_speed": STOP_SPEED}
    todo = []
    for key, lv in levels.items():
        digest, kmeta = _digest(table, grid, {"key": key, "levels": list(lv)})
        path = cache / f"effects-{key}-{digest}.npz" if cache else None
        if path is not None and path.is_file():
            with np.load(path, allow_pickle=False) as z:
                deltas[key], deltas_t[key] = z["delta"], z["delta_t"]
                meta["keys"][key] = json.loads(str(z["meta"]))
        else:
            todo.append((key, lv, path, kmeta))
    work = sum(len(lv) - 1 for _, lv, _, _ in todo)
    bar = tqdm(total=work + 2, desc="effect tables", unit="run", disable=not progress, leave=False)
    if todo:
        log.info(
            "building effect tables for %s (%d cells per level) in %s", ", ".join(k for k, *_ in todo), v.size, cache
        )
        base = simulate_observables(build_model(scene), v, m, mu, nthread=nthread)
        base_d, base_t = _fill(base.log_d, shape), _fill(aux_values(base), shape)
        # off-grid pushes at random levels, to measure each table's own accuracy
        cv, cm, cu = _random_pushes(table, CHECK_PUSHES, seed=1)
        check_base = simulate_observables(build_model(scene), cv, cm, cu, nthread=nthread)
        for key, lv, path, kmeta in todo:
            rows, rows_t, failed = [], [], {}
            for s in lv:
                if s == 0.0:
                    rows.append(np.zeros(shape))
                    rows_t.append(np.zeros((*shape, len(AUX))))
                    continue
                res = simulate_observables(_spec_model(scene, key, s), v, m, mu, nthread=nthread)
                failed[f"{s:g}"] = int((~res.ok).sum())
                rows.append(_fill(res.log_d, shape) - base_d)
                rows_t.append(_fill(aux_values(res), shape) - base_t)
                bar.update(1)
            deltas[key], deltas_t[key] = np.stack(rows), np.stack(rows_t)
            accuracy = _key_accuracy(
                scene, key, np.array(lv), axes, deltas[key], deltas_t[key], (cv, cm, cu), check_base, nthread
            )
            meta["keys"][key] = {**kmeta, "failed_cells": failed, "accuracy": accuracy}
            if path is not None:
                write_npz(
                    path,
                    delta=deltas[key],
                    delta_t=deltas_t[key],
                    meta=np.array(json.dumps(meta["keys"][key], sort_keys=True)),
                )
    aux_axes = aux_base = None
    if aux:
        aux_axes = grid.axes(table, stop=True)
        sgrid = {k: getattr(grid, k) for k in ("stop_speeds", "stop_masses", "stop_frictions")}
        digest, smeta = _digest(table, grid, {"stop_grid": sgrid, "aux": list(AUX)})
        spath = cache / f"observables-{digest}.npz" if cache else None
        if spath is not None and spath.is_file():
            with np.load(spath, allow_pickle=False) as z:
                aux_base = z["aux"]
        else:
            sv, sm, su = (x.ravel() for x in np.meshgrid(*aux_axes, indexing="ij"))
            obs = simulate_observables(build_model(scene), sv, sm, su, nthread=nthread)
            aux_base = _fill(aux_values(obs), tuple(a.size for a in aux_axes))
            if spath is not None:
                write_npz(spath, aux=aux_base, meta=np.array(json.dumps(smeta, sort_keys=True)))
        bar.update(1)
    tables = EffectTables(
        axes=axes,
        levels={k: np.array(x) for k, x in levels.items()},
        deltas=deltas,
        meta=meta,
        deltas_t=deltas_t,
        aux_axes=aux_axes,
        aux_base=aux_base,
    )
    digest, fmeta = _digest(
        table,
        grid,
        {
            "model_floor": {"n": grid.floor_pushes, "seed": 0},
            "numerical_error": table.meta.get("numerical_error"),
            "stop_grid": [getattr(grid, k) for k in ("stop_speeds", "stop_masses", "stop_frictions")] if aux else None,
            "aux": list(AUX) if aux else None,
        },
    )
    fpath = cache / f"floor-{digest}.json" if cache else None
    if fpath is not None and fpath.is_file():
        with open(fpath) as fh:
            floor = json.load(fh)["model_floor"]
    else:
        floor = model_floor(table, scene, tables if aux else None, n=grid.floor_pushes, nthread=nthread)
        if fpath is not None:
            write_json(fpath, {**fmeta, "model_floor": floor})
    bar.update(1)
    bar.close()
    meta["model_floor_rms"] = floor["rms"]
    meta["model_floor"] = floor
    return tables
