"""The diagnostic's benchmark: synthetic "real" push logs with a withheld effect, and scoring.

Generation is a separate code path from the diagnostic's: it simulates every push
directly (no tables, no interpolation) on its own scene, whose timestep differs from the
table's (config ``gap.benchmark.timestep``), and it injects effects its own way:
a table tilt rotates gravity in full (the across-push component too, which the
diagnostic does not model), anisotropic friction and speed errors are applied per push,
and two effects outside the library are available: ``friction_patch`` (the table's
friction is higher by a fraction beyond a line a few centimetres ahead of the box: friction
that varies along the table) and ``force_limit`` (the pusher's servo saturates at a lower
force, in newtons).

Each case's label (effect and magnitude) goes to a sealed file that the diagnose rule
never receives; the log holds only what a user would record: object_id, speed,
direction, displacement (with multiplicative log-normal noise), box size and, with
``measured_mass``, each object's mass as weighed (to the gram).
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import mujoco
import numpy as np
import pandas as pd

from imply.io import write_csv, write_json
from imply.options import Config
from imply.sim.effects import EFFECTS, FRICTION, MODEL, SPEC_EDITS, SPEED
from imply.sim.pushes import simulate_pushes
from imply.sim.scene import SceneConfig, build_xml

log = logging.getLogger("imply.diagnose")

OUTSIDE = ("friction_patch", "force_limit")


@dataclass(frozen=True, kw_only=True)
class BenchmarkConfig(Config):
    """The benchmark (config ``gap.benchmark``): which cases, and what a synthetic log holds."""

    config_key: ClassVar[str] = "gap.benchmark"

    seed: int = 4242
    null_logs: int = 20
    magnitude_fractions: tuple[float, ...] = (0.3, 0.6, 1.0)
    effects: tuple[str, ...] = ()
    outside: dict[str, tuple[float, ...]] = field(default_factory=dict)
    min_size_sd: float = 2.0
    targets: dict[str, float] = field(default_factory=lambda: {"top1": 0.9, "false_alarm": 0.05, "shrinkage": 0.8})
    n_objects: int = 20
    speeds: tuple[float, ...] = (0.25, 0.35, 0.45, 0.55, 0.65, 0.75, 0.85)
    directions: tuple[float, ...] = (
        0.0,
        1.5707963267948966,
        3.141592653589793,
        4.71238898038469,
    )
    replicates: int = 2
    masses: tuple[float, float] = (0.3, 1.5)
    frictions: tuple[float, float] = (0.15, 0.45)
    noise_sd: float = 0.02
    timestep: float = 0.0009
    measured_mass: bool = False  # write each object's mass (weighed: exact to the gram) into the log


def case_list(cfg: BenchmarkConfig) -> list[dict]:
    """All benchmark cases (id, effect, magnitude, seed) from config ``gap.benchmark``."""
    cases = []
    seed = cfg.seed
    for k in range(cfg.null_logs):
        cases.append(
            {
                "id": f"null-{k:02d}",
                "effect": "null",
                "magnitude": 0.0,
                "seed": seed + k,
            }
        )
    fracs = cfg.magnitude_fractions
    for e in cfg.effects:
        lo, hi = EFFECTS[e].bounds
        for j, fr in enumerate(fracs):
            # signed effects alternate sign across levels so both sides are tested
            sign = -1.0 if (lo < 0 and j % 2 == 1) else 1.0
            val = fr * (hi if sign > 0 else lo)
            cases.append(
                {
                    "id": f"{e}-{j}",
                    "effect": e,
                    "magnitude": float(val),
                    "seed": seed + 1000 + 10 * len(cases),
                }
            )
    for e, vals in cfg.outside.items():
        for j, val in enumerate(vals):
            cases.append(
                {
                    "id": f"{e}-{j}",
                    "effect": e,
                    "magnitude": float(val),
                    "seed": seed + 5000 + 10 * len(cases),
                }
            )
    return cases


def _objects(design: BenchmarkConfig, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    m = np.exp(rng.uniform(*np.log(design.masses), design.n_objects))
    mu = np.exp(rng.uniform(*np.log(design.frictions), design.n_objects))
    return m, mu


def _tilted_gravity(g: float, angle: float, axis: str, phi: float) -> list[float]:
    # table tilted by `angle` (downhill along table +x for axis x, +y for axis y); the
    # scene's +x is the push direction phi in the table frame
    gt = np.array([g * np.sin(angle), 0.0]) if axis == "x" else np.array([0.0, g * np.sin(angle)])
    c, s = np.cos(phi), np.sin(phi)
    return [
        float(c * gt[0] + s * gt[1]),
        float(-s * gt[0] + c * gt[1]),
        float(-g * np.cos(angle)),
    ]


def simulate_case(
    case: dict, base_scene: SceneConfig, design: BenchmarkConfig, nthread: int = 0
) -> tuple[pd.DataFrame, dict]:
    """The push log of one case (noise added) and its sealed label with the truth per object."""
    rng = np.random.default_rng(case["seed"])
    scene = SceneConfig.from_dict({**base_scene.to_dict(), "timestep": design.timestep})
    m, mu = _objects(design, rng)
    n_obj, sp, dirs = (
        design.n_objects,
        np.asarray(design.speeds),
        np.asarray(design.directions),
    )
    # each object is pushed once per speed, the direction rotating with the speed index
    obj = np.repeat(np.arange(n_obj), sp.size)
    v = np.tile(sp, n_obj)
    phi = dirs[(np.tile(np.arange(sp.size), n_obj) + obj) % dirs.size]
    fr = mu[obj].copy()
    vv = v.copy()
    effect, val = case["effect"], float(case["magnitude"])
    disp = np.full(v.size, np.nan)
    ok = np.ones(v.size, bool)

    def run(idx: np.ndarray, model: mujoco.MjModel | None, sc: SceneConfig | None = None) -> None:
        res = simulate_pushes(
            vv[idx],
            m[obj[idx]],
            fr[idx],
            scene=sc or scene,
            model=model,
            nthread=nthread,
        )
        disp[idx] = res.displacement
        ok[idx] = res.ok

    everything = np.arange(v.size)
    if effect == "null" or val == 0.0:
        run(everything, None)
    elif effect in EFFECTS and EFFECTS[effect].kind == SPEED:
        vv = v * (1.0 + val) if effect == "speed_gain" else v + val
        run(everything, None)
    elif effect in EFFECTS and EFFECTS[effect].kind == FRICTION:
        fr = fr * (1.0 + val * np.cos(2.0 * phi))
        run(everything, None)
    elif effect in ("tilt_x", "tilt_y"):
        g = 9.81
        for d in np.unique(phi):
            spec = mujoco.MjSpec.from_string(build_xml(scene))
            spec.option.gravity = _tilted_gravity(g, val, effect[-1], float(d))
            run(np.flatnonzero(phi == d), spec.compile())
    elif effect in EFFECTS and EFFECTS[effect].kind == MODEL:
        spec = mujoco.MjSpec.from_string(build_xml(scene))
        SPEC_EDITS[EFFECTS[effect].table_key](spec, val)
        run(everything, spec.compile())
    elif effect == "force_limit":
        run(
            everything,
            None,
            SceneConfig.from_dict({**scene.to_dict(), "pusher_force_limit": val}),
        )
    elif effect == "friction_patch":
        for i in range(n_obj):
            run(np.flatnonzero(obj == i), _patch_model(scene, float(mu[i]), val))
    else:
        raise ValueError(f"unknown benchmark effect {effect!r}")
    if not ok.all():
        log.warning(
            "case %s: %d of %d pushes failed the simulator's checks",
            case["id"],
            int((~ok).sum()),
            ok.size,
        )
    reps = design.replicates
    noise = rng.normal(0.0, design.noise_sd, (reps, v.size))
    he = scene.box_half_extents
    rows = []
    for r in range(reps):
        rows.append(pd.DataFrame({
            "object_id": [f"obj{i:03d}" for i in obj], "speed": v, "direction": np.round(phi, 9),
            "displacement": disp * np.exp(noise[r]),
            "size_x": he[0], "size_y": he[1], "size_z": he[2],
            **({"mass": np.round(m[obj], 3)} if design.measured_mass else {}),
        }))  # fmt: skip
    frame = pd.concat(rows, ignore_index=True).sort_values(["object_id", "speed"], kind="stable")
    label = {
        **case, "timestep": design.timestep, "noise_sd": design.noise_sd,
        "failed_pushes": int((~ok).sum()),
        "measured_mass": bool(design.measured_mass),
        "objects": {f"obj{i:03d}": {"mass": float(m[i]), "friction": float(mu[i])} for i in range(n_obj)},
        "noise_free_log_d": {"object": [f"obj{i:03d}" for i in obj], "speed": v.tolist(), "direction": phi.tolist(),
                             "log_d": np.log(np.maximum(disp, 1e-9)).tolist()},
    }  # fmt: skip
    return frame.reset_index(drop=True), label


def generate_logs(
    config: BenchmarkConfig, scene: SceneConfig, logs: Path, sealed: Path, *, nthread: int = 0, progress: bool = True
) -> int:
    """Simulate every case of :func:`case_list` into ``logs/<case>.csv``; labels to ``sealed``. Returns the count."""
    from tqdm.auto import tqdm

    labels = {}
    for case in tqdm(case_list(config), desc="synthetic logs", unit="log", disable=not progress):
        frame, label = simulate_case(case, scene, config, nthread=nthread)
        write_csv(logs / f"{case['id']}.csv", frame)
        labels[case["id"]] = label
    write_json(sealed, labels)
    return len(labels)


def find_summaries(labels: dict[str, dict], report_dirs: list[Path]) -> dict[str, dict]:
    """Each case's diagnosis summary, from the folder of report folders that holds it."""
    summaries = {}
    for cid in labels:
        found = [r / cid / "summary.json" for r in report_dirs if (r / cid / "summary.json").is_file()]
        if not found:
            raise FileNotFoundError(f"no diagnosis for case {cid} in {', '.join(map(str, report_dirs))}")
        with open(found[0]) as fh:
            summaries[cid] = json.load(fh)
    return summaries


