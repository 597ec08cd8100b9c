"""The model discrepancy, described: how the table's pushes differ from these ones in a way no library effect explains.

The discrepancy term (:func:`imply.diagnose.physics.candidates.discrepancy_candidate`) is a smooth,
low-dimensional function of speed, mass and friction with a Gaussian prior that keeps it
small (the model discrepancy of Kennedy and O'Hagan, in its simplest form: a few basis
functions with a ridge prior, fitted jointly with every object's mass and friction). What
depends on the object alone is absorbed by the per-object fit; it is reported as implied
parameters: where the log carries weighed masses, the masses a free fit would give them.

:func:`describe` turns a fitted discrepancy into numbers a lab can act on: how much the
table's slides change relative to these from the slowest to the fastest push, how that
differs for rough against smooth and heavy against light objects, the stop times' offset,
and the implied masses; :mod:`imply.diagnose.conclusion.render` says it in words.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from imply.diagnose.inference.fit import JointFit, Problem
from imply.diagnose.physics.candidates import Model, discrepancy_basis, scaled
from imply.diagnose.records import Record, json_field


@dataclass(frozen=True, kw_only=True)
class DiscrepancyReport(Record):
    """A fitted discrepancy, in log units: its coefficients and what they mean for these pushes."""

    coefficients: dict[str, float]
    rms_log_d: float  # RMS of its log d part over the pushes
    speed_trend: float  # mean change of its log d part from the slowest to the fastest push (these objects)
    speed_trend_rough_minus_smooth: float  # how that trend differs between the roughest and smoothest table friction
    speed_trend_heavy_minus_light: float  # between the heaviest and lightest table mass
    stop_time_offset: float | None = json_field(omit_none=True, default=None)  # mean log T part
    implied_mass_ratio: float | None = json_field(omit_none=True, default=None)  # median free-fit / weighed mass
    mimics: list[str] = json_field(default_factory=list)  # library effects it can imitate on this log's design


def _part_at(beta: np.ndarray, sv: float, sm: np.ndarray, su: np.ndarray) -> np.ndarray:
    bd, _ = discrepancy_basis(np.full(sm.size, sv), sm, su)
    return bd @ beta[: bd.shape[1]]


def describe(problem: Problem, fit: JointFit, *, mimics: list[str]) -> DiscrepancyReport | None:
    """The discrepancy of ``fit`` described on ``problem``'s pushes (None when the fit has none)."""
    found = fit.model.discrepancy
    if found is None:
        return None
    c, sl = found
    beta = fit.theta[sl]
    lm_c, lu_c = fit.objects.lm[problem.c_obj], fit.objects.lu[problem.c_obj]
    dd, dt = problem.discrepancy_terms(c, beta, problem.c_v, lm_c, lu_c)
    keep = problem.w_d > 0
    rows = dd[problem.cond][keep]
    sm = scaled(fit.objects.lm, *problem.lm_range)
    su = scaled(fit.objects.lu, *problem.lu_range)
    trend = float(np.mean(_part_at(beta, 1.0, sm, su) - _part_at(beta, -1.0, sm, su)))
    # the trend 2 (d_v + d_vu su + d_vm sm + d_vvv) changes by 4 d_vu from su = -1 to +1 (4 d_vm for sm)
    k = {name: i for i, name in enumerate(c.components)}
    return DiscrepancyReport(
        coefficients=dict(zip(c.components, beta.tolist(), strict=True)),
        rms_log_d=float(np.sqrt(np.mean(rows**2))) if rows.size else 0.0,
        speed_trend=trend,
        speed_trend_rough_minus_smooth=float(4.0 * beta[k["d_vu"]]),
        speed_trend_heavy_minus_light=float(4.0 * beta[k["d_vm"]]),
        stop_time_offset=(
            float(np.mean(dt[problem.cond][keep, problem.aux.index("stop_time")]))
            if "stop_time" in problem.aux
            else None
        ),
        implied_mass_ratio=implied_mass_ratio(problem, fit),
        mimics=list(mimics),
    )


def implied_mass_ratio(problem: Problem, fit: JointFit) -> float | None:
    """Median ratio of the masses a free fit (table alone) gives the objects to their weighed masses (None: not
    weighed)."""
    if problem.fixed_lm is None:
        return None
    free = replace(problem, fixed_lm=None)
    objs = free.initial_fit(Model(), np.zeros(0))
    return float(np.exp(np.median(objs.lm - problem.fixed_lm)))
