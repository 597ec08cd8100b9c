"""What a log's calibration probes add to every hypothesis's fit: whitened residual rows beside the pushes'.

Each probe (:mod:`imply.diagnose.inputs.probes`) is predicted under the hypothesis being fitted, as
a push is, and its residual counts in the same sum of squares:

- a **friction measurement** of object i is a prior on its friction, never a value held
  fixed: (log r_i - log reading) / (reading's sd / reading), with r_i what a pull test
  reads under the hypothesis (:func:`pull_test_log_reading`). A slow, steady drag at speed
  u in direction phi balances every force along it, so over the box's weight m g it reads

      r = mu (1 + a_c cos 2 phi + a_s sin 2 phi) cos(a) - sin(a cos(phi - psi)) + b u / (m g)

  for a table sloping a toward psi (downhill; the drag is helped where it goes downhill),
  anisotropic friction (a_c, a_s) and a viscous force b. The direction-dependent terms
  need the row's direction and the viscous term its speed: a row without a direction reads
  mu cos(a), one without a speed no viscous force. Air drag at a pull test's speed is a few
  thousandths of the weight at most, well inside any stated uncertainty, and is left out, as
  are the pusher's effects (the test has its own drive). What a test reads on a robot is
  still not exactly what the simulator's friction parameter means; the stated uncertainty
  says by how much it may differ;
- a **push with a known added mass** is predicted as the log's pushes are (the table, the
  hypothesis's effects and its discrepancy), at the object's own friction and its mass plus
  the load: it pins the object's mass apart from its friction, which displacements at
  several speeds alone leave entangled;
- a **free stroke** is the pusher with no box: its mean speed over the stroke follows from
  the rig's servo alone (:class:`Servo`: the pusher's mass, the servo's gain and force
  limit, the stroke, all in the table's scene), at the speed the hypothesis gives the
  pusher, v (1 + gain) + offset. It measures the pusher's speed error with no contact, so
  a softer pusher contact (which slows the pusher only against a box) and a speed error
  no longer read alike.

Free strokes belong to no object; their rows are counted with the first object's (the
per-object blocks of :meth:`imply.diagnose.inference.fit.Problem.fit` see no mass or friction in them),
so a leave-objects-out fold that drops the first object drops them too.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from imply.diagnose.inputs.probes import Probes
from imply.diagnose.physics.candidates import Model, terms
from imply.sim.effects import EFFECTS
from imply.sim.scene import GRAVITY

PROBE_AUX = ("stop_time", "pusher_speed")  # what an added-mass push may measure beside its displacement
SERVO_KEYS = ("pusher_mass", "pusher_kv", "pusher_force_limit", "stroke")  # what the table's scene says of the rig
STROKE_SD_FLOOR = 0.002  # log units: the free strokes' noise is never taken below this (encoders' resolution)
# log units: a free stroke's noise where nothing in the log measures it (the benchmark worlds' encoder noise)
STROKE_SD_DEFAULT = 0.01
VISCOUS_KEY = EFFECTS["viscous"].table_key  # the viscous force's coefficient b (N s/m) among a model's terms
MIN_READING = 1e-3  # a reading is positive: a hypothesis that would drag the box by itself reads this


@dataclass(frozen=True)
class Servo:
    """The rig's pusher in free air: a velocity servo (gain ``kv``, N s/m, force limit ``force_limit``, N) on the
    pusher's mass (``mass``, kg), from rest over ``stroke`` m. Continuous time: what a converged simulation or a
    rig gives."""

    mass: float
    kv: float
    force_limit: float
    stroke: float

    @classmethod
    def of_scene(cls, scene: dict | None) -> Servo | None:
        """From a table's scene (its metadata ``scene``: ``pusher_mass``, ``pusher_kv``, ``pusher_force_limit``,
        ``stroke``); None where the scene does not hold them all."""
        if not scene or not all(k in scene for k in SERVO_KEYS):
            return None
        return cls(
            float(scene["pusher_mass"]),
            float(scene["pusher_kv"]),
            float(scene["pusher_force_limit"]),
            float(scene["stroke"]),
        )

    def mean_speed(self, speed: np.ndarray) -> np.ndarray:
        """(n,) the pusher's mean speed over its stroke (m/s) when commanded ``speed`` (n,) m/s with no box: read
        from :meth:`exact_mean_speed` tabulated once on a fine grid of log speeds (every fit asks for it)."""
        v = np.asarray(speed, float)
        grid, table = self._tabulated
        inside = (v >= np.exp(grid[0])) & (v <= np.exp(grid[-1]))
        out = np.exp(np.interp(np.log(np.clip(v, np.exp(grid[0]), np.exp(grid[-1]))), grid, table))
        return out if inside.all() else np.where(inside, out, self.exact_mean_speed(v))

    @cached_property
    def _tabulated(self) -> tuple[np.ndarray, np.ndarray]:
        """The log mean speed on 4001 log speeds from 1 mm/s to 5 m/s (linear interpolation error below 1e-6)."""
        grid = np.linspace(np.log(1e-3), np.log(5.0), 4001)
        return grid, np.log(self.exact_mean_speed(np.exp(grid)))

    def exact_mean_speed(self, speed: np.ndarray) -> np.ndarray:
        """(n,) the pusher's mean speed over its stroke (m/s) when commanded ``speed`` (n,) m/s with no box.

        The force kv (V - v) saturates at the limit F while V - v > F / kv (a constant acceleration F / m),
        then the speed approaches V with time constant m / kv; the stroke time solves x(T) = stroke."""
        V = np.maximum(np.asarray(speed, float), 1e-9)
        tau = self.mass / self.kv
        gap = np.minimum(V, self.force_limit / self.kv)  # V - v when the servo leaves its force limit
        t1 = (V - gap) * self.mass / self.force_limit  # time spent at the force limit
        x1 = 0.5 * self.force_limit / self.mass * t1 * t1

        def x(t):  # distance covered by time t (t >= t1)
            s = t - t1
            return x1 + V * s - gap * tau * (1.0 - np.exp(-s / tau))

        T = np.where(x1 >= self.stroke, np.sqrt(2.0 * self.stroke * self.mass / self.force_limit), 0.0)
        exp_phase = x1 < self.stroke
        # Newton from above the root (x is convex-then-linear in t, increasing): s/V + tau + t1 overshoots
        t = t1 + (self.stroke - x1) / V + tau
        for _ in range(40):
            speed_now = V - gap * np.exp(-(t - t1) / tau)
            t = np.maximum(t - (x(t) - self.stroke) / np.maximum(speed_now, 1e-12), t1)
        T = np.where(exp_phase, t, T)
        return self.stroke / T


@dataclass(frozen=True)
class ProbeRows:
    """The probes of one log as fit rows.

    friction_obj (f,), log_friction (f,), friction_sd (f,): each measured object, its log reading and the
    reading's sd in log units; pull_speed, pull_phi (f,): its pull test's drag speed (m/s) and direction (rad), NaN
    where the probes file does not say. added_obj, added_speed, added_phi, added_mass, added_log_d (a,): each loaded push;
    added_aux: {observable: (a,) its log, NaN where not measured} for the observables of :data:`PROBE_AUX` the fit
    uses. stroke_speed, log_stroke (s,): each free stroke's commanded speed and log measured mean speed; servo:
    their physics (None: the table's scene does not say, and the free strokes are not used).
    """

    friction_obj: np.ndarray
    log_friction: np.ndarray
    friction_sd: np.ndarray
    pull_speed: np.ndarray
    pull_phi: np.ndarray
    added_obj: np.ndarray
    added_speed: np.ndarray
    added_phi: np.ndarray
    added_mass: np.ndarray
    added_log_d: np.ndarray
    added_aux: dict[str, np.ndarray]
    stroke_speed: np.ndarray
    log_stroke: np.ndarray
    servo: Servo | None

    @classmethod
    def of(cls, probes: Probes, *, aux: tuple[str, ...], scene: dict | None) -> ProbeRows:
        """The rows of a log's checked ``probes``; ``aux``: the observables the fit uses beside displacement;
        ``scene``: the table's scene (for the free strokes' servo; None leaves them out)."""
        measured = np.flatnonzero(np.isfinite(probes.friction))
        reading = probes.friction[measured]
        servo = Servo.of_scene(scene)
        keep_stroke = servo is not None
        added_aux = {
            "stop_time": probes.added_stop_time,
            "pusher_speed": probes.added_pusher_speed,
        }
        return cls(
            friction_obj=measured,
            log_friction=np.log(reading),
            friction_sd=probes.friction_sd[measured] / reading,
            pull_speed=probes.friction_speed[measured],
            pull_phi=probes.friction_direction[measured],
            added_obj=probes.added_obj,
            added_speed=probes.added_speed,
            added_phi=np.nan_to_num(probes.added_direction, nan=0.0),
            added_mass=probes.added_mass,
            added_log_d=np.log(probes.added_displacement),
            added_aux={a: np.log(added_aux[a]) for a in PROBE_AUX if a in aux},
            stroke_speed=probes.free_stroke_speed if keep_stroke else np.zeros(0),
            log_stroke=np.log(probes.free_stroke_pusher_speed) if keep_stroke else np.zeros(0),
            servo=servo,
        )

    @property
    def n_added(self) -> int:
        return int(self.added_obj.size)

    def aux_rows(self) -> list[tuple[str, np.ndarray]]:
        """Each used observable of the loaded pushes and the pushes (indices into the added arrays) that have it."""
        return [(a, np.flatnonzero(np.isfinite(v))) for a, v in self.added_aux.items()]

    @property
    def row_obj(self) -> np.ndarray:
        """(q,) the object each probe row counts with (free strokes: the first object)."""
        aux = [self.added_obj[i] for _, i in self.aux_rows()]
        return np.concatenate([self.friction_obj, self.added_obj, *aux, np.zeros(self.stroke_speed.size, int)]).astype(
            int
        )

    def stroke_noise(self, pusher_speed_sd: float | None) -> float:
        """The free strokes' noise sd (log units): the log's pusher-speed noise where the fit has it, else the
        spread of replicate strokes at one speed, else :data:`STROKE_SD_DEFAULT`."""
        if pusher_speed_sd is not None:
            return max(float(pusher_speed_sd), STROKE_SD_FLOOR)
        _, inverse = np.unique(self.stroke_speed, return_inverse=True)
        inverse = inverse.ravel()
        groups = np.bincount(inverse)
        if (groups >= 2).any():
            mean = np.bincount(inverse, self.log_stroke) / groups
            dev = self.log_stroke - mean[inverse]
            dof = int(groups.sum() - groups.size)
            if dof > 0:
                return max(float(np.sqrt((dev * dev).sum() / dof)), STROKE_SD_FLOOR)
        return STROKE_SD_DEFAULT

    def friction_prediction(self, model: Model, thetas: np.ndarray, lms: np.ndarray, lus: np.ndarray) -> np.ndarray:
        """(K, f) the log of what each friction measurement reads under the model at K settings: thetas (K, p), the
        objects' log mass and log friction lms, lus (K, N)."""
        obj = self.friction_obj
        return pull_test_log_reading(model, thetas, lms[:, obj], lus[:, obj], self.pull_speed, self.pull_phi)

    def free_stroke_prediction(self, model: Model, thetas: np.ndarray) -> np.ndarray:
        """(K, s) the log mean speed of each free stroke under the model at each of K parameter settings."""
        return free_stroke_log_speed(self.servo, model, thetas, self.stroke_speed)


