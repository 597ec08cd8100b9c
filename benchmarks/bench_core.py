"""Benchmark of the core: table build, its convergence, and scoring, each against a baseline in the same process.

Run: python benchmarks/bench_core.py [--config config.yaml] [--sample 300] [--check-cells 200]

Prints seconds, throughput and peak memory, and the ratio to the baseline:
- table: the full table build (mujoco.batch on --threads threads): seconds, MuJoCo
  steps taken, and steps per second against bare ``mujoco.rollout`` of the same scene
  on the same threads (fixed-length rollouts, no stroke or settle logic: the most a
  stepping loop can reach here);
- convergence: the table's log d at --check-cells grid nodes against a uniform-step
  reference 64 times finer (imply.table.check_table), beside the same nodes simulated
  the old way (1 ms throughout, implicitfast) against the same reference;
- scoring: 10,000 sets of K=5 rollouts plus 2 calibration pushes through Scorer
  against scipy.optimize.least_squares per set (sample, scaled);
- rendering: one 64x64 offscreen frame (set MUJOCO_GL=egl before running).
Benchmarks measure; they assert nothing.
"""

from __future__ import annotations

import argparse
import os
import resource
import time
from dataclasses import replace

import mujoco
import numpy as np
import yaml
from mujoco import rollout
from scipy.optimize import least_squares

from imply.score import Scorer
from imply.sim import SceneConfig, build_model, simulate_pushes
from imply.table import TableCheckConfig, TableGrid, build_table, error_against, reference_at_nodes


