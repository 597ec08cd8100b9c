"""The model's own error, per push: what a fit counts as variance beside the noise.

Three parts, added in quadrature: the simulator's numerical error (the part of the
tables' measured model floor that is not interpolation), the push table's interpolation
error where the model reads it (|cubic - linear| at each push as the model sees it), and,
for a model with effects, the size of any extrapolation beyond the table's range and each
tabulated effect's measured relative error times the effect it carries. The baseline is
fitted under the baseline's error (:func:`model_error` with no effects); every effect
that a model adds brings its own; the hypotheses are all weighed under the baseline's
(:mod:`imply.diagnose.inference.hypotheses`), so that their chi-squares compare.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imply.diagnose.inference.fit import ObjectFit, Problem
from imply.diagnose.physics.candidates import Model
from imply.options import Config


@dataclass(frozen=True)
class ModelError:
    """Per-row model error (RMS, log units) of log d and, where used, of each aux row."""

    log_d: np.ndarray
    log_t: np.ndarray | None

    def apply(self, problem: Problem) -> Problem:
        """``problem`` with this model error beside its noise."""
        return problem.with_model_error(self.log_d, self.log_t)


def numerical_floors(problem: Problem, opts: Config) -> tuple[float, np.ndarray]:
    """The simulator's own numerical error per observable (the part of the model floor that is not
    interpolation; interpolation is judged push by push): log d's, and each aux observable's (K,).
    ``opts``: ``model_floor``, ``stop_time_floor`` (the floors where the tables record none)."""
    floor = (problem.etables.meta.get("model_floor") or {}) if problem.etables is not None else {}
    num_d = floor.get("numerical_rms")
    d = float(num_d) if num_d is not None else float(opts.model_floor or 0.0)
    fallback = {"stop_time": opts.stop_time_floor}
    t = []
    for name in problem.aux:
        num = (floor.get(name) or {}).get("numerical_rms")
        t.append(float(num) if num is not None else float(fallback.get(name) or 0.0))
    return d, np.array(t)


def model_error(problem: Problem, model: Model, theta: np.ndarray, *, objects: ObjectFit, opts: Config) -> ModelError:
    """Per-row model error of ``model`` at ``theta`` with the objects' fitted (log m, log mu)."""
    num_d, num_t = numerical_floors(problem, opts)
    ind_d, ind_t = problem.interpolation_indicator(objects, model, theta)
    err_d2 = num_d**2 + ind_d**2
    err_t2 = num_t[problem.t_kind] ** 2 + ind_t**2 if ind_t is not None else None
    lm_c, lu_c = objects.lm[problem.c_obj], objects.lu[problem.c_obj]
    if model.dim:
        # a speed or friction carried outside the table's range is extrapolated: count its size as error
        ext_d, ext_t = problem.predict(model, theta, lm_c, lu_c).extrapolation_sizes()
        err_d2 = err_d2 + ext_d[problem.cond] ** 2
        if err_t2 is not None and ext_t is not None:
            err_t2 = err_t2 + ext_t[problem.t_cond, problem.t_kind] ** 2
    if model.dim and problem.etables is not None:
        for key, dd, dt in problem.table_terms(model, theta, lm_c, lu_c):
            # a table's error relative to the effect it carries, as measured (at most the effect itself)
            err_d2 = err_d2 + (min(problem.etables.relative_error(key, "d"), 1.0) * dd)[problem.cond] ** 2
            if err_t2 is not None and dt is not None:
                rel = np.array([min(problem.etables.relative_error(key, a), 1.0) for a in problem.aux])
                err_t2 = err_t2 + ((rel[None, :] * dt)[problem.t_cond, problem.t_kind]) ** 2
    return ModelError(np.sqrt(err_d2), None if err_t2 is None else np.sqrt(err_t2))
