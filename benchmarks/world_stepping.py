"""The benchmark world's stepping: CPU time and numerical error of coarser steps, against the default's.

Random nominal pushes across the table's range (speed, mass, friction, direction) are simulated
with the default stepping (``gap.benchmark.stepping``) and with its push, slide or both steps
doubled, one thread each, in one process. Each run's log d and log stop time are compared with the
default stepping eight times finer, the nearest thing here to the timestep-to-zero limit. The world's
own design rule (:mod:`imply.realworld.accuracy`) is that it be at least as close to that limit as
the push table is; the table's measured error is printed beside it.

Usage: ``python benchmarks/world_stepping.py [--pushes 96] [--seed 1] [--table results/table/table.npz]``
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from imply.realworld.world import WorldPushes, WorldStepping, simulate_world
from imply.sim.scene import SceneConfig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pushes", type=int, default=96)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--table", help="a push table whose measured numerical error is printed beside the world's")
    args = ap.parse_args()

    rng = np.random.default_rng(args.seed)
    n = args.pushes
    scene = SceneConfig()
    pushes = WorldPushes.nominal(
        rng.uniform(0.15, 1.0, n),
        np.exp(rng.uniform(np.log(0.2), np.log(2.0), n)),
        np.exp(rng.uniform(np.log(0.1), np.log(0.6), n)),
        rng.uniform(0.0, 2 * np.pi, n),
        scene,
    )
    base = WorldStepping()
    limit = simulate_world(pushes, scene, base.finer(8), nthread=1)
    variants = {
        "default": base,
        "push steps x2": dataclasses.replace(
            base, push_step=2 * base.push_step, slow_push_step=2 * base.slow_push_step
        ),
        "slide step x2": dataclasses.replace(base, slide_step=2 * base.slide_step),
        "both x2": dataclasses.replace(
            base, push_step=2 * base.push_step, slow_push_step=2 * base.slow_push_step, slide_step=2 * base.slide_step
        ),
    }
    print(f"{n} nominal pushes, one thread; error against the default stepping 8 times finer")
    print(f"{'stepping':<15} {'CPU s':>7} {'ratio':>6} {'log d max':>10} {'RMS':>8} {'log t max':>10}")
    first = None
    for name, stepping in variants.items():
        t0 = time.process_time()
        run = simulate_world(pushes, scene, stepping, nthread=1)
        cpu = time.process_time() - t0
        first = first or cpu
        ok = run.ok & limit.ok
        err_d = (np.log(run.displacement) - np.log(limit.displacement))[ok]
        err_t = (np.log(run.stop_time) - np.log(limit.stop_time))[ok]
        print(
            f"{name:<15} {cpu:7.2f} {cpu / first:6.2f} {np.abs(err_d).max():10.4f} {np.sqrt(np.mean(err_d**2)):8.4f}"
            f" {np.abs(err_t).max():10.4f}"
        )
    if args.table:
        from imply.table import PushTable

        table_error = PushTable.load(args.table).meta.get("numerical_error") or {}
        print(f"the table's measured error: max {table_error.get('max_abs_log_d')} in log d")


if __name__ == "__main__":
    main()
