"""The diagnostic's candidate effects, built on the library of :mod:`imply.sim.effects`.

A candidate has one or two components (a global parameter vector, fitted jointly with
every object's mass and friction) and enters the prediction of a push in direction phi
(radians, table frame) in one or more of these ways:

- a speed term: the pusher runs at v (1 + g) + c instead of the logged v
  (``speed_gain`` g, ``speed_offset`` c), the same table at another speed;
- a friction factor: mu (1 + a_c cos 2 phi + a_s sin 2 phi) (``anisotropic``, two
  components: an anisotropy a = |(a_c, a_s)| whose larger friction lies along the axis
  psi = atan2(a_s, a_c) / 2);
- tabulated terms (:mod:`imply.diagnose.physics.effect_tables`): the library's scene edits at a level s
  per push. ``tilt`` has two components (t_x, t_y): a slope a = |(t_x, t_y)| downhill
  toward azimuth psi = atan2(t_y, t_x); a push in direction phi sees the slope
  a cos(phi - psi) along it (the library's ``slope`` table) and a sin(phi - psi) across
  it (``slope_across``), both of them: a tilted table is one effect, never split into
  two that each explain part of it.

The library's ``tilt_x`` / ``tilt_y`` name the components of ``tilt``; asking for
either asks for ``tilt``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from imply.diagnose.inputs.pushlog import TRACK_OBSERVABLES
from imply.sim.effects import EFFECTS, TABLE_SOLREF, Effect
from imply.sim.track import FRACTIONS

SPEED_GAIN, SPEED_OFFSET, FRICTION2, TABLE, TILT = "speed_gain", "speed_offset", "friction2", "table", "tilt"
DISCREPANCY = "discrepancy"  # not a library effect: a smooth, low-dimensional model discrepancy


@dataclass(frozen=True)
class Candidate:
    """One candidate effect: what it is called and how a verdict says it, its components, bounds and
    how it enters a prediction.

    ``title`` and ``unit`` describe the magnitude in reports; ``phrase`` names the effect inside a
    sentence ("a tilted table"); ``clause`` turns a fitted magnitude (and azimuth, in degrees, for
    two components) into the verdict's words ("the table slopes 0.03 rad toward 35 degrees").
    """

    name: str
    title: str
    unit: str
    phrase: str
    clause: Callable[[float, float | None], str]
    kind: str  # speed_gain | speed_offset | friction2 | table | tilt
    components: tuple[str, ...]
    lo: tuple[float, ...]
    hi: tuple[float, ...]
    radius: float | None = None  # two-component candidates: the largest magnitude
    period: float | None = None  # azimuth period (2 pi for a slope, pi for an axis)
    table_keys: tuple[str, ...] = ()
    levels: tuple[float, ...] = ()
    # a two-component candidate restricted to the one direction a log's design can identify:
    # its native components are basis * x (basis a unit 2-vector, x the one component)
    basis: tuple[float, float] | None = None
    prior_sd: float | None = None  # a Gaussian prior N(0, prior_sd^2) on every component (the discrepancy's)

    @property
    def dim(self) -> int:
        return len(self.components)

    @property
    def is_library(self) -> bool:
        """A mechanism of the effect library (the discrepancy is not one)."""
        return self.kind != DISCREPANCY

    def native(self, theta: np.ndarray) -> np.ndarray:
        """The native components (tilt_x, tilt_y or the anisotropy's) of a restricted candidate's parameters."""
        theta = np.asarray(theta, float)
        if self.basis is None:
            return theta
        return theta[..., :1] * np.asarray(self.basis)

    def restricted(self, direction: np.ndarray) -> Candidate:
        """This two-component candidate along ``direction`` (a 2-vector of its components) only: one signed component."""
        u = np.asarray(direction, float)
        u = u / np.linalg.norm(u)
        r = float(self.radius)
        return dataclasses.replace(
            self, components=(f"{self.name}_along",), lo=(-r,), hi=(r,), radius=None, basis=(float(u[0]), float(u[1]))
        )

    def restricted_axis_deg(self) -> float | None:
        """A restricted candidate's fixed azimuth (degrees, in [0, period)) for a positive component."""
        if self.basis is None:
            return None
        ang = float(np.arctan2(self.basis[1], self.basis[0]))
        if self.kind == FRICTION2:
            ang /= 2.0
        return float(np.degrees(np.mod(ang, self.period)))

    def magnitude(self, theta: np.ndarray) -> float:
        theta = np.asarray(theta, float)
        if self.dim == 1:
            return float(theta[0])
        return float(np.linalg.norm(theta))

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
        t = np.minimum(np.maximum(np.asarray(theta, float), self.lo), self.hi)  # np.clip's values, without its checks
        if self.radius is not None:
            r = np.hypot(*t)
            if r > self.radius:
                t = t * (self.radius / r)
        return t

    def bound_direction(self, theta: np.ndarray, *, rtol: float = 1e-3) -> np.ndarray | None:
        """The outward unit direction of the library bound ``theta`` sits on (within ``rtol`` of the range), or
        None when it is inside. The discrepancy has no bound in this sense (its box only keeps fits finite)."""
        if not self.is_library:
            return None
        th = np.asarray(theta, float)
        if self.radius is not None:
            a = float(np.hypot(*th))
            return th / a if a >= self.radius * (1 - rtol) else None
        lo, hi = self.lo[0], self.hi[0]
        tol = rtol * (hi - lo)
        if th[0] >= hi - tol:
            return np.array([1.0])
        if th[0] <= lo + tol:
            return np.array([-1.0])
        return None

    def scale(self) -> np.ndarray:
        """A typical size of each component (its range), for steps and starts."""
        return np.maximum(np.abs(np.asarray(self.hi)), np.abs(np.asarray(self.lo)))


def _faster(m: float) -> str:
    return "faster" if m > 0 else "slower"


def speed_clause(gain: float, offset: float) -> str:
    """The verdict's words for a speed gain and a speed offset found together: v' = (1 + gain) v + offset."""
    text = (
        f"the pusher's speed is {abs(gain):.1%} {'above' if gain > 0 else 'below'} the command, "
        f"{'plus' if offset > 0 else 'less'} {abs(offset) * 1000:.2g} mm/s"
    )
    if gain * offset < 0:  # the two cross: slower on one side of a speed, faster on the other
        cross = -offset / gain
        below, above = ("slower", "faster") if gain > 0 else ("faster", "slower")
        text += f" ({below} than commanded below {cross:.2g} m/s, {above} above)"
    return text


def _one(name: str, title: str, unit: str, phrase: str, clause, kind: str = TABLE) -> Candidate:
    """A one-component candidate on the library effect ``name`` (its bounds and tabulated levels)."""
    e = EFFECTS[name]
    return Candidate(
        name,
        title,
        unit,
        phrase,
        clause,
        kind,
        (name,),
        (float(e.bounds[0]),),
        (float(e.bounds[1]),),
        table_keys=(e.table_key,) if kind == TABLE else (),
        levels=tuple(e.levels),
    )


def _library() -> list[Candidate]:
    """Every candidate, each described once: name, title, unit, phrase and the verdict's clause."""
    tx, an = EFFECTS["tilt_x"], EFFECTS["anisotropic"]
    tilt = float(max(abs(tx.bounds[0]), abs(tx.bounds[1])))
    aniso = float(max(abs(an.bounds[0]), abs(an.bounds[1])))
    return [
        _one(
            "torsional",
            "torsional friction (condim 4)",
            "m",
            "torsional friction",
            lambda m, az: f"torsional friction (condim 4) of {m:.3g} m",
        ),
        _one(
            "rolling",
            "rolling friction (condim 6)",
            "m",
            "rolling friction",
            lambda m, az: f"rolling friction (condim 6) of {m:.3g} m",
        ),
        _one(
            "viscous",
            "viscous (velocity-proportional) friction on the box",
            "N s/m",
            "viscous friction",
            lambda m, az: f"the box feels viscous friction of {m:.3g} N s/m",
        ),
        _one(
            "pusher_softness",
            "pusher contact softness (extra solref time constant)",
            "s",
            "a softer pusher",
            lambda m, az: f"the pusher's contact is softer (solref time constant +{m:.3g} s)",
        ),
        _one(
            "table_timeconst",
            "the box-table contact's solref time constant (log of its factor on the table's)",
            "log factor",
            "a softer or stiffer table contact",
            lambda m, az: (
                f"the table contact is {'softer' if m > 0 else 'stiffer'}: solref time constant "
                f"{TABLE_SOLREF[0]:.3g} -> {TABLE_SOLREF[0] * np.exp(m):.3g} s in the MJCF"
            ),
        ),
        _one(
            "table_dampratio",
            "the box-table contact's solref damping ratio (log of its factor on the table's)",
            "log factor",
            "a differently damped table contact",
            lambda m, az: (
                f"the table contact is {'less' if m < 0 else 'more'} damped: solref damping ratio "
                f"{TABLE_SOLREF[1]:.3g} -> {TABLE_SOLREF[1] * np.exp(m):.3g} in the MJCF"
            ),
        ),
        Candidate(
            "tilt",
            "table tilt: a slope toward an azimuth (along and across every push)",
            "rad",
            "a tilted table",
            lambda m, az: f"the table slopes {m:.3g} rad toward {round(az) % 360:.0f} degrees (table frame)",
            TILT,
            ("tilt_x", "tilt_y"),
            (-tilt, -tilt),
            (tilt, tilt),
            radius=tilt,
            period=2 * np.pi,
            table_keys=("slope", "slope_across"),
            levels=tuple(tx.levels),
        ),
        _one(
            "air_drag",
            "fluid drag (medium density, MuJoCo fluid model)",
            "kg/m^3",
            "air drag",
            lambda m, az: f"the box feels air drag as of a medium of {m:.3g} kg/m^3",
        ),
        _one(
            "height",
            "box height deviation from the canonical box (fraction)",
            "1",
            "a different box height",
            lambda m, az: f"the boxes are {abs(m):.0%} {'taller' if m > 0 else 'shorter'} than the table's",
        ),
        _one(
            "speed_gain",
            "commanded-vs-actual speed gain (v' = (1+g) v)",
            "1",
            "a speed gain",
            lambda m, az: f"the pusher runs {abs(m):.1%} {_faster(m)} than commanded",
            SPEED_GAIN,
        ),
        _one(
            "speed_offset",
            "commanded-vs-actual speed offset (v' = v + c)",
            "m/s",
            "a speed offset",
            lambda m, az: f"the pusher runs {abs(m):.3g} m/s {_faster(m)} than commanded",
            SPEED_OFFSET,
        ),
        Candidate(
            "anisotropic",
            "anisotropic friction: mu (1 + a cos 2(phi - axis))",
            "1",
            "anisotropic friction",
            # an axis: 0 and 180 degrees are the same direction
            lambda m, az: f"friction is {m:.0%} higher along {round(az) % 180:.0f} degrees than across it",
            FRICTION2,
            ("aniso_cos", "aniso_sin"),
            (-aniso, -aniso),
            (aniso, aniso),
            radius=aniso,
            period=np.pi,
        ),
    ]


CANDIDATES: dict[str, Candidate] = {c.name: c for c in _library()}
# the library's effects that are the box-table contact itself (an MJCF change, not a mechanism beside the contact)
CONTACT = ("table_timeconst", "table_dampratio")
ALIASES = {"tilt_x": "tilt", "tilt_y": "tilt"}


def get(names: list[str] | None = None) -> list[Candidate]:
    """Candidates by name (all, in library order, when ``names`` is None); tilt_x / tilt_y mean tilt.

    An unknown name is a ValueError naming it."""
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
        raise ValueError(f"unknown effect(s): {', '.join(unknown)} (known: {', '.join(CANDIDATES)})")
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

    # cached: a fit asks for these tens of thousands of times
    @cached_property
    def dim(self) -> int:
        return sum(c.dim for c in self.candidates)

    @cached_property
    def moves_speed(self) -> bool:
        """Whether the model changes the speed a push runs at (a speed gain or offset)."""
        return any(c.kind in (SPEED_GAIN, SPEED_OFFSET) for c in self.candidates)

    @cached_property
    def moves_friction(self) -> bool:
        """Whether the model changes the friction a push sees (an anisotropy)."""
        return any(c.kind == FRICTION2 for c in self.candidates)

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.candidates]

    def slices(self) -> list[slice]:
        return list(self._slices)

    @cached_property
    def _slices(self) -> tuple[slice, ...]:
        out, k = [], 0
        for c in self.candidates:
            out.append(slice(k, k + c.dim))
            k += c.dim
        return tuple(out)

    def plus(self, c: Candidate) -> Model:
        return Model((*self.candidates, c))

    def project(self, theta: np.ndarray) -> np.ndarray:
        theta = np.asarray(theta, float).copy()
        for c, sl in zip(self.candidates, self._slices, strict=True):
            theta[sl] = c.project(theta[sl])
        return theta

    def lo(self) -> np.ndarray:
        return np.concatenate([c.lo for c in self.candidates]) if self.candidates else np.zeros(0)

    def hi(self) -> np.ndarray:
        return np.concatenate([c.hi for c in self.candidates]) if self.candidates else np.zeros(0)

    def scale(self) -> np.ndarray:
        return np.concatenate([c.scale() for c in self.candidates]) if self.candidates else np.zeros(0)

    def prior_precision(self) -> np.ndarray:
        """Per component, the precision of its Gaussian prior in whitened units (0: none)."""
        out = [np.full(c.dim, 0.0 if c.prior_sd is None else c.prior_sd**-2.0) for c in self.candidates]
        return np.concatenate(out) if out else np.zeros(0)

    @property
    def discrepancy(self) -> tuple[Candidate, slice] | None:
        """The model's discrepancy term and its slice of theta (None without one)."""
        for c, sl in zip(self.candidates, self.slices(), strict=True):
            if c.kind == DISCREPANCY:
                return c, sl
        return None

    @property
    def library(self) -> list[Candidate]:
        """The model's library effects (the discrepancy left out)."""
        return [c for c in self.candidates if c.is_library]

    def without(self, name: str) -> Model:
        return Model(tuple(c for c in self.candidates if c.name != name))

    def theta_without(self, theta: np.ndarray, name: str) -> np.ndarray:
        """``theta`` less the components of candidate ``name``."""
        keep = [sl for c, sl in zip(self.candidates, self.slices(), strict=True) if c.name != name]
        return np.concatenate([np.asarray(theta, float)[sl] for sl in keep]) if keep else np.zeros(0)


