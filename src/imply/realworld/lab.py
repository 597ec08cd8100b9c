"""The gap benchmark as a lab would run it: pushes with calibration probes, on engines never used to choose.

A lab's session (:class:`LabBenchmarkConfig`) is the contact benchmark's
(:class:`imply.realworld.cases.ContactBenchmarkConfig`: boxes pushed at several speeds, a
contact model that is not the table's, no effect, one library effect or one outside it),
and beside the pushes the calibration probes of :mod:`imply.realworld.probes` (written for
a share ``probe_share`` of the logs). Its groups name their world: ``*_contact`` a MuJoCo
contact variant, ``*_bullet`` the Bullet world, ``*_sapien`` the SAPIEN (PhysX) world.

Two sets, by engine: the **development** set (``development_seed``,
``development_logs``: MuJoCo contact variants and Bullet) is the one any choice may be
made on; the **sealed** set (``seed``, ``logs``) adds the SAPIEN world, which no choice
was made on, beside fresh MuJoCo-variant and Bullet logs, and is scored once per design.

Every log's label holds, beside the contact benchmark's, the noise-free observables of
its pushes (and probes) in the worlds :mod:`imply.realworld.separability` reads to mark
each effect log separable or not from its contact (:func:`marked_runs`): ``all`` (the
log's world), ``contact`` (the same world without the effect; effect logs), and the
nominal MuJoCo world (the table's physics, converged) at the objects' true masses and
frictions (``table``) and at each one raised by a factor exp(``JACOBIAN_STEP``) in the
directions the per-object fit frees (``log_friction``, and ``log_mass`` where the log
does not weigh its objects). The probes are simulated in every run of an effect log (the
marking reads them there), and in a null log's own world only where its log carries them.
Each distinct push is simulated once (:func:`imply.realworld.contact.simulate_distinct`).
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
from imply.options import option
from imply.realworld.cases import (
    ContactBenchmarkConfig,
    draw_cases,
    log_track,
    make_log,
    object_names,
    push_layout,
    pushes_in_world,
    reference_log,
    reference_seed,
)
from imply.realworld.contact import run_observables, simulate_by_engine, simulate_engine
from imply.realworld.probes import (
    PROBE_COLUMNS,
    ProbeDesign,
    ProbeLayout,
    probe_layout,
    probe_observables,
    probe_pushes,
    probe_rows,
)
from imply.realworld.sapien_world import SapienStepping
from imply.realworld.shards import shard_cases
from imply.realworld.world import WorldPushes, WorldResult
from imply.sim.scene import SceneConfig
from imply.sim.track import crossing_times, track_frame_times

log = logging.getLogger("imply.realworld")

LAB_GROUPS = tuple(
    f"{kind}_{world}" for world in ("contact", "bullet", "sapien") for kind in ("null", "single", "outside")
)
SETS = ("development", "sealed")
JACOBIAN_STEP = 0.05  # log units: the per-object fit's directions, by finite differences in the nominal world
# the runs a log may have: its world, its world without the effect, the nominal world and its two derivatives
RUNS = ("all", "contact", "table", "log_mass", "log_friction")
LAB_TARGETS = (
    # without a reference session (each log alone, and with its probes)
    "null_no_library",
    "pusher_unmeasured",
    "among_named",
    "contenders_mean",
    "magnitude_within",
    "wrong_mechanism",
    "wrong_effect_single",
    "contact_named",
    # with a reference session
    "ref_null_no_change",
    "ref_single_right",
    "ref_among_named",
    "ref_wrong_effect_single",
    "ref_wrong_single",
    "ref_shrink_within",
    "shrink_tolerance",
    "ref_contact_named",
    "closed_loop",
)


@dataclass(frozen=True, kw_only=True)
class LabBenchmarkConfig(ContactBenchmarkConfig):
    """The lab benchmark (config ``gap.lab_benchmark``): pushes and calibration probes from worlds whose contact is
    not the table's, in a development set (MuJoCo variants, Bullet) and a sealed set (those and SAPIEN)."""

    config_key: ClassVar[str] = "gap.lab_benchmark"
    groups: ClassVar[tuple[str, ...]] = LAB_GROUPS

    seed: int = option(7474, doc="seed of the sealed set's draws", required=True)
    logs: dict[str, int] = option(
        {
            "null_contact": 6,
            "single_contact": 8,
            "outside_contact": 4,
            "null_bullet": 4,
            "single_bullet": 6,
            "outside_bullet": 2,
            "null_sapien": 8,
            "single_sapien": 12,
            "outside_sapien": 6,
        },
        doc="the sealed set's logs per group (*_contact: MuJoCo contact variants; *_bullet, *_sapien: those engines)",
        required=True,
        keys=LAB_GROUPS,
        items={"minimum": 0},
    )
    development_seed: int = option(2727, doc="seed of the development set's draws", required=True)
    development_logs: dict[str, int] = option(
        {
            "null_contact": 8,
            "single_contact": 12,
            "outside_contact": 4,
            "null_bullet": 6,
            "single_bullet": 10,
            "outside_bullet": 4,
        },
        doc="the development set's logs per group (no sapien: no choice is made on that engine)",
        required=True,
        keys=LAB_GROUPS,
        items={"minimum": 0},
    )
    probe_share: float = option(0.5, doc="share of logs written with calibration probes", minimum=0, maximum=1)
    probes: ProbeDesign = option(ProbeDesign(), doc="the calibration probes", required=True)
    sapien: SapienStepping = option(SapienStepping(), doc="how the SAPIEN world steps a push")
    alias_cos: float = option(
        0.95,
        doc="|cos| of an effect's and its contact's signatures (after the per-object fit) at or above which "
        "the effect is not separable from the contact",
        exclusive_minimum=0,
        maximum=1,
    )
    crossing_sd: float = option(
        0.02,
        doc="sd of the log of a track's crossing times (the separability's weight of the track)",
        exclusive_minimum=0,
    )
    targets: dict[str, float] = option(
        {
            "null_no_library": 0.9,
            "pusher_unmeasured": 0.05,
            "among_named": 0.9,
            "contenders_mean": 2.0,
            "magnitude_within": 0.3,
            "wrong_mechanism": 0.1,
            "wrong_effect_single": 0.05,
            "contact_named": 0.8,
            "ref_null_no_change": 0.95,
            "ref_single_right": 0.8,
            "ref_among_named": 0.95,
            "ref_wrong_effect_single": 0.05,
            "ref_wrong_single": 0.05,
            "ref_shrink_within": 0.8,
            "shrink_tolerance": 0.15,
            "ref_contact_named": 0.8,
            "closed_loop": 0.6,
        },
        doc="fixed before any run. Without a reference session (each log alone and with its probes): null logs "
        "stating no effect beyond the contact (share, at least); null logs without the pusher's measured speed or free "
        "strokes stating a pusher cause (at most); one big effect named (at least) with contenders_mean contenders on "
        "average (at most); outside logs stating a library mechanism as a cause (wrong_mechanism, at most); one-effect "
        "logs stating another library effect as the one cause (wrong_effect_single, at most); MuJoCo variants whose "
        "table contact is off naming the contact (at least). With a reference session (ref_*, per engine and "
        "overall): nulls stating no change; one big effect the observables can tell from the others stated as the one "
        "cause within magnitude_within; one big effect named; one-effect logs stating another effect as the one cause "
        "(at most); outside logs stating a library effect as the one cause (at most); the stated share of the gap "
        "within shrink_tolerance of the true one; the standing gap naming an off table contact; after the next "
        "experiments, logs left with several contenders stating the one cause right (closed_loop)",
        keys=LAB_TARGETS,
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        if (
            self.development_logs.get("null_sapien", 0)
            + self.development_logs.get("single_sapien", 0)
            + self.development_logs.get("outside_sapien", 0)
        ):
            raise ValueError("development_logs: the sapien world is never used to choose; give it no logs here")

    @staticmethod
    def set_subset(config: dict, name: str) -> dict:
        """The keys of a ``gap.lab_benchmark`` config dict that set ``name`` depends on (the other set's seed and
        logs left out, so that a change to one set does not remake the other)."""
        other = {"development": ("seed", "logs"), "sealed": ("development_seed", "development_logs")}
        if name not in other:
            raise ValueError(f"unknown set {name!r} (known: {', '.join(SETS)})")
        return {k: v for k, v in config.items() if k not in other[name]}

    @classmethod
    def of_subset(cls, subset: dict, name: str) -> LabBenchmarkConfig:
        """The design of set ``name`` from its :meth:`set_subset`."""
        if name == "development":
            subset = {**subset, "seed": subset.get("development_seed", 0), "logs": subset.get("development_logs", {})}
        return cls.from_dict(subset, "gap.lab_benchmark").of_set(name)

    def of_set(self, name: str) -> LabBenchmarkConfig:
        """The design of set ``name`` (``development`` or ``sealed``): its seed and logs."""
        if name == "sealed":
            return self
        if name == "development":
            return dataclasses.replace(self, seed=self.development_seed, logs=dict(self.development_logs))
        raise ValueError(f"unknown set {name!r} (known: {', '.join(SETS)})")


def draw_lab_cases(design: LabBenchmarkConfig) -> list[dict]:
    """Every log's draw (:func:`imply.realworld.cases.draw_cases`), and whether it is written with probes."""
    cases = draw_cases(design)
    for case in cases:
        rng = np.random.default_rng([design.seed, 77, int(case["noise_seed"])])
        case["probes"] = bool(rng.random() < design.probe_share)
    return cases


def lab_probe_layout(case: dict, design: LabBenchmarkConfig) -> ProbeLayout:
    """The probes of ``case``: laid out by its objects' true masses, each object's probes in its first push's
    direction."""
    obj, _ = push_layout(case, design)
    first = np.searchsorted(obj, np.arange(design.n_objects))
    return probe_layout(
        np.asarray(case["mass"], float), np.asarray(design.speeds), np.asarray(case["direction"])[first], design.probes
    )


def _probe_pushes(
    case: dict, design: LabBenchmarkConfig, scene: SceneConfig, world: dict, effects: list[dict]
) -> WorldPushes:
    """The probes of ``case`` as pushes of ``world`` (the case, or a nominal world of other masses and frictions)."""
    layout = lab_probe_layout(case, design)
    p = pushes_in_world(world, np.maximum(layout.obj, 0), layout.speed, layout.direction, scene, effects)
    return probe_pushes(layout, p, design.probes)


def fitted_runs(measured_mass: bool) -> tuple[str, ...]:
    """The nominal world's finite-difference runs of a log: the directions the per-object fit frees, each object's
    log friction, and its log mass unless the log weighs its objects (``measured_mass``)."""
    return ("log_friction",) if measured_mass else ("log_mass", "log_friction")


def marked_runs(has_effect: bool, measured_mass: bool) -> tuple[str, ...]:
    """The runs (of :data:`RUNS`) of a log that :func:`imply.realworld.separability.mark_log` reads, and so the
    runs its label holds: its world, its world without the effect (``has_effect``), the nominal world and the
    directions of the per-object fit (:func:`fitted_runs`). The marking reads the probes of an effect log's runs
    only (a null log's gap is its displacements')."""
    return ("all", *(("contact",) if has_effect else ()), "table", *fitted_runs(measured_mass))


def run_probes(case: dict) -> dict[str, bool]:
    """Every run of ``case`` (:func:`marked_runs`) and whether its probes are simulated in it: in every run of an
    effect log (the marking reads them), and in a null log's own world only where its log carries probes (its
    probes file is written from them)."""
    effect = bool(case["effects"])
    return {
        what: effect or (what == "all" and bool(case["probes"]))
        for what in marked_runs(effect, bool(case["measured_mass"]))
    }


def _runs(case: dict, design: LabBenchmarkConfig, scene: SceneConfig) -> list[tuple[str, str, WorldPushes, int]]:
    """(what, engine, pushes and probes as one batch, how many of them are pushes) of every run of ``case``, its
    probes in the batch where :func:`run_probes` says."""
    obj, v = push_layout(case, design)
    phi = np.asarray(case["direction"], float)
    m0, mu0 = np.asarray(case["mass"], float), np.asarray(case["friction"], float)
    engine = case.get("engine", "mujoco")
    step = np.exp(JACOBIAN_STEP)
    # what: (engine, effects, nominal world, masses, frictions)
    worlds = {
        "all": (engine, case["effects"], False, m0, mu0),
        "contact": (engine, [], False, m0, mu0),
        "table": ("mujoco", [], True, m0, mu0),
        "log_mass": ("mujoco", [], True, m0 * step, mu0),
        "log_friction": ("mujoco", [], True, m0, mu0 * step),
    }
    out = []
    for what, with_probes in run_probes(case).items():
        eng, effects, nominal, m, mu = worlds[what]
        world = {**case, "mass": list(m), "friction": list(mu)}
        if nominal:
            world.pop("contact", None)
        pushes = pushes_in_world(world, obj, v, phi, scene, effects)
        batch = [pushes, _probe_pushes(case, design, scene, world, effects)] if with_probes else [pushes]
        out.append((what, eng, WorldPushes.concat(batch), pushes.n))
    return out


def simulate_lab_cases(
    cases: list[dict],
    design: LabBenchmarkConfig,
    scene: SceneConfig,
    *,
    nthread: int = 0,
    chunk: int = 2400,
    progress: bool = False,
) -> tuple[dict[str, dict], dict[str, dict]]:
    """Noise-free observables of every run of every case (:func:`marked_runs`), each distinct push simulated once
    (:func:`imply.realworld.contact.simulate_distinct`), and each engine's time per simulated push.

    Returns ``{case id: {run: {displacement, stop_time, ok, pusher_speed, track (the log's world only),
    log_c (n, Q) log crossing times, probes: probe observables (where simulated: :func:`run_probes`)}}}`` and
    ``{engine: {pushes (simulated), seconds, seconds_per_push}}``."""
    runs = [(case["id"], *r) for case in cases for r in _runs(case, design, scene)]
    times = track_frame_times(design.noise.track_rate)
    out: dict[str, dict] = {}
    timing: dict[str, dict] = {}
    layouts = {case["id"]: lab_probe_layout(case, design) for case in cases}
    batches = simulate_by_engine(
        [(r[2], r[3]) for r in runs],
        scene,
        design.stepping,
        nthread=nthread,
        track_times=times,
        chunk=chunk,
        progress=progress,
    )
    for engine, mine, bounds, res, simulated, seconds in batches:
        # the engines that step one push at a time are timed per push; MuJoCo's batches on the threads given
        timing[engine] = {"pushes": simulated, "seconds": seconds, "seconds_per_push": seconds / max(simulated, 1)}
        for k, (cid, what, _, batch, n_push) in enumerate(runs[i] for i in mine):
            sl = slice(bounds[k], bounds[k] + n_push)
            psl = slice(bounds[k] + n_push, bounds[k + 1])
            cross = crossing_times(times, res.track[sl, :, 0], res.displacement[sl])
            entry = run_observables(res, sl, scene.stroke, filmed=False)
            entry["log_c"] = np.log(np.where(cross > 0, cross, np.nan))
            if what == "all":  # the camera films the log's own pushes
                entry["track"] = res.track[sl]
            if batch.n > n_push:
                n_probe = batch.n - n_push
                probe_res = WorldResult(
                    res.displacement[psl],
                    np.zeros(n_probe),
                    res.stop_time[psl],
                    res.ok[psl],
                    np.zeros(n_probe, np.int64),
                    res.stroke_time[psl],
                    drive_force=res.drive_force[psl],
                )
                probes = batch.subset(np.arange(n_push, batch.n))
                entry["probes"] = probe_observables(layouts[cid], probe_res, probes, scene.stroke)
            out.setdefault(cid, {})[what] = entry
    return {case["id"]: out[case["id"]] for case in cases}, timing


def _jsonable(entry: dict) -> dict:
    """A run's observables the lab's label adds to the contact benchmark's: log crossing times, and the probes'
    where simulated."""
    out = {"log_c": np.asarray(entry["log_c"]).tolist()}
    if "probes" in entry:
        out["probes"] = entry["probes"]
    return out


def write_lab_set(
    design: LabBenchmarkConfig,
    scene: SceneConfig,
    *,
    logs: Path,
    labels: Path,
    timing: Path,
    references: Path | None = None,
    nthread: int = 0,
    progress: bool = True,
    shard: int = 0,
    shards: int = 1,
) -> dict:
    """Simulate every log of one set into ``logs/<id>.csv`` (with ``<id>.track.csv``, and ``<id>.probes.csv`` for
    logs with probes), its labels into ``labels`` and each engine's time per simulated push into ``timing``, and
    (``references``) each log's reference session into ``references/<id>.csv`` (:func:`write_reference`). Returns the
    timing. With ``shards`` > 1, only the logs of shard ``shard``
    (:func:`imply.realworld.shards.shard_cases`), their labels and the time they took
    (:func:`imply.realworld.shards.merge_labels` and :func:`~imply.realworld.shards.merge_timing` join the
    shards')."""
    cases = shard_cases(draw_lab_cases(design), shard, shards)
    log.info(
        "simulating %d logs (%d objects x %d speeds each, with probes) on %s%s",
        len(cases),
        design.n_objects,
        len(design.speeds),
        ", ".join(dict.fromkeys(c.get("engine", "mujoco") for c in cases)),
        f" (shard {shard} of {shards})" if shards > 1 else "",
    )
    sims, times = simulate_lab_cases(cases, design, scene, nthread=nthread, progress=progress)
    out = {}
    logs.mkdir(parents=True, exist_ok=True)
    nm = design.noise
    for case in cases:
        sim = sims[case["id"]]
        frame, label = make_log(case, sim, design, scene)
        write_csv(logs / f"{case['id']}.csv", frame)
        write_csv(logs / f"{case['id']}.track.csv", log_track(case, sim, label, design))
        if case["probes"]:
            rows = recorded_probes(
                case,
                design,
                sim["all"]["probes"],
                lab_probe_layout(case, design),
                np.random.default_rng([case["noise_seed"], 3]),
            )
            write_csv(logs / f"{case['id']}.probes.csv", probes_of_logged(rows, frame))
        if references is not None:
            write_reference(case, sim, design, scene, references)
        label["probes"] = case["probes"]
        label["noise"]["track_sd"] = nm.track_sd
        label["noise"]["friction_sd"] = design.probes.friction_sd
        label["replicates"] = design.replicates
        label["free_strokes"] = design.probes.free_strokes
        for what, entry in sim.items():
            label["noise_free"][what].update(_jsonable(entry))
        out[case["id"]] = label
    write_json(labels, out)
    write_json(timing, times)
    return times


def probes_of_logged(rows: pd.DataFrame, log: pd.DataFrame) -> pd.DataFrame:
    """The probe rows of ``rows`` that a lab could file beside ``log``: those of boxes with a push in it, and free
    strokes (no box). A box whose every push failed its world's checks is not in the log, and a probe of it would name
    an object the log does not have."""
    ids = rows["object_id"].astype(str)
    keep = ids.eq("") | ids.isin(set(log["object_id"].astype(str)))
    return rows[keep].reset_index(drop=True)


def write_reference(case: dict, sim: dict, design: LabBenchmarkConfig, scene: SceneConfig, folder: Path) -> None:
    """The reference session of ``case`` (:func:`imply.realworld.cases.reference_log`: its world and boxes without
    the effect, one push of each, fresh noise) into ``folder/<id>.csv``, and where the log carries probes, the same
    probes run in that world once each, with fresh noise, into ``folder/<id>.probes.csv``. Nothing is simulated
    here: the world without the effect is a run the label already holds."""
    folder.mkdir(parents=True, exist_ok=True)
    session = reference_log(case, sim, design, scene)
    write_csv(folder / f"{case['id']}.csv", session)
    if case["probes"]:
        world = sim["contact"] if case["effects"] else sim["all"]
        once = dataclasses.replace(design, replicates=1)
        rng = np.random.default_rng([reference_seed(case), 3])
        rows = recorded_probes(case, once, world["probes"], lab_probe_layout(case, design), rng)
        write_csv(folder / f"{case['id']}.probes.csv", probes_of_logged(rows, session))


def extra_probes(
    case: dict,
    design: LabBenchmarkConfig,
    scene: SceneConfig,
    probes: pd.DataFrame,
    *,
    seed: int,
    nthread: int = 0,
) -> pd.DataFrame:
    """New calibration probes of ``case`` (rows ``probe, object_id, speed, added_mass``, as ``next_probes.csv``
    recommends them), run in the log's world (its contact, engine and effects) with its probes' protocol and noise
    (fresh draws, from ``seed``): the probes-file rows (:data:`imply.realworld.probes.PROBE_COLUMNS`), those that
    failed their world's checks left out. A friction test drags at the design's pull speed; an object's probes take
    its first push's direction, as the log's own do."""
    names = object_names(design.n_objects)
    index = {name: i for i, name in enumerate(names)}
    own = lab_probe_layout(case, design)
    # every probe of an object takes one direction
    first_direction = {int(o): float(d) for o, d in zip(own.obj, own.direction, strict=True) if o >= 0}
    kinds, objs, speeds, directions, loads = [], [], [], [], []
    for row in probes.itertuples(index=False):
        obj = index[row.object_id] if isinstance(row.object_id, str) and row.object_id else -1
        kinds.append(row.probe)
        objs.append(obj)
        speeds.append(design.probes.pull_speed if row.probe == "friction" else float(row.speed))
        directions.append(first_direction.get(obj, 0.0))
        loads.append(float(row.added_mass) if row.probe == "added_mass" else 0.0)
    layout = ProbeLayout(
        np.array(kinds), np.array(objs, int), np.array(speeds, float), np.array(directions, float), np.array(loads)
    )
    if not layout.n:
        return pd.DataFrame(columns=PROBE_COLUMNS)
    p = pushes_in_world(case, np.maximum(layout.obj, 0), layout.speed, layout.direction, scene, case["effects"])
    p = probe_pushes(layout, p, design.probes)
    res = simulate_engine(p, scene, design.stepping, engine=case.get("engine", "mujoco"), nthread=nthread)
    observed = probe_observables(layout, res, p, scene.stroke)
    return recorded_probes(case, design, observed, layout, np.random.default_rng([case["noise_seed"], seed, 3]))


def recorded_probes(
    case: dict, design: LabBenchmarkConfig, observed: dict[str, list], layout: ProbeLayout, rng: np.random.Generator
) -> pd.DataFrame:
    """The probe rows a lab records of ``case``'s probes (``observed`` noise-free, laid out by ``layout``), with the
    log's noise and replicates (:func:`imply.realworld.probes.probe_rows`)."""
    nm = design.noise
    return probe_rows(
        observed,
        layout,
        object_names(design.n_objects),
        design=design.probes,
        replicates=design.replicates,
        sd=nm.sd,
        stop_time_sd=nm.stop_time_sd,
        pusher_speed_sd=nm.pusher_speed_sd,
        with_stop_time=case["stop_time"],
        rng=rng,
    )
