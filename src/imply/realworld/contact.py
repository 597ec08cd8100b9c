"""Contact models of the benchmark's worlds: how a world's contact differs from the push table's, and which engine.

The push table and the default benchmark world share MuJoCo's contact: the same soft
box-table contact, plain Coulomb friction, the same pusher. Real contact differs from
any simulator's in ways no library effect names (the library's pusher softness,
viscous force, air drag, speed errors, tilt, anisotropic, torsional and rolling
friction and box height are effects, not contact models). A contact model sets the
world's contact parameters (:data:`imply.realworld.world.PARAMETERS`) by kind:

- ``table_compliance``: the box-table contact's solref time constant and damping ratio,
  each a factor on MuJoCo's (stiffer or softer, more or less damped);
- ``speed_friction``: velocity-dependent Coulomb friction ``mu (1 + k (|v| - v_ref))``,
  k of either sign, evaluated at every step from the box's sliding speed;
- ``regularised_friction``: friction ``mu (r + (1 - r) tanh(|v| / v_eps))``, weaker near
  zero slip as in engines with a stiction tolerance (the box creeps on at the end of a
  slide); a share r stays at rest, so that a box on a tilted table still stops;
- ``pusher_contact``: the pusher-box contact's impedance (solimp dmin and dmax lowered:
  the pusher sinks further into the box) and the friction of the pusher's face.

:func:`draw_contact` draws a random combination of kinds and magnitudes from the ranges of
a :class:`ContactDraw`. A world can also be another physics engine's
(:data:`ENGINES`); :func:`simulate_engine` dispatches a batch of pushes to it, and
:func:`simulate_distinct` simulates each distinct push of a batch once (the benchmarks'
generation: a four-direction design pushes each box alike in its four directions wherever
no tilt or direction-dependent friction turns them).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from tqdm.auto import tqdm

from imply.options import Config, option
from imply.realworld.effects import EFFECTS
from imply.realworld.world import (
    DIRECTIONAL_PARAMETERS,
    WorldPushes,
    WorldResult,
    WorldStepping,
    simulate_world,
)
from imply.sim.scene import SceneConfig
from imply.sim.track import pusher_speed

# the kinds of contact model and the world parameters each one sets
CONTACT_KINDS: dict[str, tuple[str, ...]] = {
    "table_compliance": ("table_timeconst", "table_dampratio"),
    "speed_friction": ("friction_slope", "friction_slope_speed"),
    "regularised_friction": ("friction_regularisation", "friction_rest_share"),
    "pusher_contact": ("pusher_impedance", "pusher_friction"),
}
CONTACT_PARAMETERS = tuple(p for kind in CONTACT_KINDS.values() for p in kind)
# how a parameter is drawn in its range [lo, hi]: log-uniform; log-uniform of random sign;
# uniform (a range that may start at zero); a factor log-uniform in [lo, hi] or its
# reciprocal (lo >= 1: stiffer or softer, never close to MuJoCo's own)
_LAW = {
    "table_timeconst": "factor",
    "table_dampratio": "log",
    "friction_slope": "signed",
    "friction_slope_speed": "uniform",
    "friction_regularisation": "log",
    "friction_rest_share": "uniform",
    "pusher_impedance": "log",
    "pusher_friction": "log",
}

# the physics engines a benchmark world may run on
ENGINES = ("mujoco", "bullet", "sapien")
# the effects the bullet world (imply.realworld.bullet) can carry; change it with that world
BULLET_EFFECTS = (
    "tilt",
    "viscous",
    "air_drag",
    "speed_gain",
    "speed_offset",
    "anisotropic",
    "stribeck",
    "carriage_mass",
    "force_limit",
    "friction_gradient",
)
# the effects the SAPIEN (PhysX) world (imply.realworld.sapien_world) can carry: Bullet's, on the same rig protocol
SAPIEN_EFFECTS = BULLET_EFFECTS
# a benchmark group's world (its name's second part): a MuJoCo contact variant, or an engine's own contact
# ("engine": Bullet, the contact benchmark's name for it)
WORLDS = {"contact": "mujoco", "engine": "bullet", "bullet": "bullet", "sapien": "sapien"}


def world_engine(world: str) -> str:
    """The engine of a benchmark group's world (``contact`` -> ``mujoco``; ``engine`` -> ``bullet``)."""
    if world not in WORLDS:
        raise ValueError(f"unknown benchmark world {world!r} (known: {', '.join(WORLDS)})")
    return WORLDS[world]


def engine_effects(engine: str) -> tuple[str, ...]:
    """The world effects (:data:`imply.realworld.effects.EFFECTS` names) ``engine``'s world can carry (MuJoCo: all)."""
    return {"mujoco": tuple(EFFECTS), "bullet": BULLET_EFFECTS, "sapien": SAPIEN_EFFECTS}[engine]


