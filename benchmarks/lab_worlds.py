"""Benchmark of the lab benchmark's worlds: each engine's time per push, and its convergence, in one process.

Run: taskset -c 0 python benchmarks/lab_worlds.py [--repeats 3]

Prints, for the MuJoCo world (the baseline, one thread), Bullet and SAPIEN (PhysX):
- speed: seconds per push over 48 nominal pushes (8 boxes, masses log-uniform in
  0.2-2 kg and frictions in 0.1-0.6, seed 0, x 6 speeds 0.2-0.9 m/s), best of --repeats,
  and each engine's ratio to MuJoCo's;
- the same for the probes of those boxes (a free stroke per speed, a pull test per box,
  the added-mass pushes), whose pull tests run longer than a push;
- convergence: the largest change of log d and of the pull test's reading when every step
  is halved.
Benchmarks measure; they assert nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from imply.realworld.bullet import BulletStepping, simulate_bullet
from imply.realworld.probes import ProbeDesign, probe_layout, probe_observables, probe_pushes
from imply.realworld.sapien_world import SapienStepping, simulate_sapien
from imply.realworld.world import WorldPushes, WorldStepping, simulate_world
from imply.sim.scene import SceneConfig


def _boxes() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    return np.exp(rng.uniform(np.log(0.2), np.log(2.0), 8)), np.exp(rng.uniform(np.log(0.1), np.log(0.6), 8))


def _pushes(scene: SceneConfig) -> WorldPushes:
    mass, friction = _boxes()
    speed, obj = (a.ravel() for a in np.meshgrid(np.linspace(0.2, 0.9, 6), np.arange(8)))
    return WorldPushes.nominal(speed, mass[obj], friction[obj], 0.0, scene)


def _probes(scene: SceneConfig):
    mass, friction = _boxes()
    layout = probe_layout(mass, np.linspace(0.2, 0.9, 6), np.zeros(8), ProbeDesign())
    obj = np.maximum(layout.obj, 0)
    p = WorldPushes.nominal(layout.speed, mass[obj], friction[obj], 0.0, scene)
    return layout, probe_pushes(layout, p, ProbeDesign())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    scene = SceneConfig()
    engines = {
        "mujoco": (lambda p, st=None: simulate_world(p, scene, st, nthread=1), WorldStepping()),
        "bullet": (lambda p, st=None: simulate_bullet(p, scene, st), BulletStepping()),
        "sapien": (lambda p, st=None: simulate_sapien(p, scene, st), SapienStepping()),
    }
    pushes = _pushes(scene)
    layout, probes = _probes(scene)
    base: dict[str, float] = {}
    print(
        f"{'world':8} {'s/push':>9} {'ratio':>6} {'s/probe':>9} {'ratio':>6} {'max dlog d (h/2)':>17} "
        f"{'max dreading (h/2)':>19}"
    )
    for name, (run, stepping) in engines.items():
        times = {}
        for what, batch in (("push", pushes), ("probe", probes)):
            best = np.inf
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                res = run(batch)
                best = min(best, time.perf_counter() - t0)
            times[what] = best / batch.n
            base.setdefault(what, times[what]) if name == "mujoco" else None
        fine = dataclasses.replace(stepping, push_step=stepping.push_step / 2, slide_step=stepping.slide_step / 2)
        if name == "mujoco":
            fine = stepping.finer(2)
        coarse_d, fine_d = run(pushes).displacement, run(pushes, fine).displacement
        read = probe_observables(layout, res, probes, scene.stroke)["reading"]
        read_fine = probe_observables(layout, run(probes, fine), probes, scene.stroke)["reading"]
        dd = np.nanmax(np.abs(np.log(fine_d / coarse_d)))
        dr = np.nanmax(np.abs(np.array(read_fine, float) - np.array(read, float)))
        print(
            f"{name:8} {times['push']:9.4f} {times['push'] / base['push']:6.2f} {times['probe']:9.4f} "
            f"{times['probe'] / base['probe']:6.2f} {dd:17.4f} {dr:19.4f}"
        )


if __name__ == "__main__":
    main()
