"""Calibration probes in every hypothesis's fit: the free stroke's servo physics against MuJoCo, and what each probe
does to a fit of the closed-form table's logs (test_steps.make_log)."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest
from test_steps import OPTS, make_log

from conftest import analytic_log_d
from imply.diagnose.inference.fit import Problem
from imply.diagnose.inference.shrinkage import heldout, shrinkage
from imply.diagnose.inputs.observables import Observables
from imply.diagnose.inputs.probes import Probes
from imply.diagnose.physics import candidates
from imply.diagnose.physics.candidates import Model
from imply.diagnose.physics.probe_fit import Servo
from imply.sim.scene import SceneConfig, build_model

SCENE = {"pusher_mass": 0.2, "pusher_kv": 80.0, "pusher_force_limit": 100.0, "stroke": 0.01}


def mujoco_free_stroke(speed: float, *, force_limit: float = 100.0) -> float:
    """The scene's pusher stroking with the box moved away, stepped finely with RK4: its mean speed (m/s)."""
    scene = SceneConfig(pusher_force_limit=force_limit)
    model = build_model(scene)
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = 1e-5
    data = mujoco.MjData(model)
    box = model.jnt_qposadr[model.joint("box").id]
    push = model.jnt_qposadr[model.joint("push").id]
    data.qpos[box] += 10.0
    mujoco.mj_forward(model, data)
    data.ctrl[0] = speed
    before = (0.0, 0.0)
    while data.qpos[push] < scene.stroke:
        before = (data.time, data.qpos[push])
        mujoco.mj_step(model, data)
    # the crossing, interpolated within the last step
    t = before[0] + (scene.stroke - before[1]) / (data.qpos[push] - before[1]) * (data.time - before[0])
    return scene.stroke / t


@pytest.mark.parametrize("force_limit", [100.0, 30.0])
def test_the_free_stroke_servo_matches_a_fine_mujoco_stroke(force_limit):
    servo = Servo(0.2, 80.0, force_limit, 0.01)
    speeds = np.array([0.15, 0.6, 1.05])
    simulated = np.array([mujoco_free_stroke(v, force_limit=force_limit) for v in speeds])
    np.testing.assert_allclose(np.log(servo.mean_speed(speeds)), np.log(simulated), atol=2e-3)
    # the lag is large at speed: what the pushes' table would read as a slow pusher if strokes were taken as v
    assert servo.mean_speed(np.array([1.0]))[0] < 0.85


def probes_of(log, *, friction=None, friction_sd=0.06, strokes=(), added=None) -> Probes:
    """Probes for a synthetic log: friction readings per object, free strokes ((speed, measured) pairs), added-mass
    pushes ((object, speed, displacement, load) rows)."""
    n = len(log.objects)
    added = np.zeros((0, 4)) if added is None else np.asarray(added, float)
    strokes = np.asarray(strokes, float).reshape(-1, 2)
    return Probes(
        path="<synthetic>",
        free_stroke_speed=strokes[:, 0],
        free_stroke_pusher_speed=strokes[:, 1],
        friction=np.full(n, np.nan) if friction is None else np.asarray(friction, float),
        friction_sd=np.full(n, friction_sd),
        friction_speed=np.full(n, np.nan),
        friction_direction=np.full(n, np.nan),
        added_obj=added[:, 0].astype(int),
        added_speed=added[:, 1],
        added_displacement=added[:, 2],
        added_mass=added[:, 3],
        added_direction=np.zeros(len(added)),
        added_stop_time=np.full(len(added), np.nan),
        added_pusher_speed=np.full(len(added), np.nan),
    )


