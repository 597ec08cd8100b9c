"""The stated causes put into the simulator: the corrected scene, the gap re-simulated in it, the causes refitted
there, and whether the simulator and the log's probes agree with the tables' verdict.

The verdict (:mod:`imply.diagnose.conclusion.verdict`) reads the effect tables: each effect
tabulated alone on a coarse grid, combined additively and interpolated linearly. Where
that reading is off (between levels, for combined effects, at the grid's edges) the
shrink it predicts is off too. This step checks it on the simulator itself:

1. **The corrected scene**: the scene the log was diagnosed against (the table's
   built-in one, or a user's MJCF) with every stated cause at its estimate, written by
   :mod:`imply.sim.correction` through ``mujoco.sysid`` parameters (against a reference
   session, the standing gap's stated causes too). ``corrected.xml`` in the report folder.
2. **The shrink re-simulated**: the log's pushes run twice on the push simulator
   (:func:`imply.sim.pushes.simulate_pushes_run`, the table's own stepping on
   ``mujoco.batch`` threads): in the uncorrected scene with each box at the mass and
   friction the table alone fits, and in the corrected scene with each box as the stated
   causes fit it. The RMS log d gap of each against the log gives the share closed,
   re-simulated, beside the one the tables predict
   (:class:`imply.diagnose.inference.sessions.SessionShrink`, the same definition). They
   *disagree* when they differ by more than the tables' own error (their measured model
   floor) allows.
3. **The refit in the simulator** (``simulator_refit``): the stated causes and the boxes'
   masses and frictions fitted to the log's displacements (and stop times, where the
   diagnosis used them) by ``mujoco.sysid.optimize`` (MuJoCo's Levenberg-Marquardt,
   ``mujoco.minimize``), starting from the tables' estimates, with the 95% interval
   ``mujoco.sysid.calculate_intervals`` gives from the fit's Jacobian. The Jacobian is
   taken by finite differences in one batch per column group: a box's mass moves only
   its own pushes, so every box's mass is perturbed at once (and every friction), and a
   Jacobian costs (causes' components + 2) passes over the log, not one per box.
4. **The probes**: the log's calibration probes under the leading hypothesis, each kind's
   whitened chi-square (friction measurements, added-mass pushes, free strokes).

A stated explanation is *contradicted by the simulator* where, put into it, the causes
leave open more of the log's gap than the tables say, by more than half the gap above the
noise (:data:`SHORTFALL`; and the two disagree): a small shortfall is the tables' own error
for effects combined, which they tabulate one at a time. It is *contradicted by the probes*
where a kind's chi-square has p below ``alpha`` over the number of kinds. A contradicted
explanation is not stated (:func:`imply.diagnose.conclusion.verdict.contradicted`). The
refit informs (its interval beside the tables'); it does not decide the verdict.

Pushes are simulated with the scene's own box (the table's canonical one): the table
ignores a log's box sizes, and so does the check. A track is not refitted.
"""

from __future__ import annotations

import io
import logging
import time
from dataclasses import dataclass, field

import numpy as np

from imply.diagnose.inference.fit import JointFit, Problem
from imply.diagnose.inference.sessions import SessionShrink
from imply.diagnose.inference.shrinkage import rms, share_closed
from imply.diagnose.physics.candidates import Model
from imply.diagnose.records import Record, json_field
from imply.diagnose.tails import chi2_sf
from imply.sim.correction import MECHANISM, NO_MJCF_FORM, cause_parameters, corrected_spec, friction_factor
from imply.sim.pushes import simulate_pushes_run
from imply.sim.track import stop_frame_times, stop_times

log = logging.getLogger("imply.diagnose")

CORRECTED_XML = "corrected.xml"
# finite-difference steps of the refit's Jacobian: of a cause's library range, and of a log mass or log friction
CAUSE_STEP = 0.01
BOX_STEP = 0.01
# the simulator contradicts stated causes that, put into it, leave more of the log's gap above the noise open than
# the tables say, by more than this share of it (chosen on the development sets: docs/notes/gap-diagnostic.md)
SHORTFALL = 0.5


@dataclass(frozen=True)
class Scene:
    """The scene a log is diagnosed against: its MJCF text, what to call it, and where its relative paths start."""

    xml: str
    name: str
    model_dir: str | None = None


