"""A push log against a reference session of the same robot and boxes: the standing gap taken out push by push.

A lab that diagnoses a new session usually has an older one of the same boxes on the same
robot, recorded before the change it wants explained. Both sessions carry the robot's
standing gap (what the simulator gets wrong about this robot whatever changed: its contact,
its pusher); only the new one carries the change. The reference's own diagnosis describes the
standing gap; its fit gives each box's (mass, friction). :func:`against_reference` then
takes the standing gap out of every push of the new log, observable by observable:

- where the reference ran the same push (object, speed, direction), by the reference's own
  measurement: the mean of its replicates there, less the table's prediction at the box's
  fitted (mass, friction). That cancels the standing gap whatever its form, at the price of
  the reference's noise, which every fit then counts beside the log's
  (:attr:`imply.diagnose.inputs.pushlog.PushLog.baseline_sd`);
- elsewhere, by the reference's leading hypothesis (the standing gap as fitted), at the
  same (mass, friction);
- the log's calibration probes by the reference's probes of the same kind: a free stroke by
  the reference's at the same speed, a friction measurement by the reference's of the same
  box; the probes the reference did not run, and the loaded pushes, are left out (and said).

What comes out is a push log whose gap against the table is what changed since the
reference, diagnosed as any log is. In: the new log, the reference's problem and leading fit.
Out: that log, and a :class:`Pairing` saying which boxes, pushes and observables took part.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from imply.diagnose.inference.discrepancy import DiscrepancyReport
from imply.diagnose.inference.fit import JointFit, Problem
from imply.diagnose.inference.shrinkage import rms, share_closed
from imply.diagnose.inputs.probes import Probes
from imply.diagnose.inputs.pushlog import TRACK_OBSERVABLES, PushLog
from imply.diagnose.physics.candidates import Model
from imply.diagnose.physics.effect_tables import AUX
from imply.diagnose.physics.probe_fit import Servo
from imply.diagnose.records import Record, json_field
from imply.input_files import InputError

# the aux observables held as columns of the push log (the track's are columns of crossing_times)
_COLUMNS = tuple(a for a in AUX if a not in TRACK_OBSERVABLES)


@dataclass(frozen=True, kw_only=True)
class StandingGap(Record):
    """The reference session's own diagnosis: what the simulator gets wrong about this robot and these boxes."""

    pushlog: str
    n_pushes: int
    adequacy: str
    identification: str
    effects: list[str]  # the causes the reference's verdict states
    named: list[str]  # every library effect its verdict names: the causes, then the contenders' other effects
    leading: str  # the label of its leading hypothesis
    headline: str  # its verdict's first sentence
    sentence: str  # its verdict in words
    baseline_rms: float  # the reference's RMS log d gap against the table, the boxes refitted
    noise_sd: float
    discrepancy: DiscrepancyReport | None = json_field(omit_none=True, default=None)


@dataclass(frozen=True, kw_only=True)
class SessionShrink(Record):
    """How far a log's gap against the table (log d, RMS, in sample, the boxes refitted each time) shrinks once the
    stated cause is added, and (against a reference session) once the standing gap is described too."""

    before_rms: float  # the table alone
    cause_rms: float  # the table and the stated causes, at their estimates (the table alone where none is stated)
    noise_floor_rms: float | None
    cause_share_closed: float | None  # of the gap above the noise floor
    # the standing gap (as the reference measured it) and the cause: against a reference only
    cause_and_standing_rms: float | None = json_field(omit_none=True, default=None)
    cause_and_standing_share_closed: float | None = json_field(omit_none=True, default=None)


@dataclass(frozen=True, kw_only=True)
class ReferenceReport(Record):
    """A diagnosis against a reference session: the pairing of the two sessions, the standing gap, the gap's
    shrink."""

    pushlog: str
    n_pushes: int
    objects_shared: list[str]
    objects_log_only: list[str]  # boxes the reference lacks: left out of the diagnosis against it
    objects_reference_only: list[str]  # boxes only the reference has: they inform the standing gap alone
    pushes_matched: int  # the log's pushes whose (object, speed, direction) the reference ran
    pushes_modelled: int  # the others: their baseline is the standing gap's fit
    # observables of the log the reference lacks, not used against it ("probes": the log's probes, where it has boxes
    # the reference lacks)
    observables_dropped: list[str]
    standing: StandingGap


