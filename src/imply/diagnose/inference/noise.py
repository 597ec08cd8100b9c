"""Step 1 of the diagnosis: each observable's noise, and the gross outliers every fit leaves out.

Replicate pushes (same object, speed and direction) give each observable's noise: a
robust sd from the median absolute replicate difference, then, once outliers are set
aside, the pure-error sd. A push whose replicate difference is beyond ``outlier_sd``
robust sds is a gross outlier (of the pair, the one farther from the baseline fit); so
is a push without replicates whose baseline residual is that far out, if few are. A
flagged push's replicates are set aside with it. ``noise_sd`` / ``stop_time_noise_sd``
replace the estimates; without replicates or options the residual variance is used.

:func:`estimate_noise` reads a problem at unit noise and returns a :class:`Noise`; the
problem the later steps fit under is ``noise.apply(problem)``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from imply.diagnose.inference.fit import Problem
from imply.diagnose.inputs.pushlog import TRACK_OBSERVABLES
from imply.diagnose.physics.candidates import Model
from imply.diagnose.records import Record
from imply.options import Config


@dataclass(frozen=True, kw_only=True)
class ObservableNoise(Record):
    """One observable's noise estimate and its flagged pushes (row indices)."""

    robust_sd: float | None
    replicate_pairs: int
    pure_error_ss: float
    pure_error_df: int
    outliers: list[int]
    set_aside: list[int]
    sd: float
    source: str


@dataclass(frozen=True, kw_only=True)
class Noise:
    """Every observable's noise (those beside the displacement where the log's are used) and the row weights."""

    displacement: ObservableNoise
    aux: dict[str, ObservableNoise]  # by observable, in the problem's order
    weights_d: np.ndarray  # per row: 0 where flagged or set aside, else 1
    weights_t: np.ndarray | None  # per aux row

    @property
    def stop_time(self) -> ObservableNoise | None:
        return self.aux.get("stop_time")

    def apply(self, problem: Problem) -> Problem:
        """``problem`` at this noise, with the flagged pushes and their replicates weighted 0."""
        sd_t = np.array([self.aux[a].sd for a in problem.aux]) if self.aux else None
        return problem.with_noise(self.displacement.sd, sd_t).with_weights(self.weights_d, self.weights_t)


def _groups(cond: np.ndarray, w: np.ndarray) -> list[np.ndarray]:
    order = np.argsort(cond, kind="stable")
    c = cond[order]
    cuts = np.flatnonzero(np.diff(c)) + 1
    return [g[w[g] > 0] for g in np.split(order, cuts)]


def _replicate_scale(y: np.ndarray, groups: list[np.ndarray]) -> tuple[float | None, int]:
    """Robust noise sd from replicate differences (1.4826 x median |difference| / sqrt 2)."""
    diffs = []
    for g in groups:
        if g.size >= 2:
            vals = y[g]
            diffs.extend(np.abs(vals[:, None] - vals[None, :])[np.triu_indices(g.size, 1)].tolist())
    if len(diffs) < 2:
        return None, len(diffs)
    return float(1.4826 * np.median(diffs) / np.sqrt(2.0)), len(diffs)


def _pure_error(y: np.ndarray, groups: list[np.ndarray]) -> tuple[float, int]:
    ss, df = 0.0, 0
    for g in groups:
        if g.size >= 2:
            ss += float(((y[g] - y[g].mean()) ** 2).sum())
            df += g.size - 1
    return ss, df


def flag_replicates(
    y: np.ndarray, groups: list[np.ndarray], *, scale: float | None, k: float, resid: np.ndarray
) -> np.ndarray:
    """Rows whose replicate disagreement is beyond k robust sds (the member farther from the fit)."""
    flags = np.zeros(y.size, bool)
    if scale is None or scale <= 0:
        return flags
    for g in groups:
        if g.size < 2:
            continue
        if g.size == 2:
            if abs(y[g[0]] - y[g[1]]) > k * np.sqrt(2.0) * scale:
                flags[g[np.argmax(np.abs(resid[g]))]] = True
            continue
        for j in g:
            others = np.median(y[g[g != j]])
            if abs(y[j] - others) > k * np.sqrt(1.0 + 1.0 / (g.size - 1)) * scale:
                flags[j] = True
    return flags


