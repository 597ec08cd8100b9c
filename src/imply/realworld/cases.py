"""The gap benchmark's push logs: what each log holds, drawn at random, simulated in the world, noise added.

Each log is one lab's session: ``n_objects`` boxes of the canonical size, masses and
frictions drawn log-uniformly over the push table's whole range, each pushed once at every
speed of ``speeds`` in a direction drawn uniformly on the table (radians), every push
recorded ``replicates`` times with independent readout noise. The world carries no
effect (null logs: ``null_gaussian`` and ``null_heavy``), one effect, or two at once; magnitudes are drawn log-uniformly over
each effect's range (signed effects of either sign), directional effects at a random
azimuth. What the lab recorded is drawn too: the objects' weighed masses (share
``measured_mass_share`` of the logs) and the stop time of every push (share
``stop_time_share``). Readout noise is multiplicative and log-normal (sd ``noise.sd``
on displacement, ``noise.stop_time_sd`` on stop time), or, in heavy-tailed logs (all
``null_heavy`` logs and share ``heavy_share`` of the others), Student-t with
``noise.heavy_df`` degrees of freedom and sd ``noise.heavy_sd``, plus a few gross
outliers (a displacement read off by a factor exp(+-U(``noise.outlier_size``)), and its
stop time too in half of them).

Logs are named ``log-000``, ``log-001``, ... in a shuffled order, so neither the name nor
the position tells what a log carries. The label of every log (its effects and
magnitudes, the objects' true masses and frictions, the noise, the outliers, the
noise-free observables, and for two-effect logs each effect's noise-free observables on
its own) goes to a sealed file the diagnostic never reads.

The contact benchmark (:class:`ContactBenchmarkConfig`) draws its logs the same way, from
worlds with a contact model of their own (:mod:`imply.realworld.contact`) or on another
engine, with no effect, one library effect or one outside it; a share of its logs pushes
every object in four directions 90 degrees apart at every speed. Its labels also hold the
log's ``engine``, ``contact`` model and push ``design``, and for an effect log the noise-free
observables of the world without the effect (``noise_free["contact"]``).
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pandas as pd

from imply.io import write_csv, write_json
from imply.options import Config, option
from imply.realworld.accuracy import measure_error
from imply.realworld.contact import (
    ContactDraw,
    apply_contact,
    draw_contact,
    engine_effects,
    no_contact_model,
    run_observables,
    simulate_by_engine,
    simulate_engine,
    world_engine,
)
from imply.realworld.effects import EFFECTS, IDENTIFIABLE, LIBRARY, OUTSIDE, apply_effect, draw_magnitude
from imply.realworld.shards import shard_cases
from imply.realworld.world import WorldPushes, WorldStepping
from imply.sim.scene import SceneConfig
from imply.sim.track import filmed, pusher_speed, track_frame_times

log = logging.getLogger("imply.realworld")

GROUPS = ("null_gaussian", "null_heavy", "single", "single_unidentifiable", "double", "outside")
# what the benchmark's scoring measures against a target (config gap.benchmark.targets)
TARGETS = ("false_alarm", "top1", "both_named", "none_outside", "magnitude_error", "shrinkage")
# the contact benchmark (config gap.contact_benchmark): a contact model of the world's own
# (MuJoCo), or another engine's world, with no effect, one library effect or one outside it
CONTACT_GROUPS = ("null_contact", "single_contact", "outside_contact", "null_engine", "single_engine", "outside_engine")
CONTACT_TARGETS = (
    "null_no_library",
    "among_named",
    "contenders_mean",
    "magnitude_within",
    "wrong_single",
    "closed_loop",
    "observed_single_right",
)
DIRECTIONS = 4  # pushes per object and speed in the four-direction design, 90 degrees apart


@dataclass(frozen=True, kw_only=True)
class NoiseModel(Config):
    """Readout noise of the logs (config ``gap.benchmark.noise``)."""

    config_key: ClassVar[str] = "gap.benchmark.noise"

    sd: float = option(0.02, doc="Gaussian noise of log d (sd)", exclusive_minimum=0)
    stop_time_sd: float = option(0.02, doc="Gaussian noise of log stop time (sd)", exclusive_minimum=0)
    pusher_speed_sd: float = option(
        0.01,
        doc="Gaussian noise of the log of the pusher's measured mean speed (sd; encoders: no heavy tails)",
        exclusive_minimum=0,
    )
    track_sd: float = option(
        0.001,
        doc="Gaussian noise of each position of the box's track (m; a camera's, in x and y alike)",
        exclusive_minimum=0,
    )
    track_rate: float = option(60.0, doc="frames per second of the box's track (a camera's)", exclusive_minimum=0)
    heavy_sd: float = option(0.03, doc="scale of the heavy-tailed noise", exclusive_minimum=0)
    heavy_df: float = option(3.0, doc="degrees of freedom of the heavy-tailed (Student t) noise", exclusive_minimum=2)
    outliers: tuple[int, int] = option(
        (2, 4), doc="gross outliers per heavy log, fewest and most", items={"minimum": 0}
    )
    outlier_size: tuple[float, float] = option(
        (0.3, 1.0), doc="size of a gross outlier in log d, least and most", items={"exclusive_minimum": 0}
    )

    def __post_init__(self) -> None:
        for name in ("outliers", "outlier_size"):
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi:
                raise ValueError(f"{name} must be [low, high] with 0 <= low <= high, not {[lo, hi]}")


@dataclass(frozen=True, kw_only=True)
class AccuracyCheck(Config):
    """How the world's own numerical error is measured (config ``gap.benchmark.accuracy``): ``pushes``
    of the benchmark's own and ``nominal`` effect-free ones, stepped ``factor`` times finer."""

    config_key: ClassVar[str] = "gap.benchmark.accuracy"

    pushes: int = option(48, doc="of the benchmark's own pushes", minimum=1)
    nominal: int = option(16, doc="effect-free pushes", minimum=1)
    factor: int = option(4, doc="how many times finer the reference steps", minimum=2)


