"""Benchmark of the core: table build and scoring, each against a plain baseline in the same process.

Run: python benchmarks/bench_core.py [--config config.yaml] [--sample 300]

Prints seconds, throughput and peak memory, and the ratio to the baseline:
- table: the batched build of every table cell (mujoco.batch on all cores) against a
  bare Python loop of mj_step on one MjData (one core) running the same pushes with
  the same stroke and settle logic, timed on a sample of cells and scaled to the table;
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

import mujoco
import numpy as np
import yaml
from scipy.optimize import least_squares

from imply.score import Scorer
from imply.sim import SceneConfig, build_model, simulate_pushes
from imply.sim.scene import model_numeric
from imply.table import TableGrid, build_table


def bare_push(model: mujoco.MjModel, data: mujoco.MjData, speed: float) -> tuple[float, int]:
    """One push with a plain mj_step loop (the baseline); returns displacement and steps."""
    mujoco.mj_resetData(model, data)
    stroke = model_numeric(model, "stroke")
    settle = model_numeric(model, "settle_speed")
    max_time = model_numeric(model, "max_time")
    dt = model.opt.timestep
    pq = model.jnt_qposadr[model.joint("push").id]
    pv = model.jnt_dofadr[model.joint("push").id]
    x0 = data.qpos[0]
    steps = 0
    while data.time < max_time:
        left = (stroke - data.qpos[pq]) / max(data.qvel[pv] * dt, 1e-12)
        last = left < 1.0
        data.ctrl[0] = min(max(left, 0.0), 1.0) * speed if last else speed
        mujoco.mj_step(model, data)
        steps += 1
        if last:
            break
    data.ctrl[0] = 0.0
    while data.time < max_time:
        mujoco.mj_step(model, data, nstep=25)
        steps += 25
        if np.abs(data.qvel[:3]).max() < settle:
            break
    return data.qpos[0] - x0, steps


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="config.yaml")
    parser.add_argument("--sample", type=int, default=300, help="cells / sets timed for the baselines")
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

    rng = np.random.default_rng(0)
    speeds, masses, frictions = grid.axes()
    cells = rng.integers(0, [speeds.size, masses.size, frictions.size], size=(args.sample, 3))
    t0 = time.perf_counter()
    bare = []
    for i, j, k in cells:
        model = build_model(scene, mass=masses[j], friction=frictions[k])
        data = mujoco.MjData(model)
        bare.append(bare_push(model, data, speeds[i])[0])
    bare_s = (time.perf_counter() - t0) / args.sample * n_cells
    check = simulate_pushes(speeds[cells[:, 0]], masses[cells[:, 1]], frictions[cells[:, 2]], scene=scene).displacement
    print(f"table: {n_cells} simulations batched on {args.threads} threads in {batched_s:.1f} s "
          f"({n_cells / batched_s:.0f} sims/s); bare mj_step loop, 1 core: {bare_s:.1f} s scaled from "
          f"{args.sample} cells; ratio {bare_s / batched_s:.2f}x; max |batched - bare| displacement "
          f"{np.abs(check - np.array(bare)).max():.2e} m")  # fmt: skip

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
                (lo + hi) / 2, bounds=(lo, hi),
            )  # fmt: skip
            out.append(np.sqrt(2 * fit.cost / logs.size))
    base_s = (time.perf_counter() - t0) / args.sample * n_sets
    worse = np.mean(np.array(ls_self) > scores.self_disagreement[: args.sample] + 1e-4)
    print(f"scoring: {n_sets} sets (K={query.size}, 2 calibration) in {ours_s:.2f} s; per-set least_squares "
          f"{base_s:.1f} s scaled from {args.sample} sets; ratio {base_s / ours_s:.0f}x; least_squares found a "
          f"worse self fit (local minimum) in {worse:.0%} of sets")  # fmt: skip
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
