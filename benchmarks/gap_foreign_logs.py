"""Push logs made by code other than the gap benchmark's, to check `imply diagnose` on logs it was not built beside.

Run: python benchmarks/gap_foreign_logs.py --out /tmp/foreign [--check]; then
`imply diagnose /tmp/foreign/log-NN.csv -o REPORT --table results/table/table.npz` for each
(the truth of every log is in /tmp/foreign/truth.json). Not part of the workflow.

The scene's MJCF comes from imply.sim.scene.build_xml (the canonical box); every effect
is injected by editing the MjSpec or the compiled model ourselves, and each push is
stepped with plain mujoco.mj_step at one uniform step (semi-implicit Euler, as the
exported scene asks), no shortened steps and no travel correction:

  command the (actual) pusher speed; after the first step at which the pusher slide
  reaches the stroke (custom numeric `stroke`) command 0 (the servo brakes); step on
  until every linear speed of the box is below 1e-4 m/s (checked every 1 ms) or 4 s;
  the displacement is the box's x travel (push frame) at rest.

Conventions: a push in table direction phi is simulated along the scene's +x axis; a
table tilted by angle a downhill toward table azimuth psi gives, in the push frame,
gravity g (sin a cos(psi - phi), sin a sin(psi - phi), -cos a).  Anisotropic friction:
mu(phi) = mu (1 + k cos 2 phi).

Usage: python benchmarks/gap_foreign_logs.py [--step 5e-5] [--out logs] [--check]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import mujoco
import numpy as np
import pandas as pd

from imply.sim.scene import SceneConfig, build_xml

SCENE = SceneConfig()
HALF = SCENE.box_half_extents  # canonical box (half-extents)
G = 9.81
SETTLE = 1e-4
MAX_TIME = 4.0

# truth of each log; all effect keys default to "off"
LOGS = [
    ("log-01", {}),
    ("log-02", {}),
    ("log-03", {"tilt": 0.012, "tilt_az_deg": 35.0}),
    ("log-04", {"tilt": 0.02, "tilt_az_deg": 200.0}),
    ("log-05", {"viscous": 0.4}),
    ("log-06", {"speed_gain": -0.07}),
    ("log-07", {"speed_offset": 0.04}),
    ("log-08", {"aniso": 0.2}),  # larger friction along the table x axis (azimuth 0)
    ("log-09", {"tilt": 0.015, "tilt_az_deg": 120.0, "viscous": 0.3}),
    ("log-10", {"pusher_mass": 0.35}),
    ("log-11", {"pos_friction": 0.4, "pos_start": 0.05}),  # table friction x1.4 beyond 5 cm of travel
    ("log-12", {"stribeck": 0.5, "stribeck_vs": 0.15}),  # mu (1 + 0.5 exp(-(v/0.15)^2))
]


def make_model(mass: float, friction: float, eff: dict, step: float, integrator: str = "Euler") -> mujoco.MjModel:
    """The exported scene edited through MjSpec: this box, this step, and the model-level effects."""
    spec = mujoco.MjSpec.from_string(build_xml(SCENE))
    spec.option.timestep = step
    spec.option.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    box = spec.geom("box")
    box.mass = mass  # inertia follows from the geom (uniform density)
    fr = np.array(box.friction, float)
    fr[0] = friction
    box.friction = fr
    if eff.get("viscous"):
        d = np.zeros(3)
        d[0] = eff["viscous"]
        spec.joint("box").damping = d  # joint damping on every dof of the free joint
    if eff.get("pusher_mass"):
        spec.geom("pusher").mass = eff["pusher_mass"]
    return spec.compile()


def push(model: mujoco.MjModel, speed: float, direction: float, mu: float, eff: dict) -> dict:
    """One push of a compiled model; returns displacement, lateral, tilt, stop time, steps."""
    m = model
    d = mujoco.MjData(m)
    box_j = m.joint("box")
    bq, bv = int(m.jnt_qposadr[box_j.id]), int(m.jnt_dofadr[box_j.id])
    pq = int(m.jnt_qposadr[m.joint("push").id])
    servo = m.actuator("servo").id
    gid = m.geom("box").id
    stroke = float(m.numeric("stroke").data[0])
    h = float(m.opt.timestep)

    # tilt: gravity in the push frame
    a = eff.get("tilt", 0.0)
    if a:
        rel = math.radians(eff["tilt_az_deg"]) - direction
        m.opt.gravity[:] = [G * math.sin(a) * math.cos(rel), G * math.sin(a) * math.sin(rel), -G * math.cos(a)]
    else:
        m.opt.gravity[:] = [0.0, 0.0, -G]
    # anisotropic friction: a per-push coefficient
    mu_push = mu * (1.0 + eff.get("aniso", 0.0) * math.cos(2.0 * direction))
    m.geom_friction[gid, 0] = mu_push

    law = None
    if eff.get("stribeck"):
        k, vs = eff["stribeck"], eff["stribeck_vs"]

        def law(dd):
            v = math.hypot(dd.qvel[bv], dd.qvel[bv + 1])
            return mu_push * (1.0 + k * math.exp(-((v / vs) ** 2)))
    elif eff.get("pos_friction"):
        k, x_on = eff["pos_friction"], eff["pos_start"]

        def law(dd):
            return mu_push * (1.0 + k) if dd.qpos[bq] - x0 > x_on else mu_push

    mujoco.mj_forward(m, d)
    x0, y0 = float(d.qpos[bq]), float(d.qpos[bq + 1])
    actual = speed * (1.0 + eff.get("speed_gain", 0.0)) + eff.get("speed_offset", 0.0)
    d.ctrl[servo] = actual
    steps = 0

    def one():
        nonlocal steps
        if law is not None:
            m.geom_friction[gid, 0] = law(d)
        mujoco.mj_step(m, d)
        steps += 1

    # pushing: brake after the first step at which the pusher reaches the stroke
    while d.qpos[pq] < stroke and d.time < MAX_TIME:
        one()
    d.ctrl[servo] = 0.0
    # sliding until every linear speed of the box is below SETTLE (checked every 1 ms)
    chunk = max(1, int(round(1e-3 / h)))
    while d.time < MAX_TIME:
        if law is None:
            mujoco.mj_step(m, d, nstep=chunk)
            steps += chunk
        else:
            for _ in range(chunk):
                one()
        if np.abs(d.qvel[bv : bv + 3]).max() < SETTLE:
            break
    q = d.qpos[bq + 3 : bq + 7]
    tilt = math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (q[1] ** 2 + q[2] ** 2))))
    m.geom_friction[gid, 0] = mu  # restore
    return {
        "displacement": float(d.qpos[bq] - x0),
        "lateral": float(d.qpos[bq + 1] - y0),
        "tilt": tilt,
        "stop_time": float(d.time),
        "settled": bool(d.time < MAX_TIME),
        "steps": steps,
    }


def design(seed: int) -> dict:
    """Objects, speeds, directions and noise of one log (independent of the physics)."""
    rng = np.random.default_rng(seed)
    n_obj, speeds = 8, np.linspace(0.25, 0.85, 6)
    mass = np.exp(rng.uniform(np.log(0.3), np.log(1.8), n_obj))
    fric = np.exp(rng.uniform(np.log(0.12), np.log(0.5), n_obj))
    direction = rng.uniform(0.0, 2.0 * np.pi, (n_obj, speeds.size))
    noise = rng.normal(0.0, 0.02, (n_obj, speeds.size, 2))
    return {"mass": mass, "friction": fric, "speeds": speeds, "direction": direction, "noise": noise}


def make_log(name: str, eff: dict, seed: int, step: float, measured_mass: bool) -> tuple[pd.DataFrame, pd.DataFrame]:
    des = design(seed)
    rows, raw = [], []
    for i in range(des["mass"].size):
        model = make_model(des["mass"][i], des["friction"][i], eff, step)
        for j, v in enumerate(des["speeds"]):
            phi = float(des["direction"][i, j])
            r = push(model, float(v), phi, float(des["friction"][i]), eff)
            raw.append(
                {
                    "log": name,
                    "object_id": f"obj{i}",
                    "mass": des["mass"][i],
                    "friction": des["friction"][i],
                    "speed": v,
                    "direction": phi,
                    **r,
                }
            )
            for k in range(2):
                row = {
                    "object_id": f"obj{i}",
                    "speed": round(float(v), 6),
                    "direction": phi,
                    "displacement": r["displacement"] * math.exp(des["noise"][i, j, k]),
                    "size_x": HALF[0],
                    "size_y": HALF[1],
                    "size_z": HALF[2],
                }
                if measured_mass:
                    row["mass"] = des["mass"][i]
                rows.append(row)
    return pd.DataFrame(rows), pd.DataFrame(raw)


def convergence(step: float) -> pd.DataFrame:
    """A few pushes at `step` and `step / 2` (and the library's run_pushes for the null ones)."""
    cases = [  # (log index, object, speed index)
        (0, 0, 0),
        (0, 3, 5),
        (1, 1, 0),
        (2, 2, 2),
        (3, 4, 0),
        (4, 5, 3),
        (5, 6, 1),
        (9, 0, 0),
        (10, 2, 5),
        (11, 3, 0),
        (11, 7, 4),
        (7, 1, 2),
    ]
    out = []
    for li, i, j in cases:
        name, eff = LOGS[li]
        des = design(1000 + li)
        mu, mass, v, phi = des["friction"][i], des["mass"][i], des["speeds"][j], des["direction"][i, j]
        res = {}
        for h in (step, step / 2):
            res[h] = push(make_model(mass, mu, eff, h), float(v), float(phi), float(mu), eff)
        out.append(
            {
                "log": name,
                "mass": mass,
                "friction": mu,
                "speed": v,
                "d_h": res[step]["displacement"],
                "d_h2": res[step / 2]["displacement"],
                "dlogd": math.log(res[step]["displacement"] / res[step / 2]["displacement"]),
            }
        )
    return pd.DataFrame(out)


def library_crosscheck(step: float) -> pd.DataFrame:
    """Null pushes: this generator vs imply.sim.pushes.simulate_pushes (the table's stepping)."""
    from imply.sim.pushes import simulate_pushes

    des = design(1000)
    mass = np.repeat(des["mass"], des["speeds"].size)
    fric = np.repeat(des["friction"], des["speeds"].size)
    v = np.tile(des["speeds"], des["mass"].size)
    lib = simulate_pushes(v, mass, fric, nthread=1).displacement
    mine = [
        push(make_model(mass[k], fric[k], {}, step), float(v[k]), 0.0, float(fric[k]), {})["displacement"]
        for k in range(v.size)
    ]
    return pd.DataFrame(
        {
            "mass": mass,
            "friction": fric,
            "speed": v,
            "d_lib": lib,
            "d_mine": mine,
            "dlogd": np.log(np.array(mine) / lib),
        }
    )


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--step", type=float, default=50e-6)
    ap.add_argument("--out", default="logs")
    ap.add_argument("--check", action="store_true", help="run the step-halving and library checks only")
    ap.add_argument("--gap", action="store_true", help="size of each injected effect: log d with vs without it")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    t0 = time.time()
    if args.check:
        c = convergence(args.step)
        print(c.to_string())
        print(f"max |dlog d| step vs step/2: {c.dlogd.abs().max():.5f}  rms {np.sqrt((c.dlogd**2).mean()):.5f}")
        c.to_csv(os.path.join(args.out, "convergence.csv"), index=False)
        x = library_crosscheck(args.step)
        print(x.describe().to_string())
        print(f"vs library run_pushes: max |dlog d| {x.dlogd.abs().max():.5f}  mean {x.dlogd.mean():+.5f}")
        x.to_csv(os.path.join(args.out, "library_crosscheck.csv"), index=False)
        print(f"check time {time.time() - t0:.1f} s")
        return 0
    if args.gap:
        raw = pd.read_csv(os.path.join(args.out, "raw_pushes.csv"))
        rows = []
        for name, _effects in LOGS:
            r = raw[raw.log == name]
            null = [
                push(make_model(x.mass, x.friction, {}, args.step), x.speed, x.direction, x.friction, {})[
                    "displacement"
                ]
                for x in r.itertuples()
            ]
            g = np.log(r.displacement.to_numpy() / np.array(null))
            rows.append(
                {
                    "log": name,
                    "mean_dlogd": g.mean(),
                    "rms_dlogd": np.sqrt((g**2).mean()),
                    "min": g.min(),
                    "max": g.max(),
                }
            )
        gap = pd.DataFrame(rows)
        print(gap.to_string(float_format=lambda v: f"{v:+.4f}"))
        gap.to_csv(os.path.join(args.out, "effect_sizes.csv"), index=False)
        return 0
    # measured mass in half the logs (chosen once, by a fixed draw)
    with_mass = set(np.random.default_rng(7).choice(len(LOGS), len(LOGS) // 2, replace=False).tolist())
    truth, raws = {}, []
    for li, (name, eff) in enumerate(LOGS):
        t1 = time.time()
        df, raw = make_log(name, eff, 1000 + li, args.step, li in with_mass)
        df.to_csv(os.path.join(args.out, f"{name}.csv"), index=False)
        raws.append(raw)
        bad = raw[~raw.settled | (raw.tilt > 0.1) | (raw.lateral.abs() > 0.1 * raw.displacement + 1e-3)]
        truth[name] = {
            "effects": eff,
            "measured_mass": li in with_mass,
            "seed": 1000 + li,
            "unsettled_or_bad": int(len(bad)),
            "displacement_range_m": [float(raw.displacement.min()), float(raw.displacement.max())],
        }
        print(
            f"{name} {eff} mass={li in with_mass} d=[{raw.displacement.min():.4f},{raw.displacement.max():.4f}] "
            f"bad={len(bad)} steps={raw.steps.sum()} {time.time() - t1:.1f}s",
            flush=True,
        )
    pd.concat(raws).to_csv(os.path.join(args.out, "raw_pushes.csv"), index=False)
    with open(os.path.join(args.out, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    print(f"total {time.time() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