@dataclass(frozen=True, kw_only=True)
class BenchmarkConfig(Config):
    """The gap benchmark (config ``gap.benchmark``): what its logs hold, and how the diagnoses are judged."""

    config_key: ClassVar[str] = "gap.benchmark"

    seed: int = option(8484, doc="seed of the sealed set's draws", required=True)
    development_seed: int = option(
        1001, doc="seed of the development set's draws (the same design; built by the gap_development target)"
    )
    logs: dict[str, int] = option(
        {"null_gaussian": 20, "null_heavy": 20, "single": 98, "single_unidentifiable": 12, "double": 40, "outside": 48},
        doc="logs per group (a group left out has none)",
        required=True,
        keys=GROUPS,
        items={"minimum": 0},
    )
    n_objects: int = option(8, doc="objects per log", minimum=2, required=True)
    speeds: tuple[float, ...] = option(
        (0.2, 0.34, 0.48, 0.62, 0.76, 0.9),
        doc="push speeds (m/s), with room for speed errors inside the table",
        required=True,
        min_items=2,
        items={"exclusive_minimum": 0},
    )
    masses: tuple[float, float] = option(
        (0.2, 2.0), doc="the objects' mass range (kg, log-uniform)", required=True, items={"exclusive_minimum": 0}
    )
    frictions: tuple[float, float] = option(
        (0.1, 0.6), doc="the objects' friction range (log-uniform)", required=True, items={"exclusive_minimum": 0}
    )
    replicates: int = option(
        2, doc="noise draws per simulated push (pure error for the noise)", minimum=1, required=True
    )
    measured_mass_share: float = option(0.7, doc="share of logs with weighed masses", minimum=0, maximum=1)
    stop_time_share: float = option(0.6, doc="share of logs with stop times", minimum=0, maximum=1)
    heavy_share: float = option(
        0.2, doc="share of effect logs with heavy-tailed noise and gross outliers", minimum=0, maximum=1
    )
    double_range: tuple[float, float] = option(
        (0.3, 1.0),
        doc="two-effect logs: share of each effect's largest magnitude",
        items={"exclusive_minimum": 0, "maximum": 1},
    )
    ranges: dict[str, tuple[float, float]] = option(
        {},
        doc="|magnitude| ranges by effect of imply.realworld.effects (default: each effect's own)",
        items={"exclusive_minimum": 0},
    )
    stribeck_speed: tuple[float, float] = option(
        (0.05, 0.2), doc="range of the Stribeck speed (m/s, log-uniform)", items={"exclusive_minimum": 0}
    )
    noise: NoiseModel = option(NoiseModel(), doc="readout noise of the logs", required=True)
    stepping: WorldStepping = option(WorldStepping(), doc="how the world steps a push")
    # how the diagnoses are judged (imply.realworld.benchmark.score_cases)
    accuracy: AccuracyCheck = option(
        AccuracyCheck(), doc="the world's own error, measured by 'imply study gap generate'"
    )
    min_size_sd: float = option(
        2.0, doc="effects at least this many noise sd (visible RMS) count for the targets", exclusive_minimum=0
    )
    targets: dict[str, float] = option(
        {
            "false_alarm": 0.05,
            "top1": 0.9,
            "both_named": 0.8,
            "none_outside": 0.8,
            "magnitude_error": 0.10,
            "shrinkage": 0.8,
        },
        doc="what the diagnostic must reach (imply.realworld.benchmark.score_cases)",
        keys=TARGETS,
    )

    def __post_init__(self) -> None:
        unknown = sorted(set(self.ranges) - set(EFFECTS))
        if unknown:
            raise ValueError(f"ranges: unknown effect(s) {', '.join(unknown)}")
        pairs = {
            "masses": self.masses,
            "frictions": self.frictions,
            "double_range": self.double_range,
            "stribeck_speed": self.stribeck_speed,
            **{f"ranges.{k}": v for k, v in self.ranges.items()},
        }
        for name, (lo, hi) in pairs.items():
            if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
                raise ValueError(f"{name} must be [low, high] with low <= high, not {[lo, hi]}")

    def range_of(self, name: str) -> tuple[float, float]:
        return self.ranges.get(name, EFFECTS[name].default_range)

    @property
    def n_logs(self) -> int:
        return int(sum(self.logs.values()))


