"""Each step of the diagnosis on small synthetic logs of the closed-form table (no simulation, no effect tables).

The logs' pushes follow ``analytic_log_d`` with the speed and friction effects the
diagnostic models without tables (speed gain and offset, anisotropic friction), plus
Gaussian noise; replicate pushes repeat a push with fresh noise.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from conftest import analytic_log_d
from imply.diagnose.analysis import DiagnosisConfig, Summary, baseline_fit, baseline_residuals, diagnose
from imply.diagnose.inference.aliasing import aliasing
from imply.diagnose.inference.fit import Problem
from imply.diagnose.inference.hypotheses import NO_EFFECT, enumerate_hypotheses, log_evidence
from imply.diagnose.inference.localisation import localise
from imply.diagnose.inference.model_error import model_error
from imply.diagnose.inference.noise import estimate_noise
from imply.diagnose.inference.shrinkage import heldout, share_closed, shrinkage
from imply.diagnose.inputs.pushlog import PushLog
from imply.diagnose.physics import candidates
from imply.diagnose.physics.candidates import Model
from imply.diagnose.physics.prediction import distinct_blocks

SPEEDS = (0.3, 0.5, 0.7, 0.9)
OPTS = DiagnosisConfig(grid=41, scan=5, max_effects=2)
TABLELESS = ["speed_gain", "speed_offset", "anisotropic"]


def make_log(
    *,
    seed: int = 0,
    gain: float = 0.0,
    offset: float = 0.0,
    aniso: tuple[float, float] = (0.0, 0.0),
    sd: float = 0.02,
    replicates: int = 2,
    n_objects: int = 6,
    measured_mass: bool = True,
    outlier: float = 0.0,
) -> PushLog:
    """A push log of the closed-form world: each object pushed once per speed in a random direction."""
    rng = np.random.default_rng(seed)
    mass = np.geomspace(0.3, 1.5, n_objects)
    friction = rng.permutation(np.geomspace(0.15, 0.45, n_objects))
    obj = np.repeat(np.arange(n_objects), len(SPEEDS))
    v = np.tile(SPEEDS, n_objects).astype(float)
    phi = rng.uniform(0, 2 * np.pi, v.size)
    obj, v, phi = (np.repeat(x, replicates) for x in (obj, v, phi))
    mu = friction[obj] * (1 + aniso[0] * np.cos(2 * phi) + aniso[1] * np.sin(2 * phi))
    log_d = analytic_log_d(v * (1 + gain) + offset, mass[obj], mu) + rng.normal(0, sd, v.size)
    log_d[5] += outlier
    names = [f"box{i}" for i in obj]
    frame = pd.DataFrame({"object_id": names, "speed": v, "displacement": np.exp(log_d), "direction": phi})
    return PushLog(
        path="<synthetic>",
        frame=frame,
        objects=[f"box{i}" for i in range(n_objects)],
        obj=obj,
        speed=v,
        displacement=np.exp(log_d),
        direction=phi,
        has_direction=True,
        mass=mass if measured_mass else None,
    )


def problem_of(log: PushLog, table) -> Problem:
    return Problem.of(log, table, None, grid=OPTS.grid)


# -- the problem: immutable, one prediction shape ------------------------------------------


def test_problem_is_changed_only_into_a_new_one(analytic_table):
    prob = problem_of(make_log(), analytic_table)
    noisy = prob.with_noise(0.05, None)
    assert prob.noise_d == 1.0 and noisy.noise_d == 0.05
    np.testing.assert_allclose(noisy.sd_d, 0.05)
    np.testing.assert_allclose(prob.sd_d, 1.0)
    weighted = noisy.with_weights(np.r_[0.0, np.ones(prob.y.size - 1)], None)
    assert weighted.n_rows == prob.n_rows - 1 and noisy.n_rows == prob.n_rows
    with_err = weighted.with_model_error(np.full(prob.y.size, 0.12), None)
    np.testing.assert_allclose(with_err.sd_d, 0.13)
    np.testing.assert_allclose(weighted.sd_d, 0.05)
    with pytest.raises(AttributeError):
        prob.noise_d = 2.0


def test_prediction_keeps_what_it_extrapolated(analytic_table):
    prob = problem_of(make_log(), analytic_table)
    lm, lu = np.zeros(prob.n_cond) + np.log(0.5), np.zeros(prob.n_cond) + np.log(0.3)
    inside = prob.predict(Model((candidates.CANDIDATES["speed_gain"],)), np.array([0.05]), lm, lu)
    size_d, size_t = inside.extrapolation_sizes()
    assert not size_d.any() and size_t is None and inside.extrapolated_d is None
    # +0.2 carries the 0.9 m/s pushes to 1.08 m/s, beyond the table's 1.05
    beyond = prob.predict(Model((candidates.CANDIDATES["speed_offset"],)), np.array([0.18]), lm, lu)
    size_d, _ = beyond.extrapolation_sizes()
    assert (size_d[prob.c_v == 0.9] > 0).all() and not size_d[prob.c_v < 0.8].any()
    exact = analytic_log_d(prob.c_v + 0.18, 0.5, 0.3)
    np.testing.assert_allclose(beyond.log_d, exact, atol=0.01)


def test_equal_blocks_are_found_and_spread_back():
    a, b = np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 4.0])
    col = np.concatenate([a, b, a, a])
    other = np.concatenate([b, b, b, b])
    rows, back = distinct_blocks(4, col, other)
    np.testing.assert_array_equal(rows, np.arange(6))  # the first two blocks
    np.testing.assert_array_equal(col[rows][back], col)
    np.testing.assert_array_equal(other[rows][back], other)
    # a block equal in one column but not in the other is distinct
    assert distinct_blocks(2, np.r_[a, a], np.r_[a, b]) == (None, None)
    assert distinct_blocks(1, a) == (None, None)


def test_settings_that_share_points_give_the_residuals_of_one_at_a_time(analytic_table):
    prob = problem_of(make_log(), analytic_table)
    model = Model((candidates.CANDIDATES["speed_gain"],))
    thetas = np.array([[0.05], [0.05], [0.1], [0.05]])
    lms = np.repeat(np.log(np.full((1, prob.n_obj), 0.5)), 4, 0)
    lus = np.repeat(np.log(np.full((1, prob.n_obj), 0.3)), 4, 0)
    lus[3] += 0.01  # the last setting moves every push's friction: a point of its own
    together = prob.residuals(model, thetas, lms, lus)
    alone = np.concatenate([prob.residuals(model, thetas[k : k + 1], lms[k : k + 1], lus[k : k + 1]) for k in range(4)])
    np.testing.assert_array_equal(together, alone)


# -- step 1: noise and outliers --------------------------------------------------------------


def test_noise_from_replicates_and_the_outlier_left_out(analytic_table):
    prob = problem_of(make_log(seed=3, sd=0.02, outlier=0.8), analytic_table)
    noise = estimate_noise(prob, OPTS)
    d = noise.displacement
    assert d.source == "replicate pushes" and abs(d.sd - 0.02) < 0.008
    assert d.outliers == [5] and d.set_aside == [4]  # its replicate is set aside with it
    assert noise.weights_d[4] == 0 and noise.weights_d[5] == 0 and noise.weights_d.sum() == prob.y.size - 2
    assert noise.stop_time is None and noise.weights_t is None
    fitted = noise.apply(prob)
    assert fitted.noise_d == d.sd and fitted.n_rows == prob.y.size - 2 and prob.n_rows == prob.y.size


def test_noise_option_and_no_replicates(analytic_table):
    prob = problem_of(make_log(seed=4), analytic_table)
    assert estimate_noise(prob, OPTS.replace(noise_sd=0.05)).displacement.source == "option"
    single = estimate_noise(problem_of(make_log(seed=4, replicates=1), analytic_table), OPTS).displacement
    assert single.source.startswith("residual variance") and single.replicate_pairs == 0


# -- step 2: localisation --------------------------------------------------------------------


def test_localisation_finds_the_speed_band_off(analytic_table):
    prob = problem_of(make_log(seed=5, sd=0.01), analytic_table)
    prob, base = baseline_fit(estimate_noise(prob, OPTS).apply(prob), OPTS)
    resid = np.where(prob.v == 0.9, 0.05, 0.0) + np.random.default_rng(0).normal(0, 0.01, prob.y.size)
    where = localise(prob, base.objects, resid, alpha=0.05)
    fast = [b for b in where.speed if b.band == "0.9"][0]
    assert fast.differs and abs(fast.mean - 0.05) < 0.01 and fast.n_objects == 6
    assert "speed=0.9" in where.regions_beyond_noise
    assert not [b for b in where.speed if b.band == "0.3"][0].differs
    assert where.direction is not None and len(where.object) == 6


# -- step 3: aliasing ----------------------------------------------------------------------


def test_a_speed_gain_with_weighed_masses_is_aliased_with_friction(analytic_table):
    prob = problem_of(make_log(seed=6), analytic_table)
    prob, base = baseline_fit(estimate_noise(prob, OPTS).apply(prob), OPTS)
    alias = aliasing(prob, candidates.get(TABLELESS), fit=base.objects, opts=OPTS)
    gain = alias.effects["speed_gain"]
    assert gain.absorbed_by_fit > 0.5 and "friction change" in gain.fit_alias
    assert gain.fit_alias.startswith("a speed gain here is") and gain.fit_alias.endswith("unless friction is measured")
    assert alias.effects["anisotropic"].identifiable and alias.effects["anisotropic"].fit_alias == ""
    assert alias.aliased_with_fit == [n for n in TABLELESS if alias.effects[n].fit_alias]
    assert set(alias.classes) == {a.cls for a in alias.effects.values() if a.identifiable}


# -- step 4: forward selection ---------------------------------------------------------------


def _hypotheses(log: PushLog, table):
    prob = problem_of(log, table)
    prob, base = baseline_fit(estimate_noise(prob, OPTS).apply(prob), OPTS)
    cands = candidates.get(TABLELESS)
    alias = aliasing(prob, cands, fit=base.objects, opts=OPTS)
    hyps = enumerate_hypotheses(
        prob,
        base,
        cands,
        alias=alias,
        max_effects=OPTS.max_effects,
        screen=OPTS.screen,
        scan=OPTS.scan,
        n_folds=OPTS.folds,
    )
    return prob, base, hyps


def test_the_hypotheses_weigh_a_speed_offset_first(analytic_table):
    prob, base, hyps = _hypotheses(make_log(seed=7, offset=0.05), analytic_table)
    lead = hyps.table[0]
    assert lead.effects == ["speed_offset"] and lead.weight > 0.5
    assert abs(lead.estimates[0].magnitude - 0.05) < 0.01
    assert [h.weight for h in hyps.table] == sorted((h.weight for h in hyps.table), reverse=True)
    assert abs(sum(h.weight for h in hyps.table) - 1.0) < 1e-9
    # every hypothesis that weighs holds the offset; a small gain beside it cannot be ruled out
    assert sum(h.weight for h in hyps.table if "speed_offset" in h.effects) > 0.99
    # the baseline, each effect alone, every pair (three classes at most, max_effects 2): 1 + 3 + 3
    labels = {h.label for h in hyps.table}
    assert {NO_EFFECT, "speed_gain", "speed_offset", "anisotropic", "speed_gain+speed_offset"} <= labels
    assert len(labels) == len(hyps.table)  # each hypothesis once


def test_effects_the_discrepancy_holds_never_sit_beside_it(analytic_table):
    prob = problem_of(make_log(seed=7, offset=0.05), analytic_table)
    prob, base = baseline_fit(estimate_noise(prob, OPTS).apply(prob), OPTS)
    cands = [*candidates.get(TABLELESS), candidates.discrepancy_candidate(aux=prob.aux, prior_sd=0.1, bound=1.0)]
    alias = aliasing(prob, cands, fit=base.objects, opts=OPTS)

    def table(held):
        return enumerate_hypotheses(
            prob,
            base,
            cands,
            alias=alias,
            max_effects=OPTS.max_effects,
            screen=OPTS.screen,
            scan=OPTS.scan,
            n_folds=OPTS.folds,
            held=held,
        ).table

    free, held = table(set()), table({"speed_gain"})
    assert any(h.discrepancy and "speed_gain" in h.effects for h in free)
    assert not any(h.discrepancy and "speed_gain" in h.effects for h in held)
    # the held effect stays a hypothesis without the discrepancy, and the others keep theirs with it
    labels = {h.label for h in held}
    assert {"speed_gain", "speed_gain+speed_offset", "speed_offset+discrepancy", "discrepancy"} <= labels
    assert {h.label for h in free} - labels == {h.label for h in free if h.discrepancy and "speed_gain" in h.effects}


def test_the_baseline_carries_the_weight_of_a_null_log(analytic_table):
    _, base, hyps = _hypotheses(make_log(seed=8), analytic_table)
    assert hyps.table[0].label == NO_EFFECT and hyps.fits[0] is base
    assert hyps.table[0].weight > 0.5


def test_the_evidence_pays_for_an_effect_it_does_not_need(analytic_table):
    # the same fit quality, one more parameter with a wide prior: lower evidence (the Occam factor)
    prob, base, hyps = _hypotheses(make_log(seed=8), analytic_table)
    gain = next(f for f, h in zip(hyps.fits, hyps.table, strict=True) if h.label == "speed_gain")
    assert gain.sse <= base.sse + 1e-9
    assert log_evidence(gain, 1.0) < log_evidence(base, 1.0) - 1.0
    # a larger dispersion shrinks every difference of chi-squares
    assert abs(log_evidence(base, 4.0) - log_evidence(base, 1.0)) < abs(log_evidence(base, 1.0))


def test_model_error_counts_the_numerical_floor_and_interpolation(analytic_table):
    prob = problem_of(make_log(seed=9), analytic_table)
    objects = prob.initial_fit()
    # a speed offset reads the table between its speeds, where cubic and linear interpolation differ
    model, theta = Model((candidates.CANDIDATES["speed_offset"],)), np.array([0.023])
    err = model_error(prob, model, theta, objects=objects, opts=OPTS.replace(model_floor=0.01))
    interpolation, _ = prob.interpolation_indicator(objects, model, theta)
    assert interpolation.max() > 1e-4
    np.testing.assert_allclose(err.log_d, np.sqrt(0.01**2 + interpolation**2))
    assert err.log_t is None
    assert (err.apply(prob).sd_d > prob.sd_d).all()


# -- step 5: shrinkage ---------------------------------------------------------------------


def test_share_closed():
    assert share_closed(0.1, 0.02, 0.02) == pytest.approx(1.0)
    assert share_closed(0.1, 0.06, 0.02) == pytest.approx(0.5)
    assert share_closed(0.02, 0.01, 0.02) is None  # no gap above the floor
    assert share_closed(0.1, 0.05, None) is None


def test_shrinkage_of_a_found_speed_offset(analytic_table):
    prob, base, hyps = _hypotheses(make_log(seed=7, offset=0.05), analytic_table)
    rd, rt = baseline_residuals(prob, base)
    held = heldout(prob, hyps.fits[0], 0)
    shrink = shrinkage(prob, hyps.fits[0], resid_d=rd, resid_t=rt, held=held)
    assert shrink.effects == ["speed_offset"] and shrink.effect == "speed_offset"
    assert shrink.before_rms > 3 * shrink.after_rms and shrink.gap_share_closed > 0.9
    assert shrink.judged == shrink.both_share_closed and shrink.stop_time_share_closed is None
    assert shrink.lack_of_fit.stop_time is None and shrink.lack_of_fit.displacement.n == prob.n_rows


# -- the whole pipeline, and its summary as JSON -------------------------------------------


def test_pipeline_names_anisotropy_and_its_summary_reads_back(analytic_table, tmp_path):
    from imply.diagnose.report import write_report

    prob = problem_of(make_log(seed=10, aniso=(0.1, 0.1)), analytic_table)
    diag = diagnose(prob, candidates.get(TABLELESS), OPTS.replace(model_floor=0.0, max_effects=1))
    s = diag.summary
    assert s.verdict.effects == ["anisotropic"], s.verdict
    assert s.verdict.identification == "one_cause" and s.verdict.adequacy == "explained"
    aniso = s.effects[0]
    assert abs(aniso.magnitude - np.hypot(0.1, 0.1)) < 0.03
    assert abs((aniso.azimuth_deg - 22.5 + 90) % 180 - 90) < 10
    assert s.sentence.startswith("The gap is explained (the leading hypothesis closes ")
    assert ", and by one cause: friction is 1" in s.sentence and " higher along 2" in s.sentence
    assert s.inclusion["anisotropic"] > 0.95
    write_report(diag, tmp_path)
    written = json.loads((tmp_path / "summary.json").read_text())
    assert written["effects"][0]["class"] == "anisotropic" and "cls" not in written["effects"][0]
    assert written["verdict"]["identification"] == "one_cause"
    ranked = {r["effect"]: r for r in written["ranking"]}
    assert "azimuth_deg" in ranked["anisotropic"] and "azimuth_deg" not in ranked["speed_gain"]  # absent, not null
    back = Summary.from_dict(written)
    assert back.to_dict() == written
    assert (back.verdict, back.effects, back.shrinkage, back.options) == (s.verdict, s.effects, s.shrinkage, s.options)
    assert back.hypotheses == s.hypotheses
    # one contender: nothing to separate, and the next pushes file says so with its header alone
    assert s.next_pushes is None
    assert (tmp_path / "next_pushes.csv").read_text().strip() == "object_id,speed,direction,mass"


def test_a_joint_fit_with_a_box_pulled_past_the_table_reaches_the_profiled_optimum(analytic_table):
    # box 0's friction, 0.07, lies below the table's 0.1: its fit sits at the bound and the pushes pull it further
    log = make_log(gain=0.12, measured_mass=False, seed=3)
    rng = np.random.default_rng(3)
    mu = np.where(log.obj == 0, 0.07, np.geomspace(0.15, 0.45, 6)[log.obj])
    m = np.geomspace(0.3, 1.5, 6)[log.obj]
    log_d = analytic_log_d(log.speed * 1.12, m, mu) + rng.normal(0, 0.02, log.speed.size)
    log = PushLog(**{**log.__dict__, "displacement": np.exp(log_d)})
    prob = problem_of(log, analytic_table).with_noise(0.02, None)
    model = Model((candidates.CANDIDATES["speed_gain"],))
    start = prob.initial_fit()
    fit = prob.fit(model, np.array([0.0]), start)
    assert fit.objects.lu[0] == pytest.approx(prob.lu_range[0])
    # the profile over the gain's range, every box refitted within the table's range at each value
    gains = np.linspace(model.lo()[0], model.hi()[0], 401)[:, None]
    _, _, sse = prob.refine_many(model, gains, start.lm[None, :], start.lu[None, :], iters=30)
    assert fit.sse <= sse.sum(1).min() + 0.05
    assert fit.iterations < 25