def _patch_model(scene: SceneConfig, mu: float, frac: float, start: float = 0.03) -> mujoco.MjModel:
    """Table whose friction is mu (1 + frac) beyond ``start`` metres ahead of the box's front face."""
    spec = mujoco.MjSpec.from_string(build_xml(scene))
    table = spec.geom("table")
    table.contype = 0
    table.conaffinity = 0
    x0 = scene.box_half_extents[0] + start
    for name, cx, f, prio in (
        ("near", x0 - 1.5, mu, 0),
        ("far", x0 + 1.5, mu * (1.0 + frac), 3),
    ):
        g = spec.worldbody.add_geom()
        g.name = f"table_{name}"
        g.type = mujoco.mjtGeom.mjGEOM_BOX
        g.size = [1.5, 1.5, 0.05]
        g.pos = [cx, 0.0, -0.05]
        g.friction = [f, 0.005, 0.0001]
        g.priority = prio
        g.contype = 1
        g.conaffinity = 1
    return spec.compile()


# -- scoring --------------------------------------------------------------------------


def visible_size(label: dict, table, grid: int = 101) -> float:
    """RMS log d residual of the noise-free log after each object's baseline (m, mu) fit
    (mu only where the log carries the measured mass, as the diagnostic does).

    The part of the injected effect (plus the generator's timestep difference) that no
    choice of mass and friction can absorb: what the diagnostic can possibly see.
    """
    from imply.diagnose.fit import Problem
    from imply.diagnose.pushlog import PushLog

    nf = label["noise_free_log_d"]
    objects = list(dict.fromkeys(nf["object"]))
    index = {o: i for i, o in enumerate(objects)}
    v = np.asarray(nf["speed"], float)
    # the diagnostic holds a measured mass fixed, so the visible part is judged the same way
    mass = np.array([round(label["objects"][o]["mass"], 3) for o in objects]) if label.get("measured_mass") else None
    pl = PushLog(path="<noise-free>", frame=pd.DataFrame(), objects=objects, mass=mass,
                 obj=np.array([index[o] for o in nf["object"]]), speed=v,
                 displacement=np.exp(np.asarray(nf["log_d"], float)),
                 direction=np.asarray(nf["direction"], float), has_direction=True)  # fmt: skip
    fit = Problem(pl, table, None, grid=grid).initial_fit()
    return float(np.sqrt(fit.sse.sum() / v.size))