@dataclass(frozen=True, kw_only=True)
class ContactBenchmarkConfig(BenchmarkConfig):
    """The contact benchmark (config ``gap.contact_benchmark``): logs from worlds with a contact model of their
    own (:mod:`imply.realworld.contact`) or from another engine, with no effect, one in the library or one outside.

    A share ``four_share`` of the logs has the four-direction design: every object pushed at
    every speed in 4 directions 90 degrees apart, at a rotation drawn per log; the others push
    every object once per speed in a random direction. One-effect logs draw the magnitude in
    ``effect_range`` times the effect's largest.
    """

    config_key: ClassVar[str] = "gap.contact_benchmark"

    seed: int = option(6868, doc="seed of the sealed set's draws", required=True)
    development_seed: int = option(
        7117, doc="seed of the development set's draws (the same design; built by the gap_development target)"
    )
    logs: dict[str, int] = option(
        {
            "null_contact": 16,
            "single_contact": 20,
            "outside_contact": 10,
            "null_engine": 8,
            "single_engine": 12,
            "outside_engine": 6,
        },
        doc="logs per group (*_engine: the bullet world; a group left out has none)",
        required=True,
        keys=CONTACT_GROUPS,
        items={"minimum": 0},
    )
    heavy_share: float = option(
        0.0, doc="share of effect logs with heavy-tailed noise and gross outliers", minimum=0, maximum=1
    )
    four_share: float = option(0.2, doc="share of logs with the four-direction design", minimum=0, maximum=1)
    effect_range: tuple[float, float] = option(
        (0.3, 1.0),
        doc="one-effect logs: share of the effect's largest magnitude",
        items={"exclusive_minimum": 0, "maximum": 1},
    )
    contact: ContactDraw = option(ContactDraw(), doc="how each MuJoCo log's contact model is drawn", required=True)
    targets: dict[str, float] = option(
        {
            "null_no_library": 0.9,
            "among_named": 0.9,
            "contenders_mean": 3.0,
            "magnitude_within": 0.3,
            "wrong_single": 0.1,
            "closed_loop": 0.6,
            "observed_single_right": 0.8,
        },
        doc="null logs stating no library effect as a cause (share, at least); one-effect logs naming theirs among "
        "the causes or contenders (share, at least), with contenders_mean contenders on average (at most); outside "
        "logs stating a library mechanism as the one cause (share, at most); after the next pushes, "
        "one-effect logs with several contenders stating theirs as the one cause within magnitude_within (share, at "
        "least); with the pusher's measured speed and the box's track, one-effect logs stating theirs as the one cause "
        "within magnitude_within (share, at least)",
        keys=CONTACT_TARGETS,
    )

    groups: ClassVar[tuple[str, ...]] = CONTACT_GROUPS

    def __post_init__(self) -> None:
        super().__post_init__()
        lo, hi = self.effect_range
        if not lo <= hi:
            raise ValueError(f"effect_range must be [low, high] with low <= high, not {[lo, hi]}")