@dataclass(frozen=True, kw_only=True)
class ContactDraw(Config):
    """How each log's contact model is drawn (config ``gap.contact_benchmark.contact``): ``per_log`` kinds
    of :data:`CONTACT_KINDS` at random, each parameter in its range."""

    config_key: ClassVar[str] = "gap.contact_benchmark.contact"

    kinds: tuple[str, ...] = option(
        tuple(CONTACT_KINDS),
        doc="kinds of contact model a log may have",
        min_items=1,
        unique=True,
        items={"choices": tuple(CONTACT_KINDS)},
    )
    per_log: tuple[int, int] = option((1, 3), doc="kinds combined in one log, fewest and most", items={"minimum": 1})
    ranges: dict[str, tuple[float, float]] = option(
        {
            "table_timeconst": (2.5, 4.5),
            "table_dampratio": (0.35, 0.7),
            "friction_slope": (0.5, 1.0),
            "friction_slope_speed": (0.0, 0.3),
            "friction_regularisation": (0.1, 0.3),
            "friction_rest_share": (0.35, 0.6),
            "pusher_impedance": (0.2, 0.45),
            "pusher_friction": (0.1, 1.0),
        },
        doc="range of each contact parameter: table_timeconst a factor in the range or its reciprocal, "
        "table_dampratio a factor, friction_slope |k| (s/m, either sign), friction_slope_speed and "
        "friction_regularisation in m/s, friction_rest_share a share",
        keys=CONTACT_PARAMETERS,
        items={"minimum": 0},
    )

    def __post_init__(self) -> None:
        lo, hi = self.per_log
        if not 1 <= lo <= hi <= len(self.kinds):
            raise ValueError(f"per_log must be [low, high] with 1 <= low <= high <= {len(self.kinds)} kinds")
        missing = sorted({p for k in self.kinds for p in CONTACT_KINDS[k]} - set(self.ranges))
        if missing:
            raise ValueError(f"ranges: no range for {', '.join(missing)}")
        for name, (a, b) in self.ranges.items():
            if not (np.isfinite(a) and np.isfinite(b) and 0 <= a <= b and (a > 0 or _LAW[name] == "uniform")):
                raise ValueError(f"ranges.{name} must be [low, high] with 0 < low <= high, not {[a, b]}")
            if _LAW[name] == "factor" and a < 1:
                raise ValueError(f"ranges.{name}: a factor either way needs low >= 1, not {a}")


def no_contact_model() -> dict:
    """The contact model of a world whose contact is its engine's own (the label's ``contact``)."""
    return {"kinds": [], "parameters": {}}


def draw_contact(rng: np.random.Generator, draw: ContactDraw) -> dict:
    """A contact model: ``{"kinds": [...], "parameters": {world parameter: value}}``."""
    count = int(rng.integers(draw.per_log[0], draw.per_log[1] + 1))
    kinds = sorted(rng.choice(list(draw.kinds), size=count, replace=False).tolist())
    params: dict[str, float] = {}
    for kind in kinds:
        for name in CONTACT_KINDS[kind]:
            lo, hi = draw.ranges[name]
            if _LAW[name] == "uniform":
                x = float(rng.uniform(lo, hi))
            else:
                x = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
                if _LAW[name] == "signed" and rng.random() < 0.5:
                    x = -x
                elif _LAW[name] == "factor" and rng.random() < 0.5:
                    x = 1.0 / x
            params[name] = x
    return {"kinds": kinds, "parameters": params}


def apply_contact(p: WorldPushes, contact: dict) -> None:
    """Set the world's parameters of pushes ``p`` (in place) for ``contact`` (from :func:`draw_contact`)."""
    for name, value in contact["parameters"].items():
        if name not in CONTACT_PARAMETERS:
            raise KeyError(f"unknown contact parameter {name!r} (known: {', '.join(CONTACT_PARAMETERS)})")
        p.params[name][:] = value


def simulate_engine(
    pushes: WorldPushes,
    scene: SceneConfig,
    stepping: WorldStepping | None = None,
    *,
    engine: str = "mujoco",
    nthread: int = 0,
    progress: bool = False,
    track_times=None,
) -> WorldResult:
    """Simulate ``pushes`` in the world of ``engine`` (``stepping`` is MuJoCo's; another engine steps its own way),
    recording the box at ``track_times`` where given."""
    if engine == "mujoco":
        return simulate_world(pushes, scene, stepping, nthread=nthread, progress=progress, track_times=track_times)
    if engine == "bullet":
        # imported here: the bullet world needs pybullet, which only its logs do
        from imply.realworld.bullet import simulate_bullet

        return simulate_bullet(pushes, scene, progress=progress, track_times=track_times)
    if engine == "sapien":
        # imported here: only its logs need sapien
        from imply.realworld.sapien_world import simulate_sapien

        return simulate_sapien(pushes, scene, progress=progress, track_times=track_times)
    raise ValueError(f"unknown engine {engine!r} (known: {', '.join(ENGINES)})")


