"""Which observables tell the library's effects apart, from each other and from an unknown contact.

For every library effect (the table's own simulator, :func:`imply.sim.effects.effect_spec`)
and every contact model of the other-contact benchmark (the benchmark's world,
:mod:`imply.realworld`, against the same world with MuJoCo's contact), the change it makes to
each observable of pushes at five speeds of three objects, in noise sds, with the part that
refitting each object's mass and friction (with ``--mass-measured``, its friction alone)
absorbs projected out. Printed per observable set:

- each effect's visible size after the refit (the square root of its chi-square, noise sds);
- for each library effect, its largest |cos| with any other effect or contact model (1: the
  pushes cannot tell them apart; the smaller, the better separated).

Usage: ``python benchmarks/observables_identifiability.py [--mass-measured] [--json out.json]``
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from imply.diagnose.physics.effect_tables import simulate_observables
from imply.realworld.world import WorldPushes, simulate_world
from imply.sim.effects import EFFECTS, MODEL, effect_spec
from imply.sim.scene import SceneConfig, build_model
from imply.sim.track import FRACTIONS, crossing_times, pusher_speed, stop_times

SPEEDS = np.array([0.25, 0.4, 0.55, 0.7, 0.85])
OBJECTS = [(0.4, 0.2), (1.0, 0.35), (1.8, 0.5)]  # (mass kg, friction)
# noise sd of each observable (log units): readout, stop time, encoder, camera crossing times
NOISE = {"d": 0.02, "T": 0.02, "p": 0.01, **{f"t{int(q * 100)}": 0.03 for q in FRACTIONS}}
NAMES = list(NOISE)
SETS = {
    "displacement": ["d"],
    "+ stop time": ["d", "T"],
    "+ pusher speed": ["d", "T", "p"],
    "+ track": ["d", "T", *NAMES[3:]],
    "all": NAMES,
}
LIBRARY = {
    "viscous": 0.25,
    "air_drag": 150.0,
    "pusher_softness": 0.03,
    "slope": 0.015,
    "torsional": 0.025,
    "rolling": 0.01,
    "height": 0.1,
    "speed_gain": 0.05,
    "speed_offset": 0.02,
}
CONTACTS = {
    "table_compliance": {"table_timeconst": 3.5, "table_dampratio": 0.5},
    "speed_friction": {"friction_slope": 0.75, "friction_slope_speed": 0.15},
    "regularised_friction": {"friction_regularisation": 0.2, "friction_rest_share": 0.5},
    "pusher_contact": {"pusher_impedance": 0.3, "pusher_friction": 0.5},
}
H = 0.02  # log step for the mass and friction derivatives
MASS_MEASURED = False  # set by --mass-measured: only the friction is refitted


def _design():
    v = np.tile(SPEEDS, len(OBJECTS))
    m = np.repeat([o[0] for o in OBJECTS], SPEEDS.size)
    u = np.repeat([o[1] for o in OBJECTS], SPEEDS.size)
    return v, m, u


def _stack(log_d, log_t, log_p, log_tq) -> np.ndarray:
    return np.column_stack([log_d, log_t, log_p, log_tq])  # (n, 6) in NAMES order


def table_observables(scene: SceneConfig, key: str | None, value: float, v, m, u) -> np.ndarray:
    """(n, 6) the observables from the table's simulator: the scene with effect ``key`` at ``value`` (None: none)."""
    model = effect_spec(scene, key, value).compile() if key else build_model(scene)
    o = simulate_observables(model, v, m, u, nthread=2)
    return _stack(o.log_d, o.log_t, o.log_p, o.log_tq)


def world_observables(scene: SceneConfig, params: dict, v, m, u) -> np.ndarray:
    p = WorldPushes.nominal(v, m, u, 0.0, scene)
    for k, x in params.items():
        p.params[k][:] = x
    times = np.arange(0.0, 2.5, 0.001)
    r = simulate_world(p, scene, nthread=2, track_times=times)
    tq = crossing_times(times, r.track[:, :, 0], r.displacement)
    t = stop_times(r.track[:, :, :2], np.broadcast_to(times, r.track.shape[:2]))
    return _stack(np.log(r.displacement), np.log(t), np.log(pusher_speed(scene.stroke, r.stroke_time)), np.log(tq))


