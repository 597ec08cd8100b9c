"""Calibration probes a lab runs beside its pushes, simulated in a benchmark world.

Three probes, each minutes of a robot lab's time, each measuring something the pushes
alone leave entangled with the contact:

- a **free stroke**: the pusher's stroke with no box (the box 10 m beyond its reach) at a
  commanded speed, and the pusher's measured mean speed over it (its encoders'). It
  measures the pusher's speed gain and offset with no contact at all;
- a **friction measurement** per object, what the world's own pull test reads: a test
  drive (:class:`ProbeDesign` ``pull_*``: a stiff velocity drive, far stiffer than the
  rig's servo) drags the box at a slow constant speed over a few centimetres, and the
  drive's mean force over the second half of the drag, over the box's weight, is the
  reading. On an engine whose contact differs from the table's, or with a tilt, a
  speed-dependent friction or a drag, the reading differs from the world's friction
  parameter, as a robot's would. It comes with its stated uncertainty (``friction_sd``),
  meant as a prior, not a value to hold fixed;
- a **known added mass**: the same box pushed again with a weighed load on it
  (``added_mass_share`` of its mass, kept inside the table's mass range), at the log's
  lowest and highest speed.

:func:`probe_pushes` lays the probes of a log out as world pushes (its contact model
and effects applied, as to its pushes), :func:`probe_observables` reads what each
probe measured from the simulation, and :func:`probe_rows` writes the rows a lab
records, with noise (:mod:`imply.diagnose.inputs.probes` reads them). :func:`simulate_probe_table`
runs the same probes on a user's push model, beside a push log ``imply sim pushes`` wrote
(the free strokes and pull tests stepped by the world's code path, the added-mass pushes by
the simulator of the log's own pushes; no noise added).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import mujoco
import numpy as np
import pandas as pd

from imply.options import Config, option
from imply.realworld.world import PARAMETERS, WorldPushes, WorldResult, WorldStepping, run_model
from imply.sim.push_file import simulate_push_table
from imply.sim.scene import GRAVITY, SceneConfig, build_xml
from imply.sim.track import pusher_speed

PROBE_KINDS = ("free_stroke", "friction", "added_mass")
PROBE_COLUMNS = [
    "probe",
    "object_id",
    "speed",
    "direction",
    "pusher_speed",
    "displacement",
    "stop_time",
    "added_mass",
    "friction",
    "friction_sd",
]


@dataclass(frozen=True, kw_only=True)
class ProbeDesign(Config):
    """The calibration probes of a benchmark log (config ``gap.lab_benchmark.probes``)."""

    config_key: ClassVar[str] = "gap.lab_benchmark.probes"

    free_strokes: int = option(2, doc="free strokes per speed of the log (each read with its own noise)", minimum=1)
    friction_sd: float = option(
        0.06,
        doc="stated uncertainty (one sd, absolute) of a friction measurement; also its error's sd",
        exclusive_minimum=0,
    )
    pull_speed: float = option(0.1, doc="m/s, the pull test's drag speed", exclusive_minimum=0)
    pull_stroke: float = option(0.02, doc="m the pull test drags the box", exclusive_minimum=0, maximum=0.04)
    pull_kv: float = option(2000.0, doc="N s/m, the pull test drive's velocity gain", exclusive_minimum=0)
    pull_carriage_mass: float = option(2.0, doc="kg, the pull test drive's moving mass", exclusive_minimum=0)
    added_mass_share: float = option(
        0.5, doc="the load added to a box, as a share of its mass (kept inside max_mass)", exclusive_minimum=0
    )
    max_mass: float = option(2.0, doc="kg a loaded box may weigh at most (the table's mass range)", exclusive_minimum=0)
    min_added_mass: float = option(0.05, doc="kg: a smaller load is not run", exclusive_minimum=0)


@dataclass(frozen=True)
class ProbeLayout:
    """Which probe each simulated probe push is: ``kind`` (n,) of :data:`PROBE_KINDS`, ``obj`` (n,) the object's
    index (-1 for a free stroke), ``speed`` (n,) commanded (m/s; the pull speed for a friction test),
    ``direction`` (n,) rad, ``added_mass`` (n,) kg (0 but for added-mass pushes)."""

    kind: np.ndarray
    obj: np.ndarray
    speed: np.ndarray
    direction: np.ndarray
    added_mass: np.ndarray

    @property
    def n(self) -> int:
        return int(self.kind.size)


def probe_layout(mass: np.ndarray, speeds: np.ndarray, directions: np.ndarray, design: ProbeDesign) -> ProbeLayout:
    """The probes of a log of objects of ``mass`` (kg, (n_obj,)) pushed at ``speeds``; ``directions`` (n_obj,): the
    direction each object's probes take (rad)."""
    mass = np.asarray(mass, float)
    speeds = np.unique(np.asarray(speeds, float))
    kinds, objs, vs, phis, loads = [], [], [], [], []
    for v in speeds:
        kinds.append("free_stroke"), objs.append(-1), vs.append(v), phis.append(0.0), loads.append(0.0)
    for i in range(mass.size):
        kinds.append("friction"), objs.append(i), vs.append(design.pull_speed), phis.append(directions[i])
        loads.append(0.0)
    for i, m in enumerate(mass):
        load = round(min(design.added_mass_share * m, design.max_mass - m), 3)
        if load < design.min_added_mass:
            continue
        for v in (speeds[0], speeds[-1]):
            kinds.append("added_mass"), objs.append(i), vs.append(v), phis.append(directions[i]), loads.append(load)
    return ProbeLayout(
        np.array(kinds), np.array(objs, int), np.array(vs, float), np.array(phis, float), np.array(loads, float)
    )