def distinct_pushes(pushes: WorldPushes) -> tuple[np.ndarray, np.ndarray]:
    """The distinct pushes of ``pushes``: ``first`` (k,) the index of each one's first occurrence, increasing, and
    ``inverse`` (n,) which of them every push is (``first[inverse[i]]`` is simulated alike to push i).

    Two pushes are alike when every input of their simulation is equal bit for bit; the table direction is an
    input only where a parameter of :data:`imply.realworld.world.DIRECTIONAL_PARAMETERS` is set (every world
    pushes along its own +x), so a four-direction design's pushes, and every push of a nominal world, are alike
    in all directions."""
    n = pushes.n
    directional = np.zeros(n, bool)
    for name in DIRECTIONAL_PARAMETERS:
        if name in pushes.params:
            directional |= np.asarray(pushes.params[name]) != 0
    inputs = [pushes.speed, pushes.mass, pushes.friction, np.where(directional, pushes.direction, 0.0)]
    inputs += [np.broadcast_to(pushes.params[k], (n,)) for k in sorted(pushes.params)]
    rows = np.ascontiguousarray(np.column_stack(inputs), dtype=np.float64)
    seen: dict[bytes, int] = {}
    first: list[int] = []
    inverse = np.empty(n, np.int64)
    for i in range(n):
        k = seen.setdefault(rows[i].tobytes(), len(first))
        if k == len(first):
            first.append(i)
        inverse[i] = k
    return np.asarray(first, np.int64), inverse


def simulate_distinct(
    pushes: WorldPushes,
    scene: SceneConfig,
    stepping: WorldStepping | None = None,
    *,
    engine: str = "mujoco",
    nthread: int = 0,
    track_times=None,
    chunk: int = 2400,
    progress: bool = False,
) -> tuple[WorldResult, int]:
    """:func:`simulate_engine` on each distinct push of ``pushes`` (:func:`distinct_pushes`) once, ``chunk`` of them
    per batch, and its result for every push (a push's result depends on its own inputs alone: MuJoCo steps each
    world of a batch on its own, the stepped engines build a fresh scene per push). Returns the result of every
    push, (n,) fields (the track (n, T, 3) float32; a field the engine did not record NaN), and how many pushes
    were simulated."""
    first, inverse = distinct_pushes(pushes)
    k = first.size
    n_times = 0 if track_times is None else np.asarray(track_times).size
    fields = ("displacement", "lateral", "stop_time", "stroke_time", "drive_force")
    out = {f: np.full(k, np.nan) for f in fields}
    ok = np.zeros(k, bool)
    steps = np.zeros(k, np.int64)
    track = np.full((k, n_times, 3), np.nan, np.float32)
    starts = range(0, k, chunk)
    for a in tqdm(starts, desc=f"{engine} world pushes", unit="batch", disable=not progress):
        idx = np.arange(a, min(a + chunk, k))
        res = simulate_engine(
            pushes.subset(first[idx]), scene, stepping, engine=engine, nthread=nthread, track_times=track_times
        )
        for f in fields:
            if getattr(res, f) is not None:
                out[f][idx] = getattr(res, f)
        ok[idx] = res.ok
        steps[idx] = res.steps
        if res.track is not None and n_times:
            track[idx] = res.track
    result = WorldResult(
        out["displacement"][inverse],
        out["lateral"][inverse],
        out["stop_time"][inverse],
        ok[inverse],
        steps[inverse],
        out["stroke_time"][inverse],
        track[inverse] if track_times is not None else None,
        out["drive_force"][inverse],
    )
    return result, int(k)


def run_observables(res: WorldResult, pushes: slice, stroke: float, *, filmed: bool) -> dict[str, np.ndarray]:
    """One run's noise-free observables, its ``pushes`` of a batch's result ``res``
    (:func:`simulate_by_engine`): displacement, stop time, whether the push ran (finished with a stroke of
    positive duration), the pusher's speed over its ``stroke``, and the box's track where the run is ``filmed``."""
    out = {
        "displacement": res.displacement[pushes],
        "stop_time": res.stop_time[pushes],
        "ok": res.ok[pushes] & np.isfinite(res.stroke_time[pushes]) & (res.stroke_time[pushes] > 0),
        "pusher_speed": pusher_speed(stroke, res.stroke_time[pushes]),
    }
    if filmed:
        out["track"] = res.track[pushes]
    return out


def simulate_by_engine(
    runs: list[tuple[str, WorldPushes]],
    scene: SceneConfig,
    stepping: WorldStepping | None = None,
    *,
    nthread: int = 0,
    track_times=None,
    chunk: int = 2400,
    progress: bool = False,
):
    """Every run of ``runs`` ((engine, pushes) each) simulated with its engine's other runs as one batch
    (:func:`simulate_distinct`). Yields, per engine in order of first appearance: the engine, the indices of its
    runs in ``runs``, the bounds (len + 1,) of each run's pushes in the batch, the batch's result, how many pushes
    were simulated, and the wall seconds it took."""
    for engine in dict.fromkeys(e for e, _ in runs):
        mine = [i for i, (e, _) in enumerate(runs) if e == engine]
        batch = WorldPushes.concat([runs[i][1] for i in mine])
        bounds = np.concatenate([[0], np.cumsum([runs[i][1].n for i in mine])])
        t0 = time.perf_counter()
        res, simulated = simulate_distinct(
            batch,
            scene,
            stepping,
            engine=engine,
            nthread=nthread,
            track_times=track_times,
            chunk=chunk,
            progress=progress,
        )
        yield engine, mine, bounds, res, simulated, time.perf_counter() - t0