@dataclass(frozen=True)
class Pairing:
    """Which boxes, pushes and observables of a log took part in its diagnosis against a reference."""

    objects_shared: list[str]
    objects_log_only: list[str]
    objects_reference_only: list[str]
    pushes_matched: int
    pushes_modelled: int
    observables_dropped: list[str]
    raw: PushLog  # the log's shared boxes, before the standing gap is taken out

    def record_fields(self) -> dict:
        """The fields :class:`ReferenceReport` holds of the pairing (all but the log)."""
        return {k: v for k, v in vars(self).items() if k != "raw"}


def check_pair(log: PushLog, reference: PushLog) -> None:
    """Refuse, in one line, a reference that cannot serve ``log``: one that pushes none of its boxes."""
    if not set(log.objects) & set(reference.objects):
        raise InputError(
            f"{reference.path}: the reference session pushes none of the boxes of {log.path} (object_id); a reference "
            "must push the same boxes on the same robot"
        )


def _subset(log: PushLog, keep: list[str]) -> PushLog:
    """``log``'s pushes of the objects ``keep`` (in ``log``'s order); its probes only where no object is dropped (they
    are indexed by the log's boxes)."""
    if len(keep) == len(log.objects):
        return log
    index = [log.objects.index(o) for o in keep]
    rows = np.flatnonzero(np.isin(log.obj, index))
    new_index = {old: new for new, old in enumerate(index)}

    def cut(x):
        return None if x is None else x[rows]

    return replace(
        log,
        frame=log.frame.iloc[rows].reset_index(drop=True),
        objects=list(keep),
        obj=np.array([new_index[int(i)] for i in log.obj[rows]], int),
        speed=log.speed[rows],
        displacement=log.displacement[rows],
        direction=log.direction[rows],
        mass=None if log.mass is None else log.mass[index],
        friction=None if log.friction is None else log.friction[index],
        stop_time=cut(log.stop_time),
        pusher_speed=cut(log.pusher_speed),
        crossing_times=cut(log.crossing_times),
        probes=None,
    )


def _without(log: PushLog, drop: list[str]) -> PushLog:
    """``log`` without the aux observables ``drop`` (the track goes whole)."""
    cols = {c: None for c in _COLUMNS if c in drop}
    if any(a in TRACK_OBSERVABLES for a in drop):
        cols["crossing_times"] = None
    return replace(log, **cols) if cols else log