def test_added_mass_pushes_are_predicted_at_the_loaded_mass(analytic_table):
    log = make_log(seed=1, sd=0.0, replicates=1, measured_mass=False)
    # make_log's objects (its first draws)
    mass = np.geomspace(0.3, 1.5, 6)
    friction = np.random.default_rng(1).permutation(np.geomspace(0.15, 0.45, 6))
    rows = [(i, 0.9, np.exp(analytic_log_d(0.9, mass[i] + 0.4, friction[i])), 0.4) for i in range(6)]
    table = replace(analytic_table, meta={"scene": SCENE})
    prob = Problem.of(replace(log, probes=probes_of(log, added=rows)), table, None, grid=OPTS.grid)
    prob = prob.with_noise(0.02, None)
    lms, lus = np.log(mass)[None, :], np.log(friction)[None, :]
    np.testing.assert_allclose(prob.residuals(Model(), np.zeros((1, 0)), lms, lus), 0.0, atol=1e-6)
    assert prob.residuals(Model(), np.zeros((1, 0)), lms, lus).shape[1] == log.n + 6
    # an object whose mass is off by 30% misses its loaded push by more than half a noise sd
    off = prob.probe_residuals(Model(), np.zeros((1, 0)), lms + np.log(1.3), lus)
    assert np.abs(off).min() > 0.5


def test_a_friction_reading_is_a_prior_of_its_stated_weight(analytic_table):
    log = make_log(seed=2, sd=0.02, replicates=1, measured_mass=False)
    table = replace(analytic_table, meta={"scene": SCENE})
    alone = Problem.of(log, table, None, grid=OPTS.grid).with_noise(0.02, None)
    base = alone.initial_fit()
    reading = np.exp(base.lu) * 1.3  # every reading 30% above what the pushes say

    def fitted(sd):
        probes = probes_of(log, friction=reading, friction_sd=sd * reading)
        prob = Problem.of(replace(log, probes=probes), table, None, grid=OPTS.grid).with_noise(0.02, None)
        return prob.initial_fit().lu

    # a tight reading wins over the pushes (its mass moves to agree), a loose one is nearly ignored
    assert np.abs(fitted(0.005) - np.log(reading)).max() < 0.05
    assert np.abs(fitted(2.0) - base.lu).max() < 0.02
    off = Problem.of(
        replace(log, probes=probes_of(log, friction=reading)),
        table,
        None,
        grid=OPTS.grid,
        observables=Observables(probes=False),
    )
    assert off.probes is None


def test_a_friction_test_is_read_along_its_drag(analytic_table):
    """Anisotropic friction: each box's pull test, dragged along its first push, reads the friction along that
    direction. Told the drag's direction, the fit reads the tests as the pushes do; read as the friction itself,
    tight tests pull every box's friction off and miss by many of their sds."""
    aniso = (0.2, 0.0)
    log = make_log(seed=4, aniso=aniso, sd=0.02)
    friction = np.random.default_rng(4).permutation(np.geomspace(0.15, 0.45, 6))  # make_log's objects
    first = np.array([log.direction[np.flatnonzero(log.obj == i)[0]] for i in range(6)])
    reading = friction * (1 + aniso[0] * np.cos(2 * first) + aniso[1] * np.sin(2 * first))
    table = replace(analytic_table, meta={"scene": SCENE})
    model = Model((candidates.CANDIDATES["anisotropic"],))

    def fit(direction):
        probes = replace(
            probes_of(log, friction=reading, friction_sd=0.005 * reading),
            friction_speed=np.full(6, 0.1),
            friction_direction=direction,
        )
        prob = Problem.of(replace(log, probes=probes), table, None, grid=OPTS.grid).with_noise(0.02, None)
        f = prob.fit(model, np.zeros(2), prob.initial_fit())
        rows = prob.probe_residuals(model, f.theta[None, :], f.objects.lm[None, :], f.objects.lu[None, :])[0]
        return f, float(np.sum(rows**2))

    told, told_ss = fit(first)
    blind, blind_ss = fit(np.full(6, np.nan))
    assert np.allclose(told.theta, aniso, atol=0.02)
    assert np.abs(np.exp(told.objects.lu) / friction - 1).max() < 0.02
    assert told_ss < 6 * 4  # six tests, each within a couple of its sds
    assert blind_ss > 10 * max(told_ss, 1.0)