def case_ids(design: BenchmarkConfig) -> list[str]:
    """The logs' names (they say nothing about what a log carries)."""
    width = max(3, len(str(design.n_logs - 1)))
    return [f"log-{k:0{width}d}" for k in range(design.n_logs)]


def _round_robin(names: tuple[str, ...], count: int, rng: np.random.Generator) -> list[str]:
    order = list(names)
    rng.shuffle(order)
    return [order[k % len(order)] for k in range(count)]


def _plans(design: BenchmarkConfig, rng: np.random.Generator) -> list[tuple[str, list[str]]]:
    """Every log's group and effects, in the groups' order."""
    if isinstance(design, ContactBenchmarkConfig):
        out: list[tuple[str, list[str]]] = []
        for group in design.groups:
            kind, world = group.split("_", 1)
            carried = set(engine_effects(world_engine(world)))
            pool = {
                "null": (),
                "single": tuple(n for n in IDENTIFIABLE if n in carried),
                "outside": tuple(n for n in OUTSIDE if n in carried),
            }[kind]
            count = design.logs.get(group, 0)
            if pool:
                out += [(group, [e]) for e in _round_robin(pool, count, rng)]
            else:
                out += [(group, [])] * count
        return out
    plans: list[tuple[str, list[str]]] = []
    plans += [("null_gaussian", [])] * design.logs.get("null_gaussian", 0)
    plans += [("null_heavy", [])] * design.logs.get("null_heavy", 0)
    plans += [("single", [e]) for e in _round_robin(IDENTIFIABLE, design.logs.get("single", 0), rng)]
    unident = tuple(n for n in LIBRARY if n not in IDENTIFIABLE)
    plans += [
        ("single_unidentifiable", [e]) for e in _round_robin(unident, design.logs.get("single_unidentifiable", 0), rng)
    ]
    for _ in range(design.logs.get("double", 0)):
        plans.append(("double", sorted(rng.choice(IDENTIFIABLE, size=2, replace=False).tolist())))
    plans += [("outside", [e]) for e in _round_robin(OUTSIDE, design.logs.get("outside", 0), rng)]
    return plans


def _magnitude_range(design: BenchmarkConfig, group: str, name: str) -> tuple[float, float]:
    hi = design.range_of(name)[1]
    if group == "double":
        return design.double_range[0] * hi, design.double_range[1] * hi
    if isinstance(design, ContactBenchmarkConfig):
        return design.effect_range[0] * hi, design.effect_range[1] * hi
    return design.range_of(name)


def draw_cases(design: BenchmarkConfig) -> list[dict]:
    """Every log's draw (effects, objects, directions, what was measured, noise; in the contact benchmark also
    its engine, contact model and push design), in the logs' order."""
    rng = np.random.default_rng(design.seed)
    plans = _plans(design, rng)
    order = rng.permutation(len(plans))
    ids = case_ids(design)
    cases = []
    n_obj, n_sp = design.n_objects, len(design.speeds)
    for cid, k in zip(ids, order, strict=True):
        group, names = plans[k]
        crng = np.random.default_rng([design.seed, int(k)])
        effects = []
        for name in names:
            lo, hi = _magnitude_range(design, group, name)
            e = {
                "name": name,
                "magnitude": draw_magnitude(crng, name, lo, hi),
                "azimuth": float(crng.uniform(0, 2 * np.pi)) if EFFECTS[name].directional else None,
                "in_library": EFFECTS[name].in_library,
            }
            if name == "stribeck":
                e["stribeck_speed"] = float(np.exp(crng.uniform(*np.log(design.stribeck_speed))))
            effects.append(e)
        heavy = group == "null_heavy" or (group != "null_gaussian" and crng.random() < design.heavy_share)
        cases.append(
            {
                "id": cid,
                "group": group,
                "effects": effects,
                "mass": np.exp(crng.uniform(*np.log(design.masses), n_obj)).tolist(),
                "friction": np.exp(crng.uniform(*np.log(design.frictions), n_obj)).tolist(),
                "direction": crng.uniform(0, 2 * np.pi, n_obj * n_sp).tolist(),
                "measured_mass": bool(crng.random() < design.measured_mass_share),
                "stop_time": bool(crng.random() < design.stop_time_share),
                "noise": "heavy" if heavy else "gaussian",
                "noise_seed": int(crng.integers(2**31)),
            }
        )
        if isinstance(design, ContactBenchmarkConfig):
            cases[-1].update(_contact_draw(design, group, crng))
    return cases


