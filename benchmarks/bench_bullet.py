"""Benchmark of the Bullet world (imply.realworld.bullet): its speed, its convergence, its gap to the MuJoCo table.

Run: taskset -c 0 python benchmarks/bench_bullet.py [--table results/table/table.npz] [--repeats 3]

Prints:
- speed: seconds and pushes per second for 48 nominal pushes (8 boxes, masses log-uniform
  in 0.2-2 kg and frictions in 0.1-0.6, seed 0, x 6 speeds 0.2-0.9 m/s), best of --repeats
  (run it under ``taskset -c 0`` for one core);
- convergence: the largest change of log d and stop time over those pushes when every
  step is halved (and quartered), when only the slide or only the push step is halved,
  and with 10 or 100 solver iterations instead of the default;
- gap (with --table): Bullet's nominal log d minus the push table's prediction at the
  true mass and friction on a grid of 6 speeds x 4 masses x 4 frictions: mean, sd and
  range, by speed, mass and friction, and a linear fit in log v, log m and log mu.
Benchmarks measure; they assert nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
import pandas as pd

from imply.realworld.bullet import BulletStepping, simulate_bullet
from imply.realworld.world import WorldPushes
from imply.sim.scene import SceneConfig


def _study_pushes(scene: SceneConfig) -> WorldPushes:
    rng = np.random.default_rng(0)
    mass = np.exp(rng.uniform(np.log(0.2), np.log(2.0), 8))
    friction = np.exp(rng.uniform(np.log(0.1), np.log(0.6), 8))
    speed, obj = (a.ravel() for a in np.meshgrid(np.linspace(0.2, 0.9, 6), np.arange(8)))
    return WorldPushes.nominal(speed, mass[obj], friction[obj], 0.0, scene)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--table", default=None, help="a push table (.npz) to measure the gap against")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    scene = SceneConfig()
    pushes = _study_pushes(scene)
    base = BulletStepping()

    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        ref = simulate_bullet(pushes, scene, base)
        times.append(time.perf_counter() - t0)
    best = min(times)
    print(
        f"speed: {pushes.n} pushes in {best:.2f} s (best of {args.repeats}: {', '.join(f'{t:.2f}' for t in times)}),"
        f" {pushes.n / best:.0f} pushes/s, {ref.steps.sum()} steps, all ok {bool(ref.ok.all())}"
    )

    variants = {
        "every step / 2": base.finer(2),
        "every step / 4": base.finer(4),
        "slide step / 2": dataclasses.replace(base, slide_step=base.slide_step / 2),
        "push step / 2": dataclasses.replace(base, push_step=base.push_step / 2),
        "every step x 2": dataclasses.replace(base, push_step=base.push_step * 2, slide_step=base.slide_step * 2),
        "10 iterations": dataclasses.replace(base, solver_iterations=10),
        "100 iterations": dataclasses.replace(base, solver_iterations=100),
    }
    for name, st in variants.items():
        r = simulate_bullet(pushes, scene, st)
        dd = np.log(r.displacement / ref.displacement)
        dt = r.stop_time - ref.stop_time
        print(
            f"convergence, {name}: max |d log d| {np.abs(dd).max():.4f} (mean {dd.mean():+.4f}),"
            f" max |d stop time| {np.abs(dt).max() * 1e3:.2f} ms, all ok {bool(r.ok.all())}"
        )

    if args.table:
        from imply.table import PushTable

        table = PushTable.load(args.table)
        v, m, mu = np.linspace(0.2, 0.9, 6), np.array([0.2, 0.45, 1.0, 2.0]), np.array([0.1, 0.2, 0.35, 0.6])
        V, M, MU = (a.ravel() for a in np.meshgrid(v, m, mu, indexing="ij"))
        r = simulate_bullet(WorldPushes.nominal(V, M, MU, 0.0, scene), scene, base)
        gap = np.log(r.displacement) - table.log_displacement(V, M, MU)
        print(
            f"gap, bullet - table in log d over {V.size} nominal pushes (all ok {bool(r.ok.all())}): mean"
            f" {gap.mean():+.3f}, sd {gap.std():.3f}, range [{gap.min():+.3f}, {gap.max():+.3f}]"
        )
        df = pd.DataFrame({"speed": V, "mass": M, "friction": MU, "gap": gap})
        for k in ("speed", "mass", "friction"):
            print(f"gap by {k}:\n" + df.groupby(k).gap.agg(["mean", "min", "max"]).round(3).T.to_string())
        print(
            "gap by mass (rows) and friction (columns), mean over speeds:\n"
            + df.pivot_table(index="mass", columns="friction", values="gap").round(3).to_string()
        )
        X = np.column_stack([np.ones_like(V), np.log(V), np.log(M), np.log(MU)])
        coef = np.linalg.lstsq(X, gap, rcond=None)[0]
        print(
            f"gap ~ {coef[0]:+.3f} {coef[1]:+.3f} log v {coef[2]:+.3f} log m {coef[3]:+.3f} log mu,"
            f" residual sd {(gap - X @ coef).std():.3f}"
        )


if __name__ == "__main__":
    main()