@dataclass(frozen=True, kw_only=True)
class CauseInScene(Record):
    """A stated cause as the corrected scene holds it."""

    cause: str
    value: list[float]  # its components (a tilt's and an anisotropy's two)
    mechanism: str  # how it is written (imply.sim.correction.MECHANISM)
    mjcf: bool  # written into the MJCF (False: no MJCF form; applied to each push's friction in the re-simulation)
    source: str = "stated"  # "stated", or "standing" (a reference session's standing gap)


@dataclass(frozen=True, kw_only=True)
class Refit(Record):
    """The stated causes refitted in the simulator (``mujoco.sysid.optimize``), beside the tables' estimates."""

    tables: dict[str, list[float]]  # each cause's components as the tables estimate them (the start)
    simulator: dict[str, list[float]]  # as the simulator fits them
    simulator_ci95: dict[str, list[list[float]]]  # each component's 95% interval (mujoco.sysid.calculate_intervals)
    holds_tables: bool  # every component's simulator interval holds the tables' estimate
    excludes_zero: bool  # some component's simulator interval leaves out 0: the simulator needs the cause
    chi2_start: float
    chi2_end: float
    n_residuals: int
    n_parameters: int
    iterations: int  # Levenberg-Marquardt iterations taken
    pushes_simulated: int
    seconds: float


@dataclass(frozen=True, kw_only=True)
class ProbeKind(Record):
    """One kind of calibration probe under the leading hypothesis: its whitened chi-square."""

    kind: str  # friction | added_mass | free_stroke
    n: int
    chi2: float
    p_value: float
    worst_sd: float  # the largest |whitened residual|


@dataclass(frozen=True, kw_only=True)
class SimulatorCheck(Record):
    """What the simulator and the probes say of the stated causes (``summary.json``'s ``simulator``)."""

    scene: str
    corrected_xml: str  # the file's name in the report folder
    causes: list[CauseInScene]
    not_in_scene: list[str]  # parts of the explanation with no scene form (the discrepancy), said, not dropped
    n_pushes: int
    n_failed: int  # pushes whose simulation failed its checks (left out of both RMS)
    noise_sd: float
    noise_floor_rms: float | None
    # the uncorrected scene, boxes as the table alone fits them; the corrected scene, boxes as the causes fit them
    before_rms: float
    after_rms: float
    share_closed: float | None  # re-simulated
    predicted_before_rms: float
    predicted_after_rms: float
    predicted_share_closed: float | None  # the tables' (summary.cause_shrink)
    gap_left_sd: float  # the corrected scene's RMS gap over the noise sd (about 1: down to the noise)
    tolerance: float | None  # of the share: the tables' model floor over the gap above the noise floor
    disagrees: bool  # re-simulated and predicted shares differ by more than the tolerance
    simulator_contradicts: bool
    probes: list[ProbeKind] = field(default_factory=list)
    probes_contradict: bool = False
    refit: Refit | None = json_field(omit_none=True, default=None)
    seconds: float = 0.0


@dataclass(frozen=True)
class Checked:
    """A check and the corrected scene's MJCF text (written beside the report)."""

    check: SimulatorCheck
    corrected_xml: str


def stated_causes(model: Model, theta: np.ndarray) -> dict[str, np.ndarray]:
    """Each library cause of ``model`` at ``theta`` as its native components (a restricted tilt or anisotropy back
    to its two), by candidate name; the discrepancy is left out (it has no scene form)."""
    out = {}
    for c, sl in zip(model.candidates, model.slices(), strict=True):
        if c.is_library:
            out[c.name] = np.atleast_1d(c.native(np.asarray(theta, float)[sl]))
    return out


def _bounds(model: Model) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each library cause's native bounds."""
    out = {}
    for c in model.candidates:
        if c.is_library:
            lo, hi = np.asarray(c.lo, float), np.asarray(c.hi, float)
            if c.basis is not None:  # a restricted two-component cause: its native box is the disk's
                r = float(max(abs(lo[0]), abs(hi[0])))
                lo, hi = np.full(2, -r), np.full(2, r)
            out[c.name] = (lo, hi)
    return out