def _contact_draw(design: ContactBenchmarkConfig, group: str, rng: np.random.Generator) -> dict:
    """A contact-benchmark log's engine, contact model and push design (four directions: the log's directions)."""
    engine = world_engine(group.split("_", 1)[1])
    out = {
        "engine": engine,
        "contact": draw_contact(rng, design.contact) if engine == "mujoco" else no_contact_model(),
        "design": "four" if rng.random() < design.four_share else "random",
    }
    if out["design"] == "four":
        rotation = float(rng.uniform(0.0, np.pi / 2))
        quarter = np.tile(np.arange(DIRECTIONS), design.n_objects * len(design.speeds))
        out["direction"] = np.mod(rotation + quarter * (np.pi / 2), 2 * np.pi).tolist()
    return out


def push_layout(case: dict, design: BenchmarkConfig) -> tuple[np.ndarray, np.ndarray]:
    """Object index and commanded speed of every push of ``case``, (n,) each: object by object, speed by speed
    (and, in the four-direction design, direction by direction)."""
    per = DIRECTIONS if case.get("design") == "four" else 1
    sp = np.asarray(design.speeds, float)
    return np.repeat(np.arange(design.n_objects), sp.size * per), np.tile(np.repeat(sp, per), design.n_objects)


def _world_pushes(case: dict, design: BenchmarkConfig, scene: SceneConfig, effects: list[dict]) -> WorldPushes:
    obj, v = push_layout(case, design)
    return pushes_in_world(case, obj, v, np.asarray(case["direction"]), scene, effects)


def pushes_in_world(
    case: dict, obj: np.ndarray, v: np.ndarray, phi: np.ndarray, scene: SceneConfig, effects: list[dict]
) -> WorldPushes:
    """Pushes of ``case``'s objects ``obj`` at speeds ``v`` and directions ``phi``, in its world: its contact model
    and the ``effects`` given."""
    p = WorldPushes.nominal(v, np.asarray(case["mass"])[obj], np.asarray(case["friction"])[obj], phi, scene)
    if "contact" in case:
        apply_contact(p, case["contact"])
    for e in effects:
        apply_effect(p, e["name"], e["magnitude"], e["azimuth"] or 0.0, e)
    return p


def _log_columns(
    case: dict,
    scene: SceneConfig,
    obj: np.ndarray,
    v: np.ndarray,
    phi: np.ndarray,
    displacement: np.ndarray,
    stop_time: np.ndarray | None,
    pusher_speed: np.ndarray,
) -> dict:
    """One noise draw of pushes as the columns a lab's push log holds (stop times and weighed masses where the
    case records them; the pusher's measured mean speed always: a robot's encoders give it)."""
    names = object_names(len(case["mass"]))
    he = scene.box_half_extents
    cols = {
        "object_id": [names[i] for i in obj],
        "speed": v,
        "direction": np.round(phi, 9),
        "displacement": displacement,
    }
    if case["stop_time"]:
        cols["stop_time"] = stop_time
    cols["pusher_speed"] = pusher_speed
    size_z = he[2] * (1.0 + next((e["magnitude"] for e in case["effects"] if e["name"] == "height"), 0.0))
    cols.update(size_x=he[0], size_y=he[1], size_z=size_z)
    if case["measured_mass"]:
        cols["mass"] = np.round(np.asarray(case["mass"])[obj], 3)
    return cols


def object_names(n: int) -> list[str]:
    """The object ids of a benchmark log's ``n`` objects, in their order."""
    return [f"obj{i:02d}" for i in range(n)]


def _noise(rng: np.random.Generator, kind: str, sd: float, heavy_sd: float, df: float, shape) -> np.ndarray:
    if kind == "heavy":
        return rng.standard_t(df, shape) * heavy_sd * np.sqrt((df - 2.0) / df)
    return rng.normal(0.0, sd, shape)


