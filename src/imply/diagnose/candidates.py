"""The diagnostic's candidate effects, built on the library of :mod:`imply.sim.effects`.

A candidate has one or two components (a global parameter vector, fitted jointly with
every object's mass and friction) and enters the prediction of a push in direction phi
(radians, table frame) in one or more of these ways:

- a speed term: the pusher runs at v (1 + g) + c instead of the logged v
  (``speed_gain`` g, ``speed_offset`` c), the same table at another speed;
- a friction factor: mu (1 + a_c cos 2 phi + a_s sin 2 phi) (``anisotropic``, two
  components: an anisotropy a = |(a_c, a_s)| whose larger friction lies along the axis
  psi = atan2(a_s, a_c) / 2);
- tabulated terms (:mod:`imply.diagnose.effect_tables`): the library's scene edits at a level s
  per push. ``tilt`` has two components (t_x, t_y): a slope a = |(t_x, t_y)| downhill
  toward azimuth psi = atan2(t_y, t_x); a push in direction phi sees the slope
  a cos(phi - psi) along it (the library's ``slope`` table) and a sin(phi - psi) across
  it (``slope_across``), both of them: a tilted table is one effect, never split into
  two that each explain part of it.

The library's ``tilt_x`` / ``tilt_y`` name the components of ``tilt``; asking for
either asks for ``tilt``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imply.sim.effects import EFFECTS, Effect

SPEED_GAIN, SPEED_OFFSET, FRICTION2, TABLE, TILT = "speed_gain", "speed_offset", "friction2", "table", "tilt"


@dataclass(frozen=True)
class Candidate:
    """One candidate effect: its components, bounds and how it enters a prediction."""

    name: str
    title: str
    unit: str
    kind: str  # speed_gain | speed_offset | friction2 | table | tilt
    components: tuple[str, ...]
    lo: tuple[float, ...]
    hi: tuple[float, ...]
    radius: float | None = None  # two-component candidates: the largest magnitude
    period: float | None = None  # azimuth period (2 pi for a slope, pi for an axis)
    table_keys: tuple[str, ...] = ()
    levels: tuple[float, ...] = ()
    identifiable_note: str = ""

    @property
    def dim(self) -> int:
        return len(self.components)

    def magnitude(self, theta: np.ndarray) -> float:
        theta = np.asarray(theta, float)
        return float(np.hypot(*theta)) if self.dim == 2 else float(theta[0])

    def azimuth(self, theta: np.ndarray) -> float | None:
        """Azimuth in radians in [0, period) (the slope's downhill direction, or the anisotropy's axis)."""
        if self.dim != 2:
            return None
        ang = float(np.arctan2(theta[1], theta[0]))
        if self.kind == FRICTION2:
            ang /= 2.0
        return float(np.mod(ang, self.period))

    def project(self, theta: np.ndarray) -> np.ndarray:
        """The nearest admissible parameters: inside the box, and the disk for two components."""
        t = np.clip(np.asarray(theta, float), self.lo, self.hi)
        if self.radius is not None:
            r = np.hypot(*t)
            if r > self.radius:
                t = t * (self.radius / r)
        return t

    def scale(self) -> np.ndarray:
        """A typical size of each component (its range), for steps and starts."""
        return np.maximum(np.abs(np.asarray(self.hi)), np.abs(np.asarray(self.lo)))


def _one(e: Effect, kind: str = TABLE) -> Candidate:
    return Candidate(
        e.name, e.title, e.unit, kind, (e.name,), (float(e.bounds[0]),), (float(e.bounds[1]),),
        table_keys=(e.table_key,) if kind == TABLE else (), levels=tuple(e.levels),
    )  # fmt: skip


def _library() -> dict[str, Candidate]:
    out: dict[str, Candidate] = {}
    for name in ("torsional", "rolling", "viscous", "pusher_softness"):
        out[name] = _one(EFFECTS[name])
    tx = EFFECTS["tilt_x"]
    a = float(max(abs(tx.bounds[0]), abs(tx.bounds[1])))
    out["tilt"] = Candidate(
        "tilt", "table tilt: a slope toward an azimuth (along and across every push)", "rad", TILT,
        ("tilt_x", "tilt_y"), (-a, -a), (a, a), radius=a, period=2 * np.pi, table_keys=("slope", "slope_across"),
        levels=tuple(tx.levels),
    )  # fmt: skip
    for name in ("air_drag", "height"):
        out[name] = _one(EFFECTS[name])
    out["speed_gain"] = _one(EFFECTS["speed_gain"], SPEED_GAIN)
    out["speed_offset"] = _one(EFFECTS["speed_offset"], SPEED_OFFSET)
    an = EFFECTS["anisotropic"]
    a = float(max(abs(an.bounds[0]), abs(an.bounds[1])))
    out["anisotropic"] = Candidate(
        "anisotropic", "anisotropic friction: mu (1 + a cos 2(phi - axis))", "1", FRICTION2,
        ("aniso_cos", "aniso_sin"), (-a, -a), (a, a), radius=a, period=np.pi,
    )  # fmt: skip
    return out


CANDIDATES: dict[str, Candidate] = _library()
ALIASES = {"tilt_x": "tilt", "tilt_y": "tilt"}


def get(names: list[str] | None = None) -> list[Candidate]:
    """Candidates by name (all, in library order, when ``names`` is None); tilt_x / tilt_y mean tilt."""
    if names is None:
        return list(CANDIDATES.values())
    out: list[Candidate] = []
    unknown = []
    for n in names:
        n = ALIASES.get(n, n)
        if n not in CANDIDATES:
            unknown.append(n)
        elif CANDIDATES[n] not in out:
            out.append(CANDIDATES[n])
    if unknown:
        raise KeyError(f"unknown effect(s): {', '.join(unknown)} (known: {', '.join(CANDIDATES)})")
    return out


def library_effects(candidates: list[Candidate]) -> list[Effect]:
    """The library effects whose tables the candidates need."""
    out = []
    for c in candidates:
        for comp in c.components:
            if comp in EFFECTS and EFFECTS[comp] not in out:
                out.append(EFFECTS[comp])
    return out


def needs_across(candidates: list[Candidate]) -> bool:
    return any(c.kind == TILT for c in candidates)


@dataclass(frozen=True)
class Model:
    """An ordered set of candidates whose components make one parameter vector."""

    candidates: tuple[Candidate, ...] = ()

    @property
    def dim(self) -> int:
        return sum(c.dim for c in self.candidates)

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.candidates]

    def slices(self) -> list[slice]:
        out, k = [], 0
        for c in self.candidates:
            out.append(slice(k, k + c.dim))
            k += c.dim
        return out

    def plus(self, c: Candidate) -> Model:
        return Model((*self.candidates, c))

    def project(self, theta: np.ndarray) -> np.ndarray:
        theta = np.asarray(theta, float).copy()
        for c, sl in zip(self.candidates, self.slices(), strict=True):
            theta[sl] = c.project(theta[sl])
        return theta

    def lo(self) -> np.ndarray:
        return np.concatenate([c.lo for c in self.candidates]) if self.candidates else np.zeros(0)

    def hi(self) -> np.ndarray:
        return np.concatenate([c.hi for c in self.candidates]) if self.candidates else np.zeros(0)

    def scale(self) -> np.ndarray:
        return np.concatenate([c.scale() for c in self.candidates]) if self.candidates else np.zeros(0)


@dataclass
class Terms:
    """What a model does to n pushes: speed gain and offset, friction factor, tabulated terms."""

    gain: np.ndarray
    offset: np.ndarray
    friction: np.ndarray
    tables: list[tuple[str, np.ndarray]]


def terms(model: Model, theta: np.ndarray, phi: np.ndarray) -> Terms:
    """Terms of ``model`` at parameters ``theta`` ((p,) or per push (n, p)) for pushes in directions ``phi`` (n,)."""
    n = phi.size
    theta = np.asarray(theta, float)
    th = np.broadcast_to(theta, (n, model.dim)) if theta.ndim == 1 else theta
    gain, offset, friction = np.zeros(n), np.zeros(n), np.ones(n)
    tables: list[tuple[str, np.ndarray]] = []
    for c, sl in zip(model.candidates, model.slices(), strict=True):
        x = th[:, sl]
        if c.kind == SPEED_GAIN:
            gain = gain + x[:, 0]
        elif c.kind == SPEED_OFFSET:
            offset = offset + x[:, 0]
        elif c.kind == FRICTION2:
            friction = friction * (1.0 + x[:, 0] * np.cos(2 * phi) + x[:, 1] * np.sin(2 * phi))
        elif c.kind == TILT:
            along = x[:, 0] * np.cos(phi) + x[:, 1] * np.sin(phi)
            across = np.abs(-x[:, 0] * np.sin(phi) + x[:, 1] * np.cos(phi))
            tables.append(("slope", along))
            tables.append(("slope_across", across))
        else:
            tables.append((c.table_keys[0], x[:, 0]))
    return Terms(gain, offset, friction, tables)