def probe_pushes(layout: ProbeLayout, pushes: WorldPushes, design: ProbeDesign) -> WorldPushes:
    """The probes as world pushes: ``pushes`` are the same probes laid out as pushes of the log's world (its
    objects, contact model and effects applied); here the free strokes lose their box, the friction tests get the
    test drive and its drag, and the added-mass pushes their load."""
    p = pushes
    free = layout.kind == "free_stroke"
    pull = layout.kind == "friction"
    p.params["free"][free] = 1.0
    p.params["stroke"][pull] = design.pull_stroke
    p.params["servo_kv"][pull] = design.pull_kv
    p.params["carriage_mass"][pull] = design.pull_carriage_mass
    p.params["force_limit"][pull] = 1000.0
    p.mass[:] = p.mass + layout.added_mass
    return p


def probe_observables(layout: ProbeLayout, res: WorldResult, pushes: WorldPushes, stroke: float) -> dict[str, list]:
    """What each probe measured, noise-free: ``log_p`` the pusher's mean speed (free strokes, added-mass pushes),
    ``reading`` the pull test's friction, ``log_d``, ``log_t`` (added-mass pushes), ``ok``; (n,) lists each, NaN
    where a probe does not measure it. ``pushes``: the probes as simulated (:func:`probe_pushes`).

    The pull test's gauge sits between the drive and the box: it reads the drive's force less what holds the test
    drive's own mass on its rail (a tilted table pulls it along too; the lab tares the gauge on its rail), over the
    weighed box's weight."""
    g = GRAVITY
    rail = g * np.sin(pushes.params["tilt"]) * np.cos(pushes.params["tilt_azimuth"] - pushes.direction)
    gauge = res.drive_force + pushes.params["carriage_mass"] * rail
    obj_mass = np.asarray(pushes.mass, float)
    n = layout.n
    free = layout.kind == "free_stroke"
    pull = layout.kind == "friction"
    added = layout.kind == "added_mass"
    speed = pusher_speed(stroke, res.stroke_time)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_p = np.where(free | added, np.log(speed), np.nan)
        reading = np.where(pull, gauge / (obj_mass * g), np.nan)
        log_d = np.where(added, np.log(np.maximum(res.displacement, 1e-9)), np.nan)
        log_t = np.where(added, np.log(np.maximum(res.stop_time, 1e-9)), np.nan)
    ok = np.zeros(n, bool)
    ok[free] = np.isfinite(log_p[free])
    ok[pull] = np.isfinite(reading[pull]) & (reading[pull] > 0)
    ok[added] = np.asarray(res.ok, bool)[added] & np.isfinite(log_p[added])
    return {
        "kind": layout.kind.tolist(),
        "object": layout.obj.tolist(),
        "speed": layout.speed.tolist(),
        "added_mass": layout.added_mass.tolist(),
        "log_p": log_p.tolist(),
        "reading": reading.tolist(),
        "log_d": log_d.tolist(),
        "log_t": log_t.tolist(),
        "ok": ok.tolist(),
    }