def simulate_cases(
    cases: list[dict],
    design: BenchmarkConfig,
    scene: SceneConfig,
    *,
    nthread: int = 0,
    chunk: int = 2400,
    progress: bool = False,
) -> dict[str, dict]:
    """Noise-free observables of every case (``"all"``), of each effect alone in two-effect cases (by name),
    and in the contact benchmark's effect cases of the world without the effect (``"contact"``); each distinct
    push simulated once (:func:`imply.realworld.contact.simulate_distinct`)."""
    runs: list[tuple[str, str, str, WorldPushes]] = []  # (case id, what, engine, pushes)
    for case in cases:
        engine = case.get("engine", "mujoco")
        runs.append((case["id"], "all", engine, _world_pushes(case, design, scene, case["effects"])))
        if len(case["effects"]) > 1:
            for e in case["effects"]:
                runs.append((case["id"], e["name"], engine, _world_pushes(case, design, scene, [e])))
        if case["effects"] and "engine" in case:
            runs.append((case["id"], "contact", engine, _world_pushes(case, design, scene, [])))
    out: dict[str, dict] = {}
    times = track_frame_times(design.noise.track_rate)
    batches = simulate_by_engine(
        [(r[2], r[3]) for r in runs],
        scene,
        design.stepping,
        nthread=nthread,
        track_times=times,
        chunk=chunk,
        progress=progress,
    )
    for _, mine, bounds, res, _, _ in batches:
        for k, (cid, what, _, _) in enumerate(runs[i] for i in mine):
            # the camera films the log's own pushes
            out.setdefault(cid, {})[what] = run_observables(
                res, slice(bounds[k], bounds[k + 1]), scene.stroke, filmed=what == "all"
            )
    return {case["id"]: out[case["id"]] for case in cases}


def log_track(case: dict, sim: dict, label: dict, design: BenchmarkConfig) -> pd.DataFrame:
    """The box's track of every row of ``case``'s log (:func:`make_log`'s ``label`` says which push and replicate
    each row is), as a camera records it: rows ``object_id,push,t,x,y,yaw`` (:mod:`imply.diagnose.inputs.track_file`),
    positions in the table's frame with the camera's noise, cut shortly after the box stops."""
    nm = design.noise
    times = track_frame_times(nm.track_rate)
    res = sim["all"]
    obj, _ = push_layout(case, design)
    phi = np.asarray(case["direction"], float)
    names = object_names(design.n_objects)
    # the camera's noise from a generator of its own: the log's columns are the same draws with or without a track
    rng = np.random.default_rng([case["noise_seed"], 2])
    parts = []
    for row, (j, _) in enumerate(label["rows_kept"]):
        along, across, yaw = (np.asarray(res["track"][j][:, c], float) for c in range(3))
        keep = filmed(times, res["stop_time"][j])
        c, s = np.cos(phi[j]), np.sin(phi[j])
        x = along * c - across * s + rng.normal(0.0, nm.track_sd, times.size)
        y = along * s + across * c + rng.normal(0.0, nm.track_sd, times.size)
        parts.append(
            pd.DataFrame(
                {
                    "object_id": names[obj[j]],
                    "push": row + 1,
                    "t": np.round(times[keep], 6),
                    "x": np.round(x[keep], 6),
                    "y": np.round(y[keep], 6),
                    "yaw": np.round(yaw[keep], 5),
                }
            )
        )
    columns = ["object_id", "push", "t", "x", "y", "yaw"]
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=columns)