def bare_rollout_steps_per_second(scene: SceneConfig, speeds: np.ndarray, threads: int, nstep: int = 400) -> float:
    """Steps per second of plain ``mujoco.rollout`` of the push scene at its fine step, commanded ``speeds``."""
    model = build_model(scene)
    model.opt.timestep = scene.timestep / scene.push_substeps
    n = speeds.size
    datas = [mujoco.MjData(model) for _ in range(max(threads, 1))]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.zeros((n, mujoco.mj_stateSize(model, spec)))
    mujoco.mj_getState(model, datas[0], state[0], spec)
    state[:] = state[0]
    control = np.repeat(speeds[:, None, None], nstep, axis=1)
    with rollout.Rollout(nthread=threads) as ro:
        ro.rollout(model, datas, state[:10], control[:10, :10], nstep=10)  # warm the thread pool
        t0 = time.perf_counter()
        ro.rollout(model, datas, state, control, nstep=nstep)
        return n * nstep / (time.perf_counter() - t0)


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="config.yaml")
    parser.add_argument("--sample", type=int, default=300, help="sets timed for the scoring baseline")
    parser.add_argument("--check-cells", type=int, default=200, help="grid nodes of the convergence check")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    with open(args.config) as fh:
        cfg = yaml.safe_load(fh)
    scene = SceneConfig.from_dict(cfg["scene"])
    grid = TableGrid.from_dict(cfg["table"])

    t0 = time.perf_counter()
    table = build_table(scene, grid, nthread=args.threads)
    batched_s = time.perf_counter() - t0
    n_cells = table.log_d.size
    steps = table.meta["stepping"]["substeps_total"]
    speeds, masses, frictions = grid.axes()
    rng = np.random.default_rng(0)
    bare = bare_rollout_steps_per_second(scene, rng.choice(speeds, 2000), args.threads)
    print(
        f"table: {n_cells} pushes on {args.threads} threads in {batched_s:.1f} s, {steps / 1e6:.2f} M MuJoCo "
        f"steps ({steps / n_cells:.0f} a push), {steps / batched_s / 1e3:.0f} k steps/s; bare mujoco.rollout "
        f"on {args.threads} threads: {bare / 1e3:.0f} k steps/s; ratio {steps / batched_s / bare:.2f}"
    )

    settings = TableCheckConfig(cells=args.check_cells)
    t0 = time.perf_counter()
    nodes, ref = reference_at_nodes(table, settings, nthread=args.threads)
    ref_s = time.perf_counter() - t0
    now = error_against(table, table.log_d[nodes], nodes, ref, settings.seed)
    old_scene = replace(
        scene,
        push_substeps=1,
        release_window=0.0,
        slide_steps=0,
        slow_push_speed=0.0,
        option={**scene.option, "integrator": "implicitfast"},
    )
    i, j, k = nodes
    old = simulate_pushes(speeds[i], masses[j], frictions[k], scene=old_scene, nthread=args.threads)
    before = error_against(table, np.log(old.displacement), nodes, ref, settings.seed)
    for name, e in (("this table", now), ("old stepping (1 ms, implicitfast)", before)):
        print(
            f"convergence, {name}: max |delta log d| {e['max_abs_log_d']:.4f}, RMS {e['rms_log_d']:.4f} "
            f"over {e['cells']} grid nodes"
        )
    print(
        f"  reference: uniform {ref.step * 1e6:.4g} us step ({ref_s:.0f} s); its own error estimate max "
        f"{now['reference_error_max']:.4f}, RMS {now['reference_error_rms']:.4f}"
    )

    query = np.array(cfg["score"]["query_speeds"])
    calib = np.array(cfg["score"]["calibration_speeds"])
    n_sets = 10_000
    lm = rng.uniform(np.log(masses[0]), np.log(masses[-1]), n_sets)
    lu = rng.uniform(np.log(frictions[0]), np.log(frictions[-1]), n_sets)
    y = table.log_displacement(query[None], np.exp(lm)[:, None], np.exp(lu)[:, None])
    y += 0.1 * rng.standard_normal(y.shape)
    yc = table.log_displacement(calib[None], np.exp(lm)[:, None], np.exp(lu)[:, None])
    scorer = Scorer(table, grid=cfg["score"]["grid"], floor=cfg["score"]["readout_floor"])
    scorer.score(query, np.exp(y[:10]), calib, np.exp(yc[:10]))  # warm the per-speed grid cache
    t0 = time.perf_counter()
    scores = scorer.score(query, np.exp(y), calib, np.exp(yc))
    ours_s = time.perf_counter() - t0

    lo = np.log([masses[0], frictions[0]])
    hi = np.log([masses[-1], frictions[-1]])
    both_v = np.concatenate([calib, query])
    t0 = time.perf_counter()
    ls_self, ls_anch = [], []
    for n in range(args.sample):
        for speeds_n, logs, out in ((query, y[n], ls_self), (both_v, np.concatenate([yc[n], y[n]]), ls_anch)):
            fit = least_squares(
                lambda th, s=speeds_n, lg=logs: table.log_displacement(s, np.exp(th[0]), np.exp(th[1])) - lg,
                (lo + hi) / 2,
                bounds=(lo, hi),
            )
            out.append(np.sqrt(2 * fit.cost / logs.size))
    base_s = (time.perf_counter() - t0) / args.sample * n_sets
    worse = np.mean(np.array(ls_self) > scores.self_disagreement[: args.sample] + 1e-4)
    print(
        f"scoring: {n_sets} sets (K={query.size}, 2 calibration) in {ours_s:.2f} s; per-set least_squares "
        f"{base_s:.1f} s scaled from {args.sample} sets; ratio {base_s / ours_s:.0f}x; least_squares found a "
        f"worse self fit (local minimum) in {worse:.0%} of sets"
    )
    model = build_model(scene)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with mujoco.Renderer(model, 64, 64) as renderer:
        renderer.update_scene(data, camera="top")
        renderer.render()
        t0 = time.perf_counter()
        for _ in range(500):
            renderer.update_scene(data, camera="top")
            renderer.render()
        frame_ms = (time.perf_counter() - t0) / 500 * 1000
    print(f"rendering: a 64x64 frame in {frame_ms:.2f} ms (MUJOCO_GL={os.environ.get('MUJOCO_GL', 'default')})")
    print(f"peak memory: {peak_rss_mb():.0f} MB")


if __name__ == "__main__":
    main()
