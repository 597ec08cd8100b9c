"""The next experiment may be a probe, not a push: the calibration probe that best separates the contenders.

Candidates are the probes of :mod:`imply.diagnose.inputs.probes` the log could add: a free stroke
at each candidate speed, a friction measurement of each object not yet measured (nor
weighed into the log as a fixed friction), and a push of each object with a known load (half
its fitted mass, inside the table's range) at the log's lowest and highest speed. Each
contender (as in :mod:`imply.diagnose.conclusion.next_pushes`) predicts what each probe would read, by
the same physics its fit uses (:mod:`imply.diagnose.physics.probe_fit`): the free stroke through
the rig's servo at the pusher's speed under that contender, the friction reading as a pull
test reads it under that contender's effects (:func:`imply.diagnose.physics.probe_fit.pull_test_log_reading`:
a drag at :data:`imply.diagnose.inputs.probes.DEFAULT_PULL_SPEED` along the object's first push of the log, so that a tilt or a
viscous force moves the reading and a change of the table's friction does not), the loaded
push as a push at the loaded mass. A probe's
separation of two contenders is the squared difference of their predictions over its noise
(a friction reading's default stated uncertainty, the log's displacement noise and model
floor, a free stroke's noise or, where the log does not say, 0.02 in log).

One probe is recommended where its smallest separation over the pairs of contenders is
larger than that of any single candidate push: the measurement that tells them apart.
``write_next_probes`` writes it as a probes-file row (``probe,object_id,speed,added_mass``)
with what each contender predicts (``expected_<what>_if_<label>``), beside ``next_pushes.csv``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import pandas as pd

from imply.diagnose.inference.fit import JointFit, Problem
from imply.diagnose.inputs.probes import DEFAULT_FRICTION_SD, DEFAULT_PULL_SPEED
from imply.diagnose.physics.probe_fit import Servo, free_stroke_log_speed, pull_test_log_reading
from imply.diagnose.records import Record
from imply.io import write_csv

ASSUMED_STROKE_SD = 0.02  # log units: a free stroke's noise where the log does not say (as next_pushes assumes)
LOAD_SHARE = 0.5  # a loaded push's load, as a share of the box's fitted mass (kept inside the table's mass range)
MIN_LOAD = 0.05  # kg: a smaller load is not worth a push
# what each kind of probe reads, as the file's column names it
READS = {"free_stroke": "pusher_speed", "friction": "friction", "added_mass": "displacement"}


@dataclass(frozen=True, kw_only=True)
class NextProbe(Record):
    """The probe recommended to separate the contenders, what each one predicts it reads, and why."""

    probe: str  # free_stroke | friction | added_mass
    object_id: str | None
    speed: float | None  # m/s (free strokes and loaded pushes; a friction test's drag)
    added_mass: float | None  # kg (loaded pushes)
    expected: dict[
        str, float
    ]  # by contender label: the pusher's mean speed (m/s), the friction, or the displacement (m)
    separation_sd: float  # its smallest separation over the pairs of contenders (noise sds)
    best_push_sd: float  # the same for the best single candidate push


def _candidates(problem: Problem, speeds: np.ndarray, fits: list[JointFit]):
    """Every candidate probe: (kind, object index or -1, speed or nan, load or nan) rows, each contender's prediction
    of it in log units (n, C), and its noise sd (n,)."""
    rows: list[tuple[str, int, float, float]] = []
    preds: list[np.ndarray] = []
    sds: list[np.ndarray] = []
    lead = fits[0]
    servo = Servo.of_scene(problem.table.meta.get("scene"))
    if servo is not None:
        p = np.stack([free_stroke_log_speed(servo, f.model, f.theta[None, :], speeds)[0] for f in fits], 1)
        if problem.probes is not None and problem.probes.stroke_speed.size:
            sd = problem.probes.stroke_noise(problem.aux_noise("pusher_speed"))
        else:
            sd = problem.aux_noise("pusher_speed") or ASSUMED_STROKE_SD
        rows += [("free_stroke", -1, float(v), np.nan) for v in speeds]
        preds.append(p)
        sds.append(np.full(speeds.size, sd))
    measured = np.zeros(problem.n_obj, bool)
    if problem.log.probes is not None:
        measured |= np.isfinite(problem.log.probes.friction)
    if problem.fixed_lu is None:
        free = np.flatnonzero(~measured)
        rows += [("friction", int(i), DEFAULT_PULL_SPEED, np.nan) for i in free]
        # along each object's first push (the log's order), as a lab would set up its test
        first = np.array([problem.phi[np.flatnonzero(problem.obj == i)[0]] for i in free], float)
        if not problem.log.has_direction:
            first = np.full(free.size, np.nan)  # a log without directions: the pull's is not known either
        speed = np.full(free.size, DEFAULT_PULL_SPEED)
        preds.append(
            np.stack(
                [
                    pull_test_log_reading(
                        f.model, f.theta[None, :], f.objects.lm[None, free], f.objects.lu[None, free], speed, first
                    )[0]
                    for f in fits
                ],
                1,
            )
        )
        sds.append(DEFAULT_FRICTION_SD / np.exp(lead.objects.lu[free]))
    mass = np.exp(lead.objects.lm)
    hi_mass = float(problem.table.mass_range[1])
    load = np.round(np.minimum(LOAD_SHARE * mass, hi_mass - mass), 3)
    which = np.flatnonzero(load >= MIN_LOAD)
    if which.size:
        v_lo, v_hi = float(problem.v.min()), float(problem.v.max())
        obj = np.repeat(which, 2)
        v = np.tile([v_lo, v_hi], which.size)
        phi = np.zeros(v.size)
        p = np.stack(
            [
                problem.predict_at(f.model, f.theta, v, phi, f.objects.lm[obj], f.objects.lu[obj], load=load[obj]).log_d
                for f in fits
            ],
            1,
        )
        rows += [("added_mass", int(i), float(s), float(load[i])) for i, s in zip(obj, v, strict=True)]
        preds.append(p)
        sds.append(np.full(v.size, float(np.sqrt(problem.noise_d**2 + np.mean(problem.model_err_d**2)))))
    if not rows:
        return [], np.zeros((0, len(fits))), np.zeros(0)
    return rows, np.concatenate(preds, 0), np.concatenate(sds)


def recommend_probe(
    problem: Problem, contenders: list[tuple[str, JointFit, float]], *, speeds: np.ndarray, best_push_sd: float
) -> NextProbe | None:
    """The probe that separates ``contenders`` ((label, fit, weight)) most, where it beats the best single push
    (``best_push_sd``: its smallest pair separation, noise sds); None otherwise."""
    if len(contenders) < 2:
        return None
    fits = [f for _, f, _ in contenders]
    rows, pred, sd = _candidates(problem, np.asarray(speeds, float), fits)
    if not rows:
        return None
    pairs = [(a, b) for a in range(len(fits)) for b in range(a + 1, len(fits))]
    sep = np.stack([((pred[:, a] - pred[:, b]) / sd) ** 2 for a, b in pairs], 1)
    worst = np.sqrt(sep.min(1))
    k = int(np.argmax(worst))
    if worst[k] <= best_push_sd:
        return None
    kind, obj, speed, load = rows[k]
    to_value = np.exp(pred[k])
    return NextProbe(
        probe=kind,
        object_id=problem.log.objects[obj] if obj >= 0 else None,
        speed=None if np.isnan(speed) else speed,
        added_mass=None if np.isnan(load) else load,
        expected={label: float(x) for (label, _, _), x in zip(contenders, to_value, strict=True)},
        separation_sd=float(worst[k]),
        best_push_sd=float(best_push_sd),
    )


def probe_words(p: NextProbe) -> str:
    """The recommended probe in a few words ("a free stroke at 0.9 m/s")."""
    if p.probe == "free_stroke":
        return f"a free stroke of the pusher at {p.speed:.2g} m/s"
    if p.probe == "friction":
        return f"a friction measurement of {p.object_id} (a pull at {p.speed:.2g} m/s along its first push)"
    return f"a push of {p.object_id} at {p.speed:.2g} m/s with {p.added_mass:.3g} kg added"


def next_probes_frame(probe: NextProbe | None) -> pd.DataFrame:
    """The recommended probe as a probes-file row with each contender's prediction (no rows without one)."""
    labels = list(probe.expected) if probe is not None else []
    what = READS[probe.probe] if probe is not None else "reading"
    cols = ["probe", "object_id", "speed", "added_mass", *(f"expected_{what}_if_{lab}" for lab in labels)]
    if probe is None:
        return pd.DataFrame(columns=cols)
    row = {
        "probe": probe.probe,
        "object_id": probe.object_id or "",
        "speed": "" if probe.speed is None else round(probe.speed, 4),
        "added_mass": "" if probe.added_mass is None else probe.added_mass,
        **{f"expected_{what}_if_{lab}": x for lab, x in probe.expected.items()},
    }
    return pd.DataFrame([row], columns=cols)


def write_next_probes(path: str | os.PathLike, probe: NextProbe | None) -> None:
    """``next_probes.csv``: the recommended probe (a header alone where no probe beats the next pushes)."""
    write_csv(path, next_probes_frame(probe))