def make_log(case: dict, sim: dict, design: BenchmarkConfig, scene: SceneConfig) -> tuple[pd.DataFrame, dict]:
    """The push log a lab would have written for ``case`` (noise added), and its sealed label."""
    rng = np.random.default_rng(case["noise_seed"])
    n_obj = design.n_objects
    obj, v = push_layout(case, design)
    phi = np.asarray(case["direction"])
    res = sim["all"]
    ok = res["ok"].copy()
    # a lab drops a push whose box tipped or never settled; an object left with too few
    # pushes to fit is dropped whole
    for i in range(n_obj):
        mine = (obj == i) & ok
        if mine.sum() < 3 or np.unique(v[mine]).size < 2:
            ok[obj == i] = False
    nm = design.noise
    reps = design.replicates
    shape = (reps, v.size)
    e_d = _noise(rng, case["noise"], nm.sd, nm.heavy_sd, nm.heavy_df, shape)
    e_t = _noise(rng, case["noise"], nm.stop_time_sd, nm.heavy_sd, nm.heavy_df, shape)
    outliers: list[list[int]] = []
    if case["noise"] == "heavy":
        k = int(rng.integers(nm.outliers[0], nm.outliers[1] + 1))
        flat = rng.choice(np.flatnonzero(np.tile(ok, reps)), size=min(k, int(ok.sum()) * reps), replace=False)
        for f in flat:
            r, j = divmod(int(f), v.size)
            size = rng.uniform(*nm.outlier_size) * rng.choice([-1.0, 1.0])
            e_d[r, j] += size
            if rng.random() < 0.5:
                e_t[r, j] += rng.uniform(*nm.outlier_size) * rng.choice([-1.0, 1.0])
            outliers.append([r, j])
    # the encoders' noise from a generator of its own: the other columns are the same draws with or without it
    e_p = np.random.default_rng([case["noise_seed"], 1]).normal(0.0, nm.pusher_speed_sd, shape)
    names = object_names(n_obj)
    rows = []
    for r in range(reps):
        frame = pd.DataFrame(
            _log_columns(
                case,
                scene,
                obj,
                v,
                phi,
                res["displacement"] * np.exp(e_d[r]),
                res["stop_time"] * np.exp(e_t[r]),
                res["pusher_speed"] * np.exp(e_p[r]),
            )
        )
        frame["_push"] = np.arange(v.size)
        frame["_rep"] = r
        rows.append(frame[ok])
    frame = pd.concat(rows, ignore_index=True).sort_values(["object_id", "speed", "_rep"], kind="stable")
    kept = frame[["_push", "_rep"]].to_numpy()
    frame = frame.drop(columns=["_push", "_rep"]).reset_index(drop=True)

    def observables(r: dict) -> dict:
        return {
            "log_d": np.log(np.maximum(r["displacement"], 1e-9)).tolist(),
            "log_t": np.log(np.maximum(r["stop_time"], 1e-9)).tolist(),
            "log_p": np.log(np.where(r["ok"], r["pusher_speed"], 1.0)).tolist(),
            "ok": r["ok"].tolist(),
        }

    label = {
        "id": case["id"],
        "group": case["group"],
        "effects": case["effects"],
        "noise": {
            "kind": case["noise"],
            "sd": nm.heavy_sd if case["noise"] == "heavy" else nm.sd,
            "stop_time_sd": nm.heavy_sd if case["noise"] == "heavy" else nm.stop_time_sd,
            "pusher_speed_sd": nm.pusher_speed_sd,
            "df": nm.heavy_df if case["noise"] == "heavy" else None,
        },
        "measured_mass": case["measured_mass"],
        "stop_time": case["stop_time"],
        "objects": {names[i]: {"mass": case["mass"][i], "friction": case["friction"][i]} for i in range(n_obj)},
        "pushes": {
            "object": [names[i] for i in obj],
            "speed": v.tolist(),
            "direction": phi.tolist(),
            "kept": ok.tolist(),
        },
        "noise_free": {what: observables(r) for what, r in sim.items()},
        "outliers": outliers,  # [replicate, push] of every gross outlier
        "rows_kept": kept.tolist(),  # [push, replicate] of every row of the log, in its order
        "dropped_pushes": int((~ok).sum()),
    }
    for key in ("engine", "contact", "design"):  # the contact benchmark's
        if key in case:
            label[key] = case[key]
    return frame, label


def reference_seed(case: dict) -> int:
    """The noise seed of ``case``'s reference session: a fresh draw, apart from the log's own."""
    return int(np.random.default_rng([int(case["noise_seed"]), 5]).integers(2**31))


def reference_log(case: dict, sim: dict, design: BenchmarkConfig, scene: SceneConfig) -> pd.DataFrame:
    """The reference session a lab would have recorded of ``case`` before the change: the same world and boxes
    without the effect (``sim["contact"]`` for an effect log, its own world for a null), one push of each of the
    log's pushes, with a fresh draw of the log's noise (:func:`reference_seed`)."""
    world = sim["contact"] if case["effects"] else sim["all"]
    ref_case = {**case, "effects": [], "noise_seed": reference_seed(case)}
    frame, _ = make_log(ref_case, {"all": world}, dataclasses.replace(design, replicates=1), scene)
    return frame