def _members(cls: str | None) -> list[str]:
    return [] if not cls or cls == "none" else cls.split("+")


def score_cases(
    labels: dict[str, dict],
    summaries: dict[str, dict],
    sizes: dict[str, float],
    *,
    config: BenchmarkConfig,
) -> dict:
    """Benchmark metrics from sealed labels, diagnose summaries and visible sizes.

    The result holds every case's row (``cases``), the confusion matrix, the rates the
    gap stage reports (``top1_big``, ``false_alarm``, ``none_recall_outside``, ...), and
    the settings they were judged by (``noise_sd``, ``min_size_sd``, ``targets``).
    """
    min_size_sd = config.min_size_sd
    from imply.diagnose.analysis import DiagnosisConfig, decide

    rows = []
    for cid in sorted(labels):
        lab, s = labels[cid], summaries[cid]
        eff = lab["effect"]
        group = "null" if eff == "null" else ("outside" if eff in OUTSIDE else "library")
        verdict = s["verdict"]
        predicted = verdict["effect"] or "none"
        members = _members(verdict["class"])
        opts = DiagnosisConfig.from_dict(s["options"])
        if group == "library":
            correct = eff in members
            removed = decide(
                s["ranking"],
                s["aliasing"],
                len(s["ranking"]) - 1,
                opts,
                s["noise"],
                exclude=(eff,),
            )
            removed_pred = removed["effect"] or "none"
            alias_mates = [m for m in s["aliasing"]["effects"][eff]["class"].split("+") if m != eff]
            removed_ok_none = removed_pred == "none"
            removed_ok_alias = removed_pred in alias_mates
        else:
            correct = predicted == "none"
            removed_pred, removed_ok_none, removed_ok_alias = None, None, None
        mag = next((r["magnitude"] for r in s["ranking"] if r["effect"] == eff), None) if group == "library" else None
        rel_err = abs(mag - lab["magnitude"]) / abs(lab["magnitude"]) if mag is not None and lab["magnitude"] else None
        size = sizes[cid]
        rows.append({
            "case": cid, "group": group, "effect": eff, "magnitude": lab["magnitude"], "visible_rms": size,
            "size_sd": size / lab["noise_sd"], "big": bool(size >= min_size_sd * lab["noise_sd"]),
            "predicted": predicted, "predicted_class": verdict["class"] or "none", "correct": bool(correct),
            "removed_predicted": removed_pred, "removed_none": removed_ok_none, "removed_alias": removed_ok_alias,
            "magnitude_hat": mag, "magnitude_rel_error": rel_err,
            "gap_share_closed": s["shrinkage"]["gap_share_closed"], "anchored_share_closed": s["shrinkage"]["anchored_share_closed"],
            "before_rms": s["shrinkage"]["before_rms"], "after_rms": s["shrinkage"]["after_rms"],
        })  # fmt: skip
    frame = pd.DataFrame(rows)

    def rate(mask) -> tuple[float, int]:
        sub = frame[mask]
        return (float(sub["correct"].mean()) if len(sub) else float("nan")), len(sub)

    lib = frame["group"] == "library"
    big = lib & frame["big"]
    null = frame["group"] == "null"
    out = frame["group"] == "outside"
    top1_big, n_big = rate(big)
    top1_all, n_lib = rate(lib)
    fa = float((~frame.loc[null, "correct"]).mean()) if null.any() else float("nan")
    none_recall, n_out = rate(out)
    rem = frame[big]
    removed_none = float(rem["removed_none"].astype(float).mean()) if len(rem) else float("nan")
    removed_ok = float((rem["removed_none"] | rem["removed_alias"]).astype(float).mean()) if len(rem) else float("nan")
    ok_big = frame[big & frame["correct"]]
    mag_err = float(np.nanmedian(ok_big["magnitude_rel_error"].astype(float))) if len(ok_big) else float("nan")
    shares = frame.loc[big, "gap_share_closed"].astype(float)
    anch = frame.loc[big, "anchored_share_closed"].astype(float)
    truth = frame["effect"].where(frame["group"] != "outside", "outside:" + frame["effect"])
    confusion = pd.crosstab(truth, frame["predicted"]).sort_index()
    return {
        "cases": rows,
        "confusion": {r: {c: int(confusion.loc[r, c]) for c in confusion.columns} for r in confusion.index},
        "top1_big": top1_big, "n_big": n_big, "top1_all": top1_all, "n_library": n_lib,
        "false_alarm": fa, "n_null": int(null.sum()),
        "none_recall_outside": none_recall, "n_outside": n_out,
        "removed_none_recall": removed_none, "removed_none_or_alias": removed_ok,
        "magnitude_rel_error_median": mag_err,
        "shrinkage_median": float(np.nanmedian(shares)) if shares.notna().any() else float("nan"),
        "anchored_shrinkage_median": float(np.nanmedian(anch)) if anch.notna().any() else float("nan"),
        "null_visible_rms_median": float(frame.loc[null, "visible_rms"].median()) if null.any() else float("nan"),
        "min_size_sd": min_size_sd,
        "noise_sd": config.noise_sd,
        "timestep": config.timestep,
        "measured_mass": config.measured_mass,
        "targets": dict(config.targets),
    }  # fmt: skip