def probe_rows(
    observed: dict[str, list],
    layout: ProbeLayout,
    names: list[str],
    *,
    design: ProbeDesign,
    replicates: int,
    sd: float,
    stop_time_sd: float,
    pusher_speed_sd: float,
    with_stop_time: bool,
    rng: np.random.Generator,
) -> pd.DataFrame:
    """The probe rows a lab records (:data:`PROBE_COLUMNS`; empty cells where a probe measures nothing), noise
    added: log-normal on speeds, displacements and stop times (``replicates`` draws of each free stroke and
    added-mass push, as the log's pushes), Gaussian of sd ``design.friction_sd`` on a friction reading (one per
    object). Probes that failed their world's checks are left out."""
    rows: list[dict] = []
    ok = np.asarray(observed["ok"], bool)
    for j in range(layout.n):
        kind = str(layout.kind[j])
        # the log's replicate readings of each pushed box; a free stroke is repeated free_strokes times
        reps = {"friction": 1, "free_stroke": design.free_strokes}.get(kind, replicates)
        for _ in range(reps):
            row = dict.fromkeys(PROBE_COLUMNS, "")
            row["probe"] = kind
            if kind == "free_stroke":
                row["speed"] = layout.speed[j]
                row["pusher_speed"] = np.exp(observed["log_p"][j] + rng.normal(0.0, pusher_speed_sd))
            elif kind == "friction":
                row["object_id"] = names[layout.obj[j]]
                row["friction"] = max(observed["reading"][j] + rng.normal(0.0, design.friction_sd), 0.01)
                row["friction_sd"] = design.friction_sd
                # the drag's speed and direction: what the test reads under a tilt, a drag or anisotropy depends on them
                row["speed"] = layout.speed[j]
                row["direction"] = round(float(layout.direction[j]), 9)
            else:
                row.update(
                    object_id=names[layout.obj[j]],
                    speed=layout.speed[j],
                    direction=round(float(layout.direction[j]), 9),
                    added_mass=layout.added_mass[j],
                )
                row["displacement"] = np.exp(observed["log_d"][j] + rng.normal(0.0, sd))
                t = np.exp(observed["log_t"][j] + rng.normal(0.0, stop_time_sd))
                row["pusher_speed"] = np.exp(observed["log_p"][j] + rng.normal(0.0, pusher_speed_sd))
                if with_stop_time:
                    row["stop_time"] = t
            if ok[j]:
                rows.append(row)
    return pd.DataFrame(rows, columns=PROBE_COLUMNS)


def model_pushes(model: mujoco.MjModel, speed, mass, friction, direction) -> WorldPushes:
    """Pushes of a push model (a user's MJCF, with the names :mod:`imply.sim.scene` requires) at its own carriage,
    servo and stroke."""
    speed, mass, friction, direction = (
        np.asarray(x, float).ravel().copy() for x in np.broadcast_arrays(speed, mass, friction, direction)
    )
    servo = model.actuator("servo").id
    own = {
        "carriage_mass": float(model.body("pusher").mass[0]),
        "servo_kv": float(model.actuator_gainprm[servo, 0]),
        "force_limit": float(model.actuator_forcerange[servo, 1]),
        "stroke": float(np.asarray(model.numeric("stroke").data)[0]),
    }
    params = {k: np.full(speed.size, own[k] if v is None else float(v)) for k, v in PARAMETERS.items()}
    return WorldPushes(speed, mass, friction, direction, params)