def _corrected_probes(log: PushLog, ref: Problem, standing: JointFit) -> tuple[Probes | None, list[str]]:
    """``log``'s probes with the standing gap taken out by the reference's probes of the same kind: a free stroke by
    the reference's strokes at the same commanded speed (against the servo's nominal mean speed), a friction
    measurement by the reference's of the same box (against the box's friction as the reference's fit has it, its
    stated sd combined with the reference's). Probes the reference did not run, and the loaded pushes, are left out;
    returns the probes (None: none left) and what was left out, in words."""
    own, theirs = log.probes, ref.log.probes
    if own is None:
        return None, []
    if theirs is None:
        return None, ["probes (the reference has none)"]
    left = []
    # free strokes: the log's reading over the reference's, at the nominal servo's mean speed
    servo = Servo.of_scene(ref.table.meta.get("scene"))
    speeds = np.round(theirs.free_stroke_speed, 9)
    keep = np.isin(np.round(own.free_stroke_speed, 9), speeds) & (servo is not None)
    stroke_v = own.free_stroke_speed[keep]
    stroke_p = own.free_stroke_pusher_speed[keep]
    if stroke_v.size:
        ref_log = {v: np.mean(np.log(theirs.free_stroke_pusher_speed[speeds == v])) for v in np.unique(speeds)}
        standing_log = np.array([ref_log[v] for v in np.round(stroke_v, 9)]) - np.log(servo.mean_speed(stroke_v))
        stroke_p = stroke_p * np.exp(-standing_log)
    if keep.size and not keep.all():
        left.append(f"{int((~keep).sum())} free stroke(s) at speeds the reference did not stroke")
    # friction measurements: the log's reading over the reference's of the same box, at the box's fitted friction
    friction = np.full(len(log.objects), np.nan)
    friction_sd = np.full(len(log.objects), np.nan)
    for i, name in enumerate(log.objects):
        j = ref.log.objects.index(name) if name in ref.log.objects else -1
        if j < 0 or not np.isfinite(own.friction[i]) or not np.isfinite(theirs.friction[j]):
            continue
        ratio = own.friction[i] / theirs.friction[j]
        friction[i] = ratio * np.exp(standing.objects.lu[j])
        rel = np.hypot(own.friction_sd[i] / own.friction[i], theirs.friction_sd[j] / theirs.friction[j])
        friction_sd[i] = rel * friction[i]
    dropped = int(np.isfinite(own.friction).sum() - np.isfinite(friction).sum())
    if dropped:
        left.append(f"{dropped} friction measurement(s) of boxes the reference did not measure")
    if own.n_added:
        left.append(f"{own.n_added} loaded push(es)")
    none_added = np.zeros(0)
    probes = replace(
        own,
        free_stroke_speed=stroke_v,
        free_stroke_pusher_speed=stroke_p,
        friction=friction,
        friction_sd=friction_sd,
        added_obj=np.zeros(0, int),
        added_speed=none_added,
        added_displacement=none_added,
        added_mass=none_added,
        added_direction=none_added,
        added_stop_time=none_added,
        added_pusher_speed=none_added,
    )
    return (probes if stroke_v.size or np.isfinite(friction).any() else None), left


def _condition_keys(objects: list[str], obj: np.ndarray, v: np.ndarray, phi: np.ndarray) -> list[tuple]:
    """Each push's condition as a key two sessions share: its box's name, speed and direction (mod 2 pi)."""
    return [
        (objects[int(o)], round(float(s), 9), round(float(np.mod(p, 2 * np.pi)), 6))
        for o, s, p in zip(obj, v, phi, strict=True)
    ]


def _measured_baseline(ref: Problem, tab_d: np.ndarray, tab_t: np.ndarray | None) -> dict[tuple, tuple]:
    """The reference's measured standing gap at each of its conditions: {condition key: (log d gap, aux gaps (K,)
    or None, unflagged replicates of log d, of each aux observable (K,))}, from the mean of its unflagged
    replicates less the table's prediction (``tab_d`` (C,), ``tab_t`` (C, K)) at the boxes' fitted values."""
    keys = _condition_keys(ref.log.objects, ref.c_obj, ref.c_v, ref.c_phi)
    w = ref.w_d > 0
    k_d = np.bincount(ref.cond, w, minlength=ref.n_cond)
    mean_d = np.bincount(ref.cond, np.where(w, ref.y, 0.0), minlength=ref.n_cond) / np.maximum(k_d, 1)
    K = len(ref.aux)
    mean_t = np.zeros((ref.n_cond, K))
    k_t = np.zeros((ref.n_cond, K))
    for j in range(K):
        rows = ref.aux_rows(ref.aux[j])
        wt = ref.w_t[rows] > 0
        k_t[:, j] = np.bincount(ref.cond, wt, minlength=ref.n_cond)
        mean_t[:, j] = np.bincount(ref.cond, np.where(wt, ref.y_t[rows], 0.0), minlength=ref.n_cond) / np.maximum(
            k_t[:, j], 1
        )
    out = {}
    for c, key in enumerate(keys):
        if k_d[c] == 0:
            continue
        gap_t = mean_t[c] - tab_t[c] if K else None
        out[key] = (mean_d[c] - tab_d[c], gap_t, k_d[c], k_t[c])
    return out