def extra_pushes(
    case: dict,
    design: BenchmarkConfig,
    scene: SceneConfig,
    obj: np.ndarray,
    speed: np.ndarray,
    direction: np.ndarray,
    *,
    seed: int,
    nthread: int = 0,
) -> pd.DataFrame:
    """New pushes of ``case``'s objects (indices ``obj``) at ``speed`` and ``direction``, run in the same world (its
    contact model, engine and effects) with the same protocol and noise as its log: ``design.replicates`` noise
    draws per push (fresh ones, from ``seed``), the log's columns, pushes whose box failed the world's checks left
    out."""
    obj, v, phi = np.asarray(obj, int), np.asarray(speed, float), np.asarray(direction, float)
    p = pushes_in_world(case, obj, v, phi, scene, case["effects"])
    res = simulate_engine(p, scene, design.stepping, engine=case.get("engine", "mujoco"), nthread=nthread)
    rng = np.random.default_rng([case["noise_seed"], seed])
    rng_p = np.random.default_rng([case["noise_seed"], seed, 1])
    nm = design.noise
    frames = []
    ok = np.asarray(res.ok, bool) & np.isfinite(res.stroke_time)
    for _ in range(design.replicates):
        d = res.displacement * np.exp(_noise(rng, case["noise"], nm.sd, nm.heavy_sd, nm.heavy_df, v.shape))
        t = (
            res.stop_time * np.exp(_noise(rng, case["noise"], nm.stop_time_sd, nm.heavy_sd, nm.heavy_df, v.shape))
            if case["stop_time"]
            else None
        )
        p = pusher_speed(scene.stroke, res.stroke_time) * np.exp(rng_p.normal(0.0, nm.pusher_speed_sd, v.shape))
        frames.append(pd.DataFrame(_log_columns(case, scene, obj, v, phi, d, t, p))[ok])
    return pd.concat(frames, ignore_index=True)


def write_benchmark_logs(
    design: BenchmarkConfig,
    scene: SceneConfig,
    *,
    logs: Path,
    sealed: Path,
    accuracy: Path | None,
    table_error: dict | None = None,
    nthread: int = 0,
    progress: bool = True,
    shard: int = 0,
    shards: int = 1,
) -> dict | None:
    """Simulate every log into ``logs/<id>.csv``, seal the labels in ``sealed``, and measure the world's
    own numerical error into ``accuracy`` (beside the table's, ``table_error``). Returns that error.

    With ``shards`` > 1, only the logs of shard ``shard`` (:func:`imply.realworld.shards.shard_cases`) and their
    labels; the world's error, measured on a sample of every log's pushes (the same whichever shard measures it),
    only where ``accuracy`` is given (None: not measured, None returned)."""
    drawn = draw_cases(design)
    cases = shard_cases(drawn, shard, shards)
    log.info(
        "simulating %d logs (%d objects x %d speeds each) in the world%s",
        len(cases),
        design.n_objects,
        len(design.speeds),
        f" (shard {shard} of {shards})" if shards > 1 else "",
    )
    sims = simulate_cases(cases, design, scene, nthread=nthread, progress=progress)
    labels = {}
    for case in cases:
        frame, label = make_log(case, sims[case["id"]], design, scene)
        write_csv(logs / f"{case['id']}.csv", frame)
        write_csv(logs / f"{case['id']}.track.csv", log_track(case, sims[case["id"]], label, design))
        labels[case["id"]] = label
    error = None
    if accuracy is not None:
        check = design.accuracy
        log.info("measuring the world's numerical error on %d of its pushes", check.pushes + check.nominal)
        # the MuJoCo world's error (another engine's logs are that engine's; its convergence is its module's)
        world_cases = [c for c in drawn if c.get("engine", "mujoco") == "mujoco"] or drawn
        sample, nominal = accuracy_sample(world_cases, design, scene, check.pushes, check.nominal)
        error = measure_error(
            sample, nominal, scene, design.stepping, factor=check.factor, nthread=nthread, progress=progress
        )
        error["table_numerical_error"] = table_error
        error["stepping"] = design.stepping.to_dict()
        write_json(accuracy, error)
    write_json(sealed, labels)
    return error


def accuracy_sample(
    cases: list[dict], design: BenchmarkConfig, scene: SceneConfig, n: int, n_nominal: int, seed: int = 0
) -> tuple[WorldPushes, WorldPushes]:
    """Pushes drawn from the benchmark's own logs (effects and all), and pushes of the nominal world."""
    rng = np.random.default_rng([design.seed, seed])
    picks = []
    for k in rng.choice(len(cases), size=n, replace=len(cases) < n):
        case = cases[int(k)]
        p = _world_pushes(case, design, scene, case["effects"])
        picks.append(p.subset(np.array([int(rng.integers(p.n))])))
    n_obj = n_nominal
    sp = np.asarray(design.speeds, float)
    nominal = WorldPushes.nominal(
        rng.choice(sp, n_obj),
        np.exp(rng.uniform(*np.log(design.masses), n_obj)),
        np.exp(rng.uniform(*np.log(design.frictions), n_obj)),
        rng.uniform(0, 2 * np.pi, n_obj),
        scene,
    )
    return WorldPushes.concat(picks), nominal