@dataclass(frozen=True)
class PushSet:
    """The pushes to simulate: (n,) speed, direction, and the rows of the log they stand for."""

    speed: np.ndarray
    direction: np.ndarray
    obj: np.ndarray


def simulate_log(
    scene: Scene,
    causes: dict[str, np.ndarray],
    pushes: PushSet,
    lm: np.ndarray,
    lu: np.ndarray,
    *,
    stop_time: bool = False,
    nthread: int = 0,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """The pushes in ``scene`` with ``causes`` written in, each box at exp(lm), exp(lu) of its object (K settings at
    once: lm, lu (K, N)): log displacement (K, n), log stop time (K, n) with ``stop_time`` (else None), and ok
    (K, n). A tilt needs a scene per push direction; everything else shares one. Replicate pushes (the same object,
    speed and direction) are simulated once: the simulator gives them the same outcome."""
    key = np.stack([pushes.obj.astype(float), pushes.speed, pushes.direction], 1)
    distinct, first, back = np.unique(key, axis=0, return_index=True, return_inverse=True)
    if distinct.shape[0] < pushes.speed.size:
        once = PushSet(speed=pushes.speed[first], direction=pushes.direction[first], obj=pushes.obj[first])
        log_d, log_t, ok = simulate_log(scene, causes, once, lm, lu, stop_time=stop_time, nthread=nthread)
        back = back.ravel()
        return log_d[:, back], None if log_t is None else log_t[:, back], ok[:, back]
    lm, lu = np.atleast_2d(lm), np.atleast_2d(lu)
    k, n = lm.shape[0], pushes.speed.size
    frames = stop_frame_times() if stop_time else None
    log_d, ok = np.full((k, n), np.nan), np.zeros((k, n), bool)
    log_t = np.full((k, n), np.nan) if stop_time else None
    groups = np.unique(pushes.direction) if "tilt" in causes else np.array([0.0])
    factor = friction_factor(causes, pushes.direction)
    for phi in groups:
        rows = np.flatnonzero(pushes.direction == phi) if "tilt" in causes else np.arange(n)
        spec = corrected_spec(scene.xml, cause_parameters(causes, direction=float(phi)), model_dir=scene.model_dir)
        model = spec.compile()
        obj = pushes.obj[rows]
        run = simulate_pushes_run(
            np.tile(pushes.speed[rows], k),
            np.exp(lm[:, obj]).ravel(),
            (np.exp(lu[:, obj]) * factor[rows]).ravel(),
            model=model,
            nthread=nthread,
            frame_times=frames,
        )
        res = run.result
        with np.errstate(divide="ignore", invalid="ignore"):
            log_d[:, rows] = np.log(res.displacement).reshape(k, rows.size)
        ok[:, rows] = (res.ok & (res.displacement > 0)).reshape(k, rows.size)
        if stop_time:
            t = stop_times(run.frames_box_qpos[:, :, :2], run.frames_time)
            with np.errstate(divide="ignore", invalid="ignore"):
                log_t[:, rows] = np.log(t).reshape(k, rows.size)
    return log_d, log_t, ok


def _rms_against(y: np.ndarray, sim: np.ndarray, keep: np.ndarray) -> float:
    return rms(np.where(keep, y - sim, 0.0), keep.astype(float))


def probe_kinds(problem: Problem, fit: JointFit) -> list[ProbeKind]:
    """Each kind of the log's probes, under ``fit``: whitened chi-square, its p-value and the worst row."""
    pr = problem.probes
    if pr is None:
        return []
    r = problem.probe_residuals(fit.model, fit.theta[None, :], fit.objects.lm[None, :], fit.objects.lu[None, :])[0]
    f, a = pr.log_friction.size, pr.n_added
    added_aux = sum(rows.size for _, rows in pr.aux_rows())
    s = pr.stroke_speed.size
    parts = {
        "friction": (0, f),
        "added_mass": (f, f + a + added_aux),
        "free_stroke": (f + a + added_aux, f + a + added_aux + s),
    }
    out = []
    for kind, (lo, hi) in parts.items():
        x = r[lo:hi]
        x = x[np.isfinite(x)]
        if x.size:
            chi2 = float(np.sum(x**2))
            out.append(
                ProbeKind(
                    kind=kind,
                    n=int(x.size),
                    chi2=chi2,
                    p_value=chi2_sf(chi2, float(x.size)),
                    worst_sd=float(np.max(np.abs(x))),
                )
            )
    return out


def refit_in_simulator(
    scene: Scene,
    problem: Problem,
    model: Model,
    causes: dict[str, np.ndarray],
    lm: np.ndarray,
    lu: np.ndarray,
    pushes: PushSet,
    *,
    iterations: int,
    nthread: int,
) -> Refit:
    """The causes and the boxes refitted to the log in the simulator by ``mujoco.sysid.optimize``, from the tables'
    estimates ``causes`` and boxes ``lm``, ``lu`` (N,); the module doc, step 3."""
    from mujoco import sysid

    t0 = time.perf_counter()
    bounds = _bounds(model)
    params = cause_parameters(causes, bounds=bounds)
    names = list(params.keys())
    sizes = [params[k].size for k in names]
    n_obj = lm.size
    free_m = problem.fixed_lm is None
    free_u = problem.fixed_lu is None
    # the boxes as parameters beside the causes (no modifier: a box's mass and friction are set per push)
    if free_m:
        params.add(
            sysid.Parameter("log_mass", lm, np.full(n_obj, problem.lm_range[0]), np.full(n_obj, problem.lm_range[1]))
        )
    if free_u:
        params.add(
            sysid.Parameter(
                "log_friction", lu, np.full(n_obj, problem.lu_range[0]), np.full(n_obj, problem.lu_range[1])
            )
        )
    n_cause = int(sum(sizes))
    use_t = "stop_time" in problem.aux and problem.log.stop_time is not None
    keep_d = problem.w_d > 0
    sd_d = np.broadcast_to(problem.sd_d, problem.y.shape)
    if use_t:
        rows_t = problem.aux_rows("stop_time")
        keep_t = problem.w_t[rows_t] > 0
        sd_t = np.broadcast_to(problem.sd_t, problem.w_t.shape)[rows_t]
        y_t = np.log(problem.log.stop_time)
    simulated = [0]

    def split(x: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
        out, k = {}, 0
        for name, size in zip(names, sizes, strict=True):
            out[name] = x[k : k + size]
            k += size
        m = x[k : k + n_obj] if free_m else problem.fixed_lm
        k += n_obj if free_m else 0
        u = x[k : k + n_obj] if free_u else problem.fixed_lu
        return out, m, u

    def residuals_at(xs: np.ndarray) -> np.ndarray:
        """(rows, K) whitened residuals at K parameter vectors (columns of ``xs``); a failed push reads 0 there."""
        parts = [split(xs[:, j]) for j in range(xs.shape[1])]
        out = np.zeros(((2 if use_t else 1) * pushes.speed.size, xs.shape[1]))
        # columns with the same causes share a scene: their boxes run in one batch
        keys = [tuple(np.concatenate([np.atleast_1d(v) for v in c.values()]).round(15)) for c, _, _ in parts]
        for key in dict.fromkeys(keys):
            cols = [j for j, k in enumerate(keys) if k == key]
            causes_j = parts[cols[0]][0]
            m = np.stack([parts[j][1] for j in cols])
            u = np.stack([parts[j][2] for j in cols])
            d, t, ok = simulate_log(scene, causes_j, pushes, m, u, stop_time=use_t, nthread=nthread)
            simulated[0] += pushes.speed.size * len(cols)
            for i, j in enumerate(cols):
                r = [np.where(keep_d & ok[i], (problem.y - d[i]) / sd_d, 0.0)]
                if use_t:
                    r.append(np.where(keep_t & ok[i] & np.isfinite(t[i]), (y_t - t[i]) / sd_t, 0.0))
                out[:, j] = np.concatenate(r)
        return out

    def residual_fn(x, _params):
        x = np.asarray(x, float)
        return [residuals_at(x.reshape(x.shape[0], -1))], None, None

    def jacobian(x, r):
        # grouped forward differences: each cause component alone, then every box's mass at once, every friction
        x = np.asarray(x, float).reshape(-1)
        r0 = np.asarray(r, float).reshape(-1)
        lo, hi = params.get_bounds()
        cols = []
        steps = []
        for i in range(n_cause):
            h = CAUSE_STEP * (hi[i] - lo[i])
            h = h if x[i] + h <= hi[i] else -h
            xi = x.copy()
            xi[i] += h
            cols.append(xi)
            steps.append(h)
        blocks = []
        k = n_cause
        for free in (free_m, free_u):
            if free:
                xi = x.copy()
                h = np.where(x[k : k + n_obj] + BOX_STEP <= hi[k : k + n_obj], BOX_STEP, -BOX_STEP)
                xi[k : k + n_obj] += h
                blocks.append((k, h))
                cols.append(xi)
                k += n_obj
        rs = residuals_at(np.stack(cols, axis=1))
        jac = np.zeros((r0.size, x.size))
        for i in range(n_cause):
            jac[:, i] = (rs[:, i] - r0) / steps[i]
        row_obj = np.tile(pushes.obj, 2 if use_t else 1)
        for b, (k, h) in enumerate(blocks):
            diff = (rs[:, n_cause + b] - r0) / h[row_obj]
            jac[np.arange(r0.size), k + row_obj] = diff
        return jac

    x0 = params.as_vector()
    r_start = residual_fn(x0, params)[0][0][:, 0]
    trace = io.StringIO()
    # mu_factor 10: at an optimum the simulator's own roughness makes every trial step fail, and MuJoCo's default
    # (10^0.1) would spend about 140 passes over the log raising the regulariser to its cap; xtol and gtol stop it
    # once a step is below a thousandth of the parameters, or the gradient below 1e-6 chi-square per unit
    opt, result = sysid.optimize(
        params,
        residual_fn,
        optimizer="mujoco",
        verbose=False,
        max_iters=iterations,
        jacobian=jacobian,
        mu_factor=10.0,
        xtol=1e-3,
        gtol=1e-6,
        output=trace,
    )
    log.debug("simulator refit:\n%s", trace.getvalue())
    x1 = opt.as_vector()
    r_end = residual_fn(x1, opt)[0][0][:, 0]
    # the Jacobian MuJoCo's solver took at the final point
    jac = np.asarray(result.jac, float)
    _, half = sysid.calculate_intervals([r_end], jac)
    tables, sim, ci = {}, {}, {}
    holds, excludes = True, False
    k = 0
    for name, size in zip(names, sizes, strict=True):
        t_v = np.atleast_1d(causes[name]).astype(float)
        s_v = x1[k : k + size]
        w = half[k : k + size]
        tables[name] = t_v.tolist()
        sim[name] = s_v.tolist()
        ci[name] = [[float(a - b), float(a + b)] for a, b in zip(s_v, w, strict=True)]
        holds &= bool(np.all(np.abs(t_v - s_v) <= w))
        excludes |= bool(np.any(np.abs(s_v) > w))
        k += size
    return Refit(
        tables=tables,
        simulator=sim,
        simulator_ci95=ci,
        holds_tables=holds,
        excludes_zero=excludes,
        chi2_start=float(np.sum(r_start**2)),
        chi2_end=float(np.sum(r_end**2)),
        n_residuals=int(r_end.size),
        n_parameters=int(x1.size),
        iterations=max(len(result.extras.get("objective", [])) - 1, 0),
        pushes_simulated=int(simulated[0]),
        seconds=round(time.perf_counter() - t0, 3),
    )


def check_causes(
    *,
    problem: Problem,
    leading: JointFit,
    raw_problem: Problem,
    base: JointFit,
    model: Model,
    theta: np.ndarray,
    standing: dict[str, np.ndarray] | None,
    predicted: SessionShrink,
    model_floor: float | None,
    alpha: float,
    scene: Scene,
    refit: bool,
    iterations: int,
    nthread: int = 0,
) -> Checked:
    """The module's four steps for the stated causes (``model`` at ``theta``, fitted on ``raw_problem``, the log
    against the table, whose table-alone fit is ``base``); ``problem`` and ``leading``: the diagnosis's own problem
    and leading fit (their probes). ``standing``: a reference session's stated causes, written into the scene too.
    ``predicted``: the tables' shrink of the same causes on the same log (the summary's ``cause_shrink``)."""
    t0 = time.perf_counter()
    causes = stated_causes(model, theta)
    in_scene = {**(standing or {}), **causes}
    for name, value in (standing or {}).items():
        if name in causes:  # what changed is measured on top of the standing gap
            in_scene[name] = value + causes[name]
    xml = corrected_spec(scene.xml, cause_parameters(in_scene), model_dir=scene.model_dir).to_xml()
    p = raw_problem
    pushes = PushSet(speed=p.log.speed, direction=p.log.direction, obj=p.obj)
    lms, lus = _refit_boxes(p, model, theta, base)
    keep = p.w_d > 0
    before_d, _, ok0 = simulate_log(scene, {}, pushes, base.objects.lm, base.objects.lu, nthread=nthread)
    after_d, _, ok1 = simulate_log(scene, causes, pushes, lms, lus, nthread=nthread)
    good = keep & ok0[0] & ok1[0]
    before = _rms_against(p.y, before_d[0], good)
    after = _rms_against(p.y, after_d[0], good)
    n, n_obj, k = p.n_rows, p.n_obj, p.k_free
    floor = p.noise_d * np.sqrt(max(n - k * n_obj, 0) / n) if n else None
    share = share_closed(before, after, floor)
    tol = None
    if model_floor is not None and floor is not None and predicted.before_rms - floor > 1e-12:
        tol = float(model_floor / (predicted.before_rms - floor))
    disagrees, short = compare_shares(share, predicted.cause_share_closed, tol)
    kinds = probe_kinds(problem, leading)
    probes_bad = any(pk.p_value < alpha / len(kinds) for pk in kinds)
    fitted = None
    if refit and causes:
        fitted = refit_in_simulator(scene, p, model, causes, lms, lus, pushes, iterations=iterations, nthread=nthread)
    check = SimulatorCheck(
        scene=scene.name,
        corrected_xml=CORRECTED_XML,
        causes=[
            CauseInScene(
                cause=name,
                value=np.atleast_1d(v).astype(float).tolist(),
                mechanism=MECHANISM[name],
                mjcf=name not in NO_MJCF_FORM,
                source="stated" if name in causes else "standing",
            )
            for name, v in in_scene.items()
        ],
        not_in_scene=["discrepancy"] if leading.model.discrepancy is not None else [],
        n_pushes=int(n),
        n_failed=int((~(ok0[0] & ok1[0])).sum()),
        noise_sd=float(p.noise_d),
        noise_floor_rms=floor,
        before_rms=before,
        after_rms=after,
        share_closed=share,
        predicted_before_rms=float(predicted.before_rms),
        predicted_after_rms=float(predicted.cause_rms),
        predicted_share_closed=predicted.cause_share_closed,
        gap_left_sd=float(after / p.noise_d) if p.noise_d > 0 else float("nan"),
        tolerance=tol,
        disagrees=bool(disagrees),
        simulator_contradicts=bool(short),
        probes=kinds,
        probes_contradict=bool(probes_bad),
        refit=fitted,
        seconds=round(time.perf_counter() - t0, 3),
    )
    return Checked(check=check, corrected_xml=xml)


def compare_shares(share: float | None, predicted: float | None, tolerance: float | None) -> tuple[bool, bool]:
    """(disagree, contradict): whether the re-simulated ``share`` and the ``predicted`` one differ by more than
    ``tolerance``, and whether the simulator contradicts the stated causes: they disagree and, in the simulator, the
    causes leave more than :data:`SHORTFALL` of the log's gap above the noise open beyond what the tables say they
    leave (the shares differ by more than it). Nothing to compare where either share or the tolerance is None."""
    if share is None or predicted is None or tolerance is None:
        return False, False
    disagree = abs(share - predicted) > tolerance
    return disagree, bool(disagree and share < predicted - SHORTFALL)


def _refit_boxes(p: Problem, model: Model, theta: np.ndarray, base: JointFit) -> tuple[np.ndarray, np.ndarray]:
    """The boxes as the tables fit them under ``model`` at ``theta``, from the table-alone fit ``base``."""
    if not model.dim:
        return base.objects.lm, base.objects.lu
    lms, lus, _ = p.refine_many(model, theta[None, :], base.objects.lm[None, :], base.objects.lu[None, :])
    return lms[0], lus[0]