def against_reference(
    log: PushLog, ref: Problem, standing: JointFit, *, observables_used: tuple[str, ...]
) -> tuple[PushLog, Pairing]:
    """``log`` with the standing gap taken out of every push (module docstring), and its :class:`Pairing`.

    ``ref``: the reference's problem as its diagnosis fitted it (noise, weights); ``standing``: its leading fit;
    ``observables_used``: the aux observables a diagnosis of ``log`` would use (those the reference lacks are
    dropped)."""
    check_pair(log, ref.log)
    shared = [o for o in log.objects if o in ref.log.objects]
    log_only = [o for o in log.objects if o not in ref.log.objects]
    ref_only = [o for o in ref.log.objects if o not in log.objects]
    dropped = [a for a in observables_used if a not in ref.aux]
    if log_only and log.probes is not None:
        dropped.append("probes (they name boxes the reference lacks)")
    unused = [a for a in AUX if a not in observables_used or a in dropped]
    raw = _without(_subset(log, shared), unused)
    if raw.probes is not None and ref.observables.probes:
        probes, left_out = _corrected_probes(raw, ref, standing)
        raw = replace(raw, probes=probes)
        dropped += left_out
    aux = tuple(a for a in observables_used if a in ref.aux)
    pl = Problem.of(raw, ref.table, ref.etables, grid=ref.grid, observables=ref.observables)
    if pl.aux != aux:  # the log's problem reads the same observables as the reference's (those both have)
        raise AssertionError(f"observables {pl.aux} against {aux}")
    cols = [ref.aux.index(a) for a in aux]

    # the boxes' fitted values in the reference
    at = np.array([ref.log.objects.index(o) for o in shared])[pl.c_obj]
    lm, lu = standing.objects.lm[at], standing.objects.lu[at]
    none = np.zeros(0)
    table_log = pl.predict(Model(), none, lm, lu)
    lead_log = pl.predict(standing.model, standing.theta, lm, lu)
    gap_d = lead_log.log_d - table_log.log_d
    gap_t = lead_log.log_t - table_log.log_t if aux else None
    sd_d = np.zeros(pl.n_cond)
    sd_t = np.zeros((pl.n_cond, len(aux)))

    ref_tab = ref.predict(Model(), none, standing.objects.lm[ref.c_obj], standing.objects.lu[ref.c_obj])
    measured = _measured_baseline(ref, ref_tab.log_d, ref_tab.log_t)
    matched = np.zeros(pl.n_cond, bool)
    for c, key in enumerate(_condition_keys(raw.objects, pl.c_obj, pl.c_v, pl.c_phi)):
        if key not in measured:
            continue
        g_d, g_t, k_d, k_t = measured[key]
        matched[c] = True
        gap_d[c] = g_d
        sd_d[c] = ref.noise_d / np.sqrt(k_d)
        for j, col in enumerate(cols):
            if k_t[col] > 0:
                gap_t[c, j] = g_t[col]
                sd_t[c, j] = ref.noise_aux[col] / np.sqrt(k_t[col])
            else:
                sd_t[c, j] = 0.0

    cond = pl.cond
    changes: dict = {"displacement": np.exp(raw.log_d - gap_d[cond])}
    baseline_sd = {"displacement": sd_d[cond]}
    crossing = None if raw.crossing_times is None else raw.crossing_times.copy()
    for j, a in enumerate(aux):
        corrected = np.exp(raw.aux(a) - gap_t[cond, j])
        baseline_sd[a] = sd_t[cond, j]
        if a in TRACK_OBSERVABLES:
            crossing[:, TRACK_OBSERVABLES.index(a)] = corrected
        else:
            changes[a] = corrected
    if crossing is not None:
        changes["crossing_times"] = crossing
    corrected_log = replace(raw, baseline_sd=baseline_sd, **changes)
    n_matched = int(matched[cond].sum())
    pairing = Pairing(
        objects_shared=shared,
        objects_log_only=log_only,
        objects_reference_only=ref_only,
        pushes_matched=n_matched,
        pushes_modelled=int(cond.size - n_matched),
        observables_dropped=dropped,
        raw=raw,
    )
    return corrected_log, pairing