def flag_singletons(resid: np.ndarray, groups: list[np.ndarray], *, scale: float | None, k: float) -> np.ndarray:
    """Rows without replicates whose residual is beyond k sds, if at most 5% of the pushes are."""
    flags = np.zeros(resid.size, bool)
    if scale is None or scale <= 0:
        return flags
    single = (
        np.concatenate([g for g in groups if g.size == 1]) if any(g.size == 1 for g in groups) else np.zeros(0, int)
    )
    if not single.size:
        return flags
    far = single[np.abs(resid[single]) > k * scale]
    if far.size <= max(1, int(0.05 * resid.size)):
        flags[far] = True
    return flags


def _observable(
    problem: Problem, y: np.ndarray, resid: np.ndarray, *, groups: list[np.ndarray], option_sd: float | None, k: float
) -> tuple[ObservableNoise, np.ndarray]:
    """One observable's noise and its row weights."""
    scale, npairs = _replicate_scale(y, groups)
    flags = flag_replicates(y, groups, scale=scale, k=k, resid=resid)
    if scale is None:
        # no replicates: a robust scale of the baseline residuals
        med = np.median(np.abs(resid - np.median(resid)))
        scale_r = 1.4826 * med if med > 0 else None
        flags |= flag_singletons(resid, groups, scale=scale_r, k=k)
    else:
        flags |= flag_singletons(resid, groups, scale=scale, k=k)
    # a flagged push's replicates are set aside too: the kept pushes are then all in complete
    # groups whose spread is the noise the tests assume, with no stray tail among them
    partners = np.isin(problem.cond, problem.cond[flags]) & ~flags
    w = (~(flags | partners)).astype(float)
    ss, df = _pure_error(y, _groups(problem.cond, w))
    if option_sd is not None:
        sd, source = float(option_sd), "option"
    elif df >= 2 and ss > 1e-12 * df:
        sd, source = float(np.sqrt(ss / df)), "replicate pushes"
    else:
        keep = w > 0
        dof = max(int(keep.sum()) - problem.k_free * problem.n_obj, 1)
        sd = float(np.sqrt(np.sum(resid[keep] ** 2) / dof)) or 1e-3
        source = "residual variance (no replicate pushes and no noise option)"
    est = ObservableNoise(
        robust_sd=scale,
        replicate_pairs=npairs,
        pure_error_ss=ss,
        pure_error_df=df,
        outliers=np.flatnonzero(flags).tolist(),
        set_aside=np.flatnonzero(partners).tolist(),
        sd=sd,
        source=source,
    )
    return est, w


def estimate_noise(problem: Problem, opts: Config) -> Noise:
    """Each observable's noise sd and the rows flagged as gross outliers, from ``problem`` at unit noise.

    ``opts`` is the diagnosis' settings (:class:`imply.diagnose.analysis.DiagnosisConfig`:
    ``noise_sd``, ``stop_time_noise_sd``, ``pusher_speed_noise_sd``, ``track_noise_sd``, ``outlier_sd``)."""
    ones = np.ones(problem.y.size)
    groups = _groups(problem.cond, ones)
    # a first baseline fit, on everything, to tell which member of a pair is off
    # without the probes: their rows are whitened by their own stated or measured sds, not by unit noise
    unit = replace(problem, probes=None).with_noise(1.0, 1.0)
    unit = unit.with_weights(ones, np.ones(problem.t_row.size) if problem.use_t else None)
    fit0 = unit.initial_fit()
    rd, rt = unit.row_residuals(unit.predict(Model(), np.zeros(0), fit0.lm[unit.c_obj], fit0.lu[unit.c_obj]))
    disp, w_d = _observable(unit, unit.y, rd, groups=groups, option_sd=opts.noise_sd, k=opts.outlier_sd)
    aux, w_t = {}, None
    if unit.y_t is not None:
        w_t = np.ones(unit.y_t.size)
        for name in unit.aux:
            rows = unit.aux_rows(name)
            option_sd = opts.track_noise_sd if name in TRACK_OBSERVABLES else getattr(opts, f"{name}_noise_sd")
            aux[name], w_t[rows] = _observable(
                unit, unit.y_t[rows], rt[rows], groups=groups, option_sd=option_sd, k=opts.outlier_sd
            )
    return Noise(displacement=disp, aux=aux, weights_d=w_d, weights_t=w_t)