def signatures(scene: SceneConfig) -> dict[str, np.ndarray]:
    """Each effect's change (noise sds), per object with its (log m, log mu) refit projected out: (n, 6)."""
    v, m, u = _design()
    out = {}

    def residual(delta: np.ndarray, jac_m: np.ndarray, jac_u: np.ndarray) -> np.ndarray:
        sd = np.array([NOISE[k] for k in NAMES])
        r = delta / sd
        Jm, Ju = jac_m / sd, jac_u / sd
        res = np.empty_like(r)
        for i in range(len(OBJECTS)):
            sl = slice(i * SPEEDS.size, (i + 1) * SPEEDS.size)
            J = np.column_stack([Ju[sl].ravel()] if MASS_MEASURED else [Jm[sl].ravel(), Ju[sl].ravel()])
            c = np.linalg.lstsq(J, r[sl].ravel(), rcond=None)[0]
            res[sl] = (r[sl].ravel() - J @ c).reshape(r[sl].shape)
        return res

    base = table_observables(scene, None, 0.0, v, m, u)
    jm = (table_observables(scene, None, 0.0, v, m * np.exp(H), u) - base) / H
    ju = (table_observables(scene, None, 0.0, v, m, u * np.exp(H)) - base) / H
    for name, x in LIBRARY.items():
        if EFFECTS.get(name) is not None and EFFECTS[name].kind != MODEL:
            vv = v * (1 + x) if name == "speed_gain" else v + x
            obs = table_observables(scene, None, 0.0, vv, m, u)
        else:
            obs = table_observables(scene, name, x, v, m, u)
        out[name] = residual(obs - base, jm, ju)
    wbase = world_observables(scene, {}, v, m, u)
    wjm = (world_observables(scene, {}, v, m * np.exp(H), u) - wbase) / H
    wju = (world_observables(scene, {}, v, m, u * np.exp(H)) - wbase) / H
    for name, params in CONTACTS.items():
        out[f"contact:{name}"] = residual(world_observables(scene, params, v, m, u) - wbase, wjm, wju)
    return out


def analyse(sig: dict[str, np.ndarray]) -> dict:
    table = {}
    for set_name, cols in SETS.items():
        idx = [NAMES.index(c) for c in cols]
        vec = {k: s[:, idx].ravel() for k, s in sig.items()}
        rms = {k: float(np.linalg.norm(x)) for k, x in vec.items()}
        worst = {}
        for a in LIBRARY:
            best, who = 0.0, ""
            for b, y in vec.items():
                if b == a:
                    continue
                na, nb = np.linalg.norm(vec[a]), np.linalg.norm(y)
                c = abs(float(vec[a] @ y)) / (na * nb) if na > 0 and nb > 0 else 0.0
                if c > best:
                    best, who = c, b
            worst[a] = {"cos": best, "with": who}
        table[set_name] = {"rms": rms, "closest": worst}
    return table


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", help="write the analysis here")
    ap.add_argument("--mass-measured", action="store_true", help="the masses are weighed: refit friction alone")
    args = ap.parse_args(argv)
    global MASS_MEASURED
    MASS_MEASURED = args.mass_measured
    out = analyse(signatures(SceneConfig()))
    sets = list(SETS)
    print("Largest |cos| of each library effect with any other effect or contact model, after the (m, mu) refit")
    print("(visible size, noise sds, in brackets)" + (" -- masses weighed" if MASS_MEASURED else "") + ":\n")
    print("| effect | " + " | ".join(sets) + " |")
    print("|---" * (len(sets) + 1) + "|")
    for a in LIBRARY:
        cells = [
            f"{out[s]['closest'][a]['cos']:.2f} {out[s]['closest'][a]['with']} ({out[s]['rms'][a]:.1f})" for s in sets
        ]
        print(f"| {a} | " + " | ".join(cells) + " |")
    print(
        "\nContact models, visible size (noise sds): "
        + "; ".join(
            f"{k.split(':')[1]} " + "/".join(f"{out[s]['rms'][k]:.1f}" for s in sets)
            for k in out[sets[0]]["rms"]
            if k.startswith("contact:")
        )
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