def test_free_strokes_measure_a_speed_gain_that_friction_aliases(analytic_table):
    """With weighed masses a speed gain and friction are nearly one direction in the closed-form table; free
    strokes measure the gain with no box."""
    gain = 0.06
    log = make_log(seed=6, gain=gain, sd=0.02)
    servo = Servo.of_scene(SCENE)
    speeds = np.repeat([0.3, 0.6, 0.9], 2)
    rng = np.random.default_rng(0)
    measured = servo.mean_speed(speeds * (1 + gain)) * np.exp(rng.normal(0, 0.005, speeds.size))
    table = replace(analytic_table, meta={"scene": SCENE})
    model = Model((candidates.CANDIDATES["speed_gain"],))

    def fit(with_strokes: bool):
        probes = probes_of(log, strokes=np.stack([speeds, measured], 1)) if with_strokes else None
        prob = Problem.of(replace(log, probes=probes), table, None, grid=OPTS.grid).with_noise(0.02, None)
        start = prob.initial_fit()
        f = prob.fit(model, np.array([0.0]), start)
        return float(f.theta[0]), float(np.sqrt(f.covariance()[0, 0]))

    g0, sd0 = fit(False)
    g1, sd1 = fit(True)
    assert abs(g1 - gain) < 0.01 and sd1 < sd0 / 3


def test_the_fit_reads_what_the_options_ask_by_default():
    from imply.diagnose.analysis import DiagnosisConfig

    assert DiagnosisConfig().observables() == Observables()


# -- the launch left free -----------------------------------------------------------------------------------------


def analytic_log_t(v, m, mu):
    """A Coulomb slide's stop time in the closed-form world: T = v / (mu g), as a log."""
    return np.log(v) - np.log(mu) - np.log(9.81)


class StopTimeTables:
    """Just enough of :class:`imply.diagnose.physics.effect_tables.EffectTables` for the baseline's stop times."""

    aux = ("stop_time",)

    def aux_index(self, name):
        return 0

    def aux_log(self, v, m, mu):
        return analytic_log_t(np.asarray(v), np.asarray(m), np.asarray(mu))[:, None]

    def aux_log_at(self, pts, cols):
        v, log_m, log_mu = np.asarray(pts).T
        return analytic_log_t(v, np.exp(log_m), np.exp(log_mu))[:, None]

    def aux_interpolation_indicator(self, v, m, mu):
        return np.zeros((np.asarray(v).size, 1))


def launched_log(launch_sd: float, seed: int = 3):
    """A closed-form log with stop times whose every push leaves the pusher at its own speed (the contact's doing)."""
    log = make_log(seed=seed, sd=0.0, replicates=1)
    rng = np.random.default_rng(seed)
    mass = np.geomspace(0.3, 1.5, 6)
    friction = np.random.default_rng(seed).permutation(np.geomspace(0.15, 0.45, 6))
    v = log.speed * np.exp(rng.normal(0, launch_sd, log.n))
    m, mu = mass[log.obj], friction[log.obj]
    noise = rng.normal(0, 0.01, (2, log.n))
    d = np.exp(analytic_log_d(v, m, mu) + noise[0])
    t = np.exp(analytic_log_t(v, m, mu) + noise[1])
    return replace(log, displacement=d, stop_time=t)


def test_a_free_launch_leaves_the_slide_to_read(analytic_table):
    """Launches scattered by 10% are a large misfit under the table's launch, and leave only the noise once each
    push's launch is profiled out: the displacement against the stop time still sits on the table's slide."""
    log = launched_log(0.1)
    prob = Problem.of(log, analytic_table, StopTimeTables(), grid=OPTS.grid).with_noise(0.01, 0.01)
    assert prob.aux == ("stop_time",)
    held = prob.fit(Model(), np.zeros(0), prob.initial_fit())
    freed = prob.with_free_launch(held.objects)
    fit = freed.fit(Model(), np.zeros(0), held.objects)
    rows = 2 * log.n
    assert held.sse / rows > 10  # the launches, read as misfit
    assert fit.sse / (rows - freed.n_nuisance - 2 * 6) < 2.0  # what is left is the noise
    # the raw residuals the reports read agree with what the fit sums
    rd, rt = freed.row_residuals(
        freed.predict(Model(), np.zeros(0), fit.objects.lm[freed.c_obj], fit.objects.lu[freed.c_obj])
    )
    np.testing.assert_allclose(np.sum((rd / 0.01) ** 2) + np.sum((rt / 0.01) ** 2), fit.sse, rtol=1e-6)
    # a friction off by 20% is not a launch: the slide shows it
    off = freed.residuals(Model(), np.zeros((1, 0)), fit.objects.lm[None, :], fit.objects.lu[None, :] + np.log(1.2))
    assert np.sum(off**2) > 5 * fit.sse


