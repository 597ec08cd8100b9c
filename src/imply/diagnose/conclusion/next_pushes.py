"""The next pushes: a small set of new pushes that would best tell the contending explanations apart.

Candidates are pushes of the log's own objects at ``speeds`` speeds across the push
table's range and, where the log has directions, ``directions`` directions around the
table (otherwise the log's single direction). Under each contender (the hypothesis of
largest weight of each explanation in contention, :mod:`imply.diagnose.conclusion.verdict`), every
candidate push has a predicted log displacement (and log stop time and pusher speed where
the log has them), from that hypothesis's fitted effects and the object's fitted mass and friction.

Each pair's :class:`PairSeparation` says how far the recommended pushes, as many pushes of the
log's own design, and the log's own pushes observable by observable set it apart: which
measurement told the leading hypotheses apart.

For two hypotheses a and b, a push adds (pred_a - pred_b)^2 / sd^2 to their separation,
with sd the noise and the model's own error at that push (:mod:`imply.diagnose.inference.model_error`),
summed over the observables: the expected log Bayes factor between them after the push is
half the accumulated separation (the Kullback-Leibler divergence of two Gaussian
predictions of equal spread). The pushes are picked greedily, each candidate at most
once, each pick maximising the smallest separation of any pair of contenders (then the
weighted sum over pairs), so that every pair gets separated, not only the easiest. A
closed form, unlike an expected information gain over the posterior, and it needs
nothing but predictions the fits already make. It takes each object's fitted mass and
friction as known: the log's own pushes of that object pin them down.

Where the log lacks an observable the tables hold (the stop time, the pusher's speed),
:attr:`PairSeparation.measure` says how far measuring it on the log's own pushes would set the
contenders apart, in units of an assumed noise sd of 0.02 in its log: "measure the
pusher's speed" can separate what more displacements cannot.

``write_next_pushes`` writes them as push-log columns (``object_id,speed`` and
``direction``, ``size_x,size_y,size_z`` and ``mass`` where the log has them) with what
each contender predicts: ``expected_displacement_if_<label>`` (m) and, where the log has
stop times, ``expected_stop_time_if_<label>`` (s). ``imply sim pushes`` runs the file on an
MJCF as it is; its extra columns pass through.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from imply.diagnose.conclusion.next_probes import NextProbe, recommend_probe
from imply.diagnose.inference.fit import JointFit, Problem
from imply.diagnose.inference.model_error import numerical_floors
from imply.diagnose.inputs.observables import Observables
from imply.diagnose.inputs.pushlog import SIZE_COLUMNS, TRACK_OBSERVABLES, PushLog
from imply.diagnose.records import Record, json_field
from imply.io import write_csv
from imply.options import Config


@dataclass(frozen=True, kw_only=True)
class NextPush(Record):
    """One recommended push and what each contender predicts for it."""

    object_id: str
    speed: float
    direction: float | None
    expected_displacement: dict[str, float]  # by contender label (m)
    expected_stop_time: dict[str, float] | None  # by contender label (s), where the log has stop times
    expected_pusher_speed: dict[str, float] | None = None  # by contender label (m/s), where the log has them


@dataclass(frozen=True, kw_only=True)
class PairSeparation(Record):
    """How far apart two contenders (``first``, ``second``: hypothesis labels) are set, in noise sds (the square root
    of the summed chi-square)."""

    first: str
    second: str
    next_pushes_sd: float  # by the recommended pushes
    log_design_sd: float  # by as many pushes drawn from the log's own design, for comparison
    by_observable: dict[str, float]  # by the log's own pushes, per observable it has
    measure: dict[str, float] | None = json_field(omit_none=True, default=None)  # per observable it lacks, measured


@dataclass(frozen=True, kw_only=True)
class PushDesign(Record):
    """The recommended pushes, and how far apart they would set each pair of contenders (the leading pair first)."""

    contenders: list[str]  # labels of the hypotheses the pushes separate
    pushes: list[NextPush]
    pairs: list[PairSeparation]
    # the calibration probe that would separate the contenders more than any single push (None: none would)
    probe: NextProbe | None = json_field(omit_none=True, default=None)


# the noise sd (log units) assumed for an observable the log lacks, to say what measuring it would add
ASSUMED_SD = 0.02
# the name :attr:`PairSeparation.measure` gives the box's track (its crossing times together)
TRACK = "track"


def candidate_log(log: PushLog, v_range: tuple[float, float], *, speeds: int, directions: int) -> PushLog:
    """A push log (displacements 1) of every candidate push: each object at ``speeds`` speeds inside ``v_range`` and,
    where ``log`` has directions, at ``directions`` directions around the table."""
    lo, hi = v_range
    sp = np.linspace(lo + 0.03 * (hi - lo), hi - 0.03 * (hi - lo), speeds)
    dirs = np.arange(directions) * (2 * np.pi / directions) if log.has_direction else np.zeros(1)
    n_obj = len(log.objects)
    obj = np.repeat(np.arange(n_obj), sp.size * dirs.size)
    v = np.tile(np.repeat(sp, dirs.size), n_obj)
    phi = np.tile(dirs, n_obj * sp.size)
    ones = np.ones(v.size)
    frame = pd.DataFrame({"object_id": [log.objects[i] for i in obj], "speed": v, "direction": phi})
    return PushLog(
        path="<next pushes>",
        frame=frame,
        objects=list(log.objects),
        obj=obj,
        speed=v,
        displacement=ones,
        direction=phi,
        has_direction=log.has_direction,
        mass=log.mass,
        friction=log.friction,
        stop_time=ones if log.stop_time is not None else None,
        pusher_speed=ones if log.pusher_speed is not None else None,
        crossing_times=np.ones((ones.size, len(TRACK_OBSERVABLES))) if log.crossing_times is not None else None,
    )


def predictions(problem: Problem, fit: JointFit) -> tuple[np.ndarray, np.ndarray | None]:
    """log d (n,) and the aux observables (K, n; None without) of every push of ``problem`` (a log's pushes, or
    the candidate pushes) under ``fit``, each object at its fitted mass and friction."""
    lm, lu = fit.objects.lm[problem.c_obj], fit.objects.lu[problem.c_obj]
    pred = problem.predict(fit.model, fit.theta, lm, lu)
    aux = pred.log_t[problem.cond].T if pred.log_t is not None else None
    return pred.log_d[problem.cond], aux


def _measure(problem: Problem, contenders, pairs) -> dict[str, list[float]] | None:
    """Per observable the tables hold and the log lacks: the separation its measurement on the log's pushes adds to
    each pair of contenders (in the order of ``pairs``)."""
    held = problem.etables.aux if problem.etables is not None else ()
    missing = [a for a in held if problem.log.aux(a) is None]
    if not missing:
        return None
    ones = {a: np.ones(problem.log.n) for a in missing if a not in TRACK_OBSERVABLES}
    if any(a in TRACK_OBSERVABLES for a in missing):
        ones["crossing_times"] = np.ones((problem.log.n, len(TRACK_OBSERVABLES)))
    every = Observables(stop_time=True, pusher_speed=True, track=True, probes=False)
    full = Problem.of(
        replace(problem.log, **ones), problem.table, problem.etables, grid=problem.grid, observables=every
    )
    preds = [predictions(full, f)[1] for _, f, _ in contenders]
    # the track is one measurement: its crossing times count together
    measured = {a: [a] for a in missing if a not in TRACK_OBSERVABLES}
    if "crossing_times" in ones:
        measured[TRACK] = list(TRACK_OBSERVABLES)
    out = {}
    for name, parts in measured.items():
        rows = [full.aux.index(a) for a in parts]
        out[name] = [float(np.sqrt(np.sum(((preds[i][rows] - preds[j][rows]) / ASSUMED_SD) ** 2))) for i, j in pairs]
    return out


def _greedy(sep: np.ndarray, pair_w: np.ndarray, n: int, groups: np.ndarray) -> list[int]:
    """Indices of ``n`` rows of ``sep`` (candidates, pairs), each at most once, greedily maximising the smallest
    accumulated separation over pairs, then the weighted sum; among equals, a candidate whose group (an object and
    speed: the same push in another direction) has been picked fewer times."""
    acc = np.zeros(sep.shape[1])
    free = np.ones(sep.shape[0], bool)
    picked = np.zeros(int(groups.max()) + 1 if groups.size else 0)
    out = []
    for _ in range(min(n, sep.shape[0])):
        total = acc[None, :] + sep
        worst = np.round(total.min(1), 9)
        summed = np.round(total @ pair_w, 9)
        order = np.lexsort((picked[groups], -summed, -worst))  # last key first
        k = int(next(i for i in order if free[i]))
        out.append(k)
        free[k] = False
        picked[groups[k]] += 1
        acc = acc + sep[k]
    return out


def design_pushes(
    problem: Problem,
    contenders: list[tuple[str, JointFit, float]],
    *,
    n: int,
    speeds: int,
    directions: int,
    opts: Config,
    seed: int = 0,
) -> PushDesign | None:
    """The ``n`` pushes that best separate ``contenders`` ((label, fit, weight), at least two; None otherwise)."""
    if len(contenders) < 2 or n < 1:
        return None
    cand = Problem.of(
        candidate_log(problem.log, problem.v_range, speeds=speeds, directions=directions),
        problem.table,
        problem.etables,
        grid=problem.grid,
        observables=replace(problem.observables, probes=False),
    )
    num_d, num_t = numerical_floors(problem, opts)
    lead = contenders[0][1]
    ind_d, ind_t = cand.interpolation_indicator(lead.objects, lead.model, lead.theta)
    sd_d = np.sqrt(problem.noise_d**2 + num_d**2 + ind_d**2)
    sd_t = None
    if cand.use_t and ind_t is not None:
        noise_t = problem.noise_aux
        sd_t = np.sqrt(noise_t[cand.t_kind] ** 2 + num_t[cand.t_kind] ** 2 + ind_t**2).reshape(len(cand.aux), -1)
    preds = [predictions(cand, f) for _, f, _ in contenders]
    pairs = [(a, b) for a in range(len(contenders)) for b in range(a + 1, len(contenders))]
    sep = np.zeros((cand.y.size, len(pairs)))
    for j, (a, b) in enumerate(pairs):
        sep[:, j] = ((preds[a][0] - preds[b][0]) / sd_d) ** 2
        if sd_t is not None and preds[a][1] is not None:
            sep[:, j] += (((preds[a][1] - preds[b][1]) / sd_t) ** 2).sum(0)
    w = np.array([contenders[a][2] * contenders[b][2] for a, b in pairs])
    groups = np.unique(np.stack([cand.obj, np.round(cand.v, 9)], 1), axis=0, return_inverse=True)[1].ravel()
    picks = _greedy(sep, w / max(w.sum(), 1e-300), n, groups)
    labels = [c[0] for c in contenders]
    # the log's own design, as many pushes drawn at random: what repeating it would add
    rng = np.random.default_rng(seed)
    own_preds = [predictions(problem, f) for _, f, _ in contenders]  # the log's own pushes
    rows = rng.choice(problem.y.size, size=min(len(picks), problem.y.size), replace=False)
    sd_aux = problem.sd_t.reshape(len(problem.aux), -1) if problem.use_t else None
    keep = problem.w_d > 0
    total = sep[picks].sum(0)
    measure = _measure(problem, contenders, pairs)
    separations = []
    for j, (a, b) in enumerate(pairs):
        chi_d = ((own_preds[a][0] - own_preds[b][0]) / problem.sd_d) ** 2
        parts = {"displacement": chi_d}
        if problem.use_t and own_preds[a][1] is not None:
            chi_t = ((own_preds[a][1] - own_preds[b][1]) / sd_aux) ** 2
            parts.update({name: chi_t[i] for i, name in enumerate(problem.aux)})
        chi = sum(parts.values())
        separations.append(
            PairSeparation(
                first=labels[a],
                second=labels[b],
                next_pushes_sd=float(np.sqrt(total[j])),
                log_design_sd=float(np.sqrt(chi[rows].sum())),
                by_observable={name: float(np.sqrt(x[keep].sum())) for name, x in parts.items()},
                measure=None if measure is None else {name: sd[j] for name, sd in measure.items()},
            )
        )
    pushes = []
    for k in picks:
        pushes.append(
            NextPush(
                object_id=cand.log.objects[cand.obj[k]],
                speed=float(cand.v[k]),
                direction=float(cand.phi[k]) if problem.log.has_direction else None,
                expected_displacement={lab: float(np.exp(p[0][k])) for lab, p in zip(labels, preds, strict=True)},
                expected_stop_time=_expected(cand, "stop_time", labels, preds, k),
                expected_pusher_speed=_expected(cand, "pusher_speed", labels, preds, k),
            )
        )
    best_push_sd = float(np.sqrt(sep.min(1).max())) if sep.size else 0.0
    probe = recommend_probe(problem, contenders, speeds=np.unique(cand.v), best_push_sd=best_push_sd)
    return PushDesign(
        contenders=labels,
        pushes=pushes,
        pairs=separations,
        probe=probe,
    )


def _expected(cand: Problem, name: str, labels: list[str], preds, k: int) -> dict[str, float] | None:
    if name not in cand.aux:
        return None
    a = cand.aux.index(name)
    return {lab: float(np.exp(p[1][a, k])) for lab, p in zip(labels, preds, strict=True)}


def next_pushes_frame(design: PushDesign | None, log: PushLog) -> pd.DataFrame:
    """The recommended pushes as push-log columns with each contender's predictions (no rows without a design)."""
    has_size = all(c in log.frame for c in SIZE_COLUMNS)
    cols = ["object_id", "speed"] + (["direction"] if log.has_direction else [])
    cols += (SIZE_COLUMNS if has_size else []) + (["mass"] if log.mass is not None else [])
    labels = design.contenders if design is not None else []
    cols += [f"expected_displacement_if_{lab}" for lab in labels]
    if design is not None and design.pushes and design.pushes[0].expected_stop_time is not None:
        cols += [f"expected_stop_time_if_{lab}" for lab in labels]
    if design is not None and design.pushes and design.pushes[0].expected_pusher_speed is not None:
        cols += [f"expected_pusher_speed_if_{lab}" for lab in labels]
    rows = []
    for p in design.pushes if design is not None else []:
        i = log.objects.index(p.object_id)
        first = int(np.flatnonzero(log.obj == i)[0])
        row = {"object_id": p.object_id, "speed": round(p.speed, 4)}
        if log.has_direction:
            row["direction"] = round(float(np.mod(p.direction, 2 * np.pi)), 6)
        if has_size:
            row.update({c: log.frame[c].iloc[first] for c in SIZE_COLUMNS})
        if log.mass is not None:
            row["mass"] = float(log.mass[i])
        row.update({f"expected_displacement_if_{k}": v for k, v in p.expected_displacement.items()})
        if p.expected_stop_time is not None:
            row.update({f"expected_stop_time_if_{k}": v for k, v in p.expected_stop_time.items()})
        if p.expected_pusher_speed is not None:
            row.update({f"expected_pusher_speed_if_{k}": v for k, v in p.expected_pusher_speed.items()})
        rows.append(row)
    return pd.DataFrame(rows, columns=cols)


def write_next_pushes(path: str | os.PathLike, design: PushDesign | None, log: PushLog) -> None:
    """``next_pushes.csv``: the recommended pushes (a header alone where nothing is left to separate)."""
    write_csv(path, next_pushes_frame(design, log))