# -- the model discrepancy ------------------------------------------------------------------
# A smooth function of the push's speed and the object's mass and friction (each scaled to
# [-1, 1] over the table's range), added to log d and, where stop times are used, to log T:
# the speed's first three powers, and the first two times mass and times friction. Terms that
# depend on the object alone are left out of log d: each object's (mass, friction) fit absorbs
# them (they are reported as implied masses instead), and a term the fit can trade against
# freely would make the held-out fits unstable. Log T keeps a constant, which the per-object
# fit cannot absorb in both observables at once.
DISCREPANCY_D = ("d_v", "d_vv", "d_vu", "d_vm", "d_vvv", "d_vvu", "d_vvm")
DISCREPANCY_T = ("t_1", "t_v", "t_vv", "t_vu", "t_vm")
# each observable beside the displacement has its own coefficients, named with its prefix
AUX_PREFIX = {
    "stop_time": "t",
    "pusher_speed": "p",
    **{name: f"c{100 * q:.0f}" for name, q in zip(TRACK_OBSERVABLES, FRACTIONS, strict=True)},
}


def discrepancy_candidate(*, aux: tuple[str, ...] = (), prior_sd: float, bound: float) -> Candidate:
    """The discrepancy term: coefficients of :func:`discrepancy_basis` on log d and on each observable of ``aux``
    (in that order, :data:`DISCREPANCY_T` each, renamed with the observable's prefix), each with a
    N(0, ``prior_sd``^2) prior and within +-``bound``."""
    comps = DISCREPANCY_D + tuple(f"{AUX_PREFIX[a]}{name[1:]}" for a in aux for name in DISCREPANCY_T)
    return Candidate(
        DISCREPANCY,
        "model discrepancy: a smooth function of speed, mass and friction",
        "log units",
        "a smooth discrepancy between the table and these pushes",
        lambda m, az: "a smooth discrepancy",
        DISCREPANCY,
        comps,
        tuple([-bound] * len(comps)),
        tuple([bound] * len(comps)),
        prior_sd=prior_sd,
    )


def scaled(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """``x`` mapped from [lo, hi] to [-1, 1] (clipped)."""
    return np.clip((2.0 * np.asarray(x, float) - (lo + hi)) / (hi - lo), -1.0, 1.0)


def discrepancy_basis(sv: np.ndarray, sm: np.ndarray, su: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The discrepancy's basis at scaled speed, log mass and log friction (n,): log d (n, 7) and log T (n, 5),
    in the order of :data:`DISCREPANCY_D` and :data:`DISCREPANCY_T`."""
    v2 = sv * sv
    bd = np.stack([sv, v2, sv * su, sv * sm, v2 * sv, v2 * su, v2 * sm], 1)
    return bd, np.concatenate([np.ones((sv.size, 1)), bd[:, :4]], 1)


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
        if c.kind == DISCREPANCY:  # enters the prediction on its own (Problem.predict)
            continue
        x = c.native(th[:, sl])
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