def simulate_model_probes(
    model: mujoco.MjModel,
    objects: pd.DataFrame,
    speeds: np.ndarray,
    design: ProbeDesign,
    *,
    simulate_added,
    nthread: int = 0,
) -> pd.DataFrame:
    """Probe rows (:data:`PROBE_COLUMNS`, noise-free) for a push model: a free stroke at every speed of ``speeds``
    and a pull test of every object of ``objects`` (``object_id,mass,friction``) stepped by the benchmark world's
    code path (:func:`imply.realworld.world.run_model`), and each object pushed with its load at the lowest and
    highest speed by ``simulate_added(object_ids, speeds, masses)`` -> (displacement, stop_time, pusher_speed, ok),
    the simulator that made the log's pushes."""
    names = objects["object_id"].tolist()
    mass = objects["mass"].to_numpy(float)
    layout = probe_layout(mass, speeds, np.zeros(len(names)), design)
    friction = objects["friction"].to_numpy(float)
    obj = np.maximum(layout.obj, 0)
    world = probe_pushes(layout, model_pushes(model, layout.speed, mass[obj], friction[obj], 0.0), design)
    tool = ~np.asarray(layout.kind == "added_mass")
    res = run_model(model, world.subset(np.flatnonzero(tool)), WorldStepping(), nthread=nthread)
    full = {f: np.full(layout.n, np.nan) for f in ("displacement", "stop_time", "stroke_time", "drive_force")}
    ok = np.zeros(layout.n, bool)
    for f in full:
        full[f][tool] = getattr(res, f)
    ok[tool] = res.ok
    stroke = float(np.asarray(model.numeric("stroke").data)[0])
    result = WorldResult(
        full["displacement"],
        np.zeros(layout.n),
        full["stop_time"],
        ok,
        np.zeros(layout.n, np.int64),
        full["stroke_time"],
        drive_force=full["drive_force"],
    )
    observed = probe_observables(layout, result, world, stroke)
    added = np.flatnonzero(layout.kind == "added_mass")
    rows = []
    for j in np.flatnonzero(tool & np.asarray(observed["ok"], bool)):
        row = {**dict.fromkeys(PROBE_COLUMNS, ""), "probe": str(layout.kind[j])}
        if layout.kind[j] == "free_stroke":
            row.update(speed=layout.speed[j], pusher_speed=float(np.exp(observed["log_p"][j])))
        else:
            row.update(
                object_id=names[layout.obj[j]],
                friction=observed["reading"][j],
                friction_sd=design.friction_sd,
                speed=layout.speed[j],
                direction=float(layout.direction[j]),
            )
        rows.append(row)
    if added.size:
        d, t, p, good = simulate_added(
            [names[k] for k in layout.obj[added]],
            layout.speed[added],
            mass[layout.obj[added]] + layout.added_mass[added],
        )
        for k, j in enumerate(added):
            if good[k]:
                rows.append(
                    {
                        **dict.fromkeys(PROBE_COLUMNS, ""),
                        "probe": "added_mass",
                        "object_id": names[layout.obj[j]],
                        "speed": layout.speed[j],
                        "added_mass": layout.added_mass[j],
                        "displacement": d[k],
                        "stop_time": t[k],
                        "pusher_speed": p[k],
                    }
                )
    return pd.DataFrame(rows, columns=PROBE_COLUMNS)


def simulate_probe_table(
    pushes: pd.DataFrame,
    log_frame: pd.DataFrame,
    *,
    model: mujoco.MjModel | None = None,
    scene: SceneConfig | None = None,
    design: ProbeDesign | None = None,
    nthread: int = 0,
) -> pd.DataFrame:
    """The probe rows for the objects of ``pushes`` (as :func:`imply.sim.push_file.read_pushes` returns it) on
    ``model`` or the built-in ``scene``; ``log_frame`` is their push log (the added-mass pushes keep its box)."""
    design = design or ProbeDesign()
    scene = scene or SceneConfig()
    compiled = model if model is not None else mujoco.MjModel.from_xml_string(build_xml(scene))
    box = compiled.geom("box").id
    first = pushes.drop_duplicates("object_id")
    objects = pd.DataFrame(
        {
            "object_id": first["object_id"].to_numpy(),
            "mass": first["mass"].to_numpy(float)
            if "mass" in first
            else np.full(len(first), compiled.body("box").mass[0]),
            "friction": (
                first["friction"].to_numpy(float)
                if "friction" in first
                else np.full(len(first), compiled.geom_friction[box, 0])
            ),
        }
    )
    if "size_x" in pushes:
        raise ValueError("probes need the model's own box; a pushes file with size columns varies it")

    def simulate_added(ids: list[str], speeds: np.ndarray, masses: np.ndarray):
        row = {o: i for i, o in enumerate(objects["object_id"])}
        frame = pd.DataFrame(
            {
                "object_id": ids,
                "speed": speeds,
                "mass": masses,
                "friction": objects["friction"].to_numpy()[[row[o] for o in ids]],
            }
        )
        out, _ = simulate_push_table(frame, model=model, scene=None if model is not None else scene, nthread=nthread)
        return (
            out["displacement"].to_numpy(),
            out["stop_time"].to_numpy(),
            out["pusher_speed"].to_numpy(),
            out["ok"].to_numpy(bool),
        )

    speeds = np.unique(log_frame["speed"].to_numpy(float))
    return simulate_model_probes(compiled, objects, speeds, design, simulate_added=simulate_added, nthread=nthread)