def test_freed_launches_count_in_the_lack_of_fit(analytic_table):
    """Each freed launch is a parameter fitted on its condition's rows: the held-out lack of fit of the table, read
    with the launch freed on logs whose only departure is the launch, is a chi-square on what is left."""
    per_dof = []
    for seed in (3, 5, 7):
        log = launched_log(0.1, seed=seed)
        prob = Problem.of(log, analytic_table, StopTimeTables(), grid=OPTS.grid).with_noise(0.01, 0.01)
        held = prob.fit(Model(), np.zeros(0), prob.initial_fit())
        lm, lu = held.objects.lm[prob.c_obj], held.objects.lu[prob.c_obj]
        rd, rt = prob.row_residuals(prob.predict(Model(), np.zeros(0), lm, lu))
        freed = prob.with_free_launch(held.objects)
        fit = freed.fit(Model(), np.zeros(0), held.objects)
        s = shrinkage(freed, fit, resid_d=rd, resid_t=rt, held=heldout(freed, fit, 0))
        per_dof.append(s.lack_of_fit.heldout_chi2 / s.lack_of_fit.dof)
        assert 0.95 < s.both_share_closed <= 1.0  # the launches' gap closed down to the noise, not past it
    assert 0.7 < np.mean(per_dof) < 1.4, per_dof


def test_without_stop_times_nothing_is_freed(analytic_table):
    prob = Problem.of(make_log(seed=1), analytic_table, None, grid=OPTS.grid)
    assert prob.with_free_launch(prob.initial_fit()) is prob


# -- the next experiment may be a probe ------------------------------------------------------------------------


def test_a_free_stroke_is_recommended_where_it_separates_a_speed_gain_best(analytic_table):
    from imply.diagnose.conclusion.next_probes import next_probes_frame, recommend_probe

    log = make_log(seed=6, gain=0.06, sd=0.02)
    table = replace(analytic_table, meta={"scene": SCENE})
    prob = Problem.of(log, table, None, grid=OPTS.grid).with_noise(0.02, None)
    start = prob.initial_fit()
    gain = prob.fit(Model((candidates.CANDIDATES["speed_gain"],)), np.array([0.05]), start)
    none = prob.fit(Model(), np.zeros(0), start)
    contenders = [("speed_gain", gain, 0.5), ("none", none, 0.5)]
    speeds = np.array([0.3, 0.6, 0.9])
    probe = recommend_probe(prob, contenders, speeds=speeds, best_push_sd=0.5)
    # with masses weighed, the friction absorbs the gain in the pushes; a free stroke reads it directly
    # (slowest: the servo's lag dilutes a gain least there)
    assert probe is not None and probe.probe == "free_stroke" and probe.speed == 0.3
    servo = Servo.of_scene(SCENE)
    assert probe.expected["none"] == pytest.approx(servo.mean_speed(np.array([0.3]))[0])
    assert probe.expected["speed_gain"] > probe.expected["none"] * 1.03
    assert probe.separation_sd > 0.5
    row = next_probes_frame(probe)
    assert list(row.columns[:4]) == ["probe", "object_id", "speed", "added_mass"]
    assert row["expected_pusher_speed_if_none"].iloc[0] == pytest.approx(probe.expected["none"])
    # a push that separates them better leaves the probe out
    assert recommend_probe(prob, contenders, speeds=speeds, best_push_sd=100.0) is None
    assert next_probes_frame(None).empty