def stated_part(fit: JointFit, causes: list[str]) -> tuple[Model, np.ndarray]:
    """The part of ``fit``'s model made of the library effects ``causes`` (those a verdict states), and its
    parameters at their estimates."""
    keep = [(c, sl) for c, sl in zip(fit.model.candidates, fit.model.slices(), strict=True) if c.name in causes]
    model = Model(tuple(c for c, _ in keep))
    theta = np.concatenate([fit.theta[sl] for _, sl in keep]) if keep else np.zeros(0)
    return model, theta


def against_table(raw: PushLog, fitted: Problem, base: JointFit | None = None) -> tuple[Problem, JointFit]:
    """The log ``raw`` against the table, under ``fitted``'s noise, weights and model error (``fitted`` itself where
    its rows are ``raw``'s and its launch the table's), and the table alone fitted on it (``base`` where given and
    ``fitted`` is that problem)."""
    if raw is fitted.log and fitted.launch is None:
        p = fitted
    else:
        p = Problem.of(raw, fitted.table, fitted.etables, grid=fitted.grid, observables=fitted.observables)
        p = replace(
            p,
            noise_d=fitted.noise_d,
            noise_t=fitted.noise_t,
            model_err_d=fitted.model_err_d,
            model_err_t=fitted.model_err_t,
            w_d=fitted.w_d,
            w_t=fitted.w_t,
        )
        base = None
    if base is None:
        base = p.fit(Model(), np.zeros(0), p.initial_fit())
    return p, base


def cause_shrink(
    raw: PushLog,
    fitted: Problem,
    fit: JointFit,
    causes: list[str],
    *,
    base: JointFit | None = None,
    standing_described: bool = False,
) -> SessionShrink:
    """How far the gap of the log ``raw`` against the table (log d, RMS, in sample, its boxes refitted each time)
    shrinks once the stated ``causes`` are added at their estimates in ``fit`` (the leading fit on ``fitted``,
    whose rows are ``raw``'s: its noise, weights and model error are used), and (``standing_described``: ``fitted``
    is ``raw`` with a reference's standing gap taken out) once the standing gap is described too. ``base``: the
    table alone fitted on ``fitted``, where the caller has it and ``fitted`` is ``raw``'s own problem (launch the
    table's): it is then the baseline, not fitted again."""
    none = np.zeros(0)
    p, base = against_table(raw, fitted, base)

    def resid(problem: Problem, model: Model, theta: np.ndarray, lm: np.ndarray, lu: np.ndarray) -> np.ndarray:
        return problem.row_residuals(problem.predict(model, theta, lm[problem.c_obj], lu[problem.c_obj]))[0]

    before = rms(resid(p, Model(), none, base.objects.lm, base.objects.lu), p.w_d)
    model, theta = stated_part(fit, causes)
    if model.dim:
        lms, lus, _ = p.refine_many(model, theta[None, :], base.objects.lm[None, :], base.objects.lu[None, :])
        cause = rms(resid(p, model, theta, lms[0], lus[0]), p.w_d)
    else:
        cause = before
    both = rms(resid(fitted, fit.model, fit.theta, fit.objects.lm, fit.objects.lu), fitted.w_d)
    n, N, k = p.n_rows, p.n_obj, p.k_free
    floor = p.noise_d * np.sqrt(max(n - k * N, 0) / n) if n else None
    return SessionShrink(
        before_rms=before,
        cause_rms=cause,
        cause_and_standing_rms=both if standing_described else None,
        noise_floor_rms=floor,
        cause_share_closed=share_closed(before, cause, floor),
        cause_and_standing_share_closed=share_closed(before, both, floor) if standing_described else None,
    )