def free_stroke_log_speed(servo: Servo, model: Model, thetas: np.ndarray, speeds: np.ndarray) -> np.ndarray:
    """(K, s) the log of the pusher's mean speed over a free stroke commanded at ``speeds`` (s,) m/s, under ``model``
    at K parameter settings ``thetas`` (K, p): the servo driven at the speed the model gives the pusher."""
    K, s = thetas.shape[0], speeds.size
    if s == 0:
        return np.zeros((K, 0))
    speed = np.broadcast_to(speeds, (K, s))
    if model.dim:
        t = terms(model, np.repeat(thetas, s, axis=0), np.zeros(K * s))
        speed = speed * (1.0 + t.gain.reshape(K, s)) + t.offset.reshape(K, s)
    return np.log(servo.mean_speed(speed.ravel())).reshape(K, s)


def pull_test_log_reading(
    model: Model, thetas: np.ndarray, lm: np.ndarray, lu: np.ndarray, speed: np.ndarray, phi: np.ndarray
) -> np.ndarray:
    """(K, f) the log of what a pull test reads (its force over the box's weight) of f boxes of log mass and log
    friction ``lm``, ``lu`` (K, f), dragged at ``speed`` (f,) m/s in direction ``phi`` (f,) rad, under ``model`` at
    K parameter settings ``thetas`` (K, p): the steady balance along the drag (module docstring). A NaN speed leaves
    the viscous force out, a NaN direction the tilt along the drag and the anisotropy."""
    lu = np.asarray(lu, float)
    K, f = lu.shape
    if not model.dim or f == 0:
        return lu.copy()
    speed, phi = np.asarray(speed, float), np.asarray(phi, float)
    has_phi = np.tile(np.isfinite(phi), K)
    t = terms(model, np.repeat(np.asarray(thetas, float), f, axis=0), np.tile(np.nan_to_num(phi), K))
    along, across, viscous = np.zeros(K * f), np.zeros(K * f), np.zeros(K * f)
    for key, s in t.tables:
        if key == "slope":
            along = along + s
        elif key == "slope_across":
            across = across + s
        elif key == VISCOUS_KEY:
            viscous = viscous + s
    slope = np.hypot(along, across)  # the whole slope, whatever the drag's direction: the normal force's
    friction = np.exp(lu).ravel() * np.where(has_phi, t.friction, 1.0) * np.cos(slope)
    drag = np.tile(np.nan_to_num(speed), K) * viscous / (np.exp(np.asarray(lm, float)).ravel() * GRAVITY)
    reading = friction - np.sin(np.where(has_phi, along, 0.0)) + drag
    return np.log(np.maximum(reading, MIN_READING)).reshape(K, f)
