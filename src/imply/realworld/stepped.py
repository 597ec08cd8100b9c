"""One push, stepped one engine step at a time: the rig's protocol for engines without a batch (Bullet, SAPIEN).

An engine world builds the scene its own way and hands :func:`run_push` an
:class:`EngineRig`: the few calls a push needs (the pusher's joint state, the box's pose
and velocity, a force on the box, the box's friction, the servo's force, the step). The
protocol is the MuJoCo world's (:mod:`imply.realworld.world`), written once for every
such engine:

- the pusher's velocity servo, force ``kv (u - v)`` clipped to the force limit, drives
  the box over the stroke; the last two steps before the stroke share what is left of it,
  no step shorter than half the push step (an engine's penetration correction launches
  the box on a very short step); then the servo is commanded to 0 and brakes, a release
  window at the push step follows, and the box slides to rest on the slide step;
- viscous force and air drag are forces on the box at every step, and the friction laws
  (anisotropy, Stribeck, a gradient along the table) set the box's friction at every step
  from its state at the start of the step;
- the stop time is when the box's speed in the table plane falls below ``stop_speed``
  (interpolated within the step), the push is over below ``rest_speed``;
- the servo's mean force over the second half of the stroke is recorded (a pull test's
  gauge reading), and the box's track at the times asked for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from imply.sim.track import yaw_of


class EngineRig(Protocol):
    """The calls :func:`run_push` makes on an engine's scene (positions in the push frame, +x along the push)."""

    def pusher_state(self) -> tuple[float, float]:
        """The carriage's travel along its joint (m) and its speed (m/s)."""

    def box_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """The box's position (3,) and orientation as a unit quaternion (4,), x, y, z, w."""

    def box_velocity(self) -> np.ndarray:
        """The box's linear velocity (3,)."""

    def rotation(self, quat: np.ndarray) -> np.ndarray:
        """The (3, 3) rotation matrix of ``quat`` (x, y, z, w), the engine's own."""

    def push_box(self, force: np.ndarray, position: np.ndarray) -> None:
        """Apply ``force`` (3,) at ``position`` on the box for the coming step."""

    def set_box_friction(self, friction: float) -> None:
        """The box-table contact's friction coefficient from the coming step on."""

    def drive(self, force: float) -> None:
        """The servo's force on the carriage's joint for the coming step."""

    def set_step(self, step: float) -> None:
        """The engine's step (s) from the coming step on."""

    def step(self) -> None:
        """Advance the engine one step."""


@dataclass(frozen=True)
class SteppedPush:
    """One push's outcome: travel along and across the push (m), stop time (s), ok, steps, stroke time (s),
    the servo's mean force over the second half of the stroke (N) and the box's track (T, 3) where asked."""

    displacement: float
    lateral: float
    stop_time: float
    ok: bool
    steps: int
    stroke_time: float
    drive_force: float
    track: np.ndarray | None


def check_steps(stepping: StepPlan, engine: str) -> None:
    """Refuse (ValueError naming the field) steps and thresholds that are not positive numbers, or a push that could
    take more than 1e7 steps."""
    for name in ("push_step", "slide_step", "stop_speed", "rest_speed", "max_time"):
        value = getattr(stepping, name)
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ValueError(f"{engine} stepping: {name} must be a positive number, not {value!r}")
    if stepping.max_time / min(stepping.push_step, stepping.slide_step) > 1e7:
        raise ValueError(f"{engine} stepping: a push could take more than 1e7 steps; raise the steps")


class StepPlan(Protocol):
    """The steps (s) and thresholds (m/s) of a push: an engine's stepping config (``BulletStepping``, ...)."""

    push_step: float
    release_window: float
    slide_step: float
    stop_speed: float
    rest_speed: float
    max_time: float


def run_push(
    rig: EngineRig,
    st: StepPlan,
    *,
    speed: float,
    friction: float,
    direction: float,
    prm: dict[str, float],
    stroke: float,
    area: tuple[float, float, float],
    track_times: np.ndarray | None = None,
) -> SteppedPush:
    """Push the box of ``rig`` at commanded ``speed`` over ``stroke`` (m) in table direction ``direction`` (rad).

    ``prm``: the world's parameters (:data:`imply.realworld.world.PARAMETERS`) this engine
    carries; ``area``: the box's cross-sections per body axis (m^2), for air drag. The
    rig's step is ``st.push_step`` when the push starts.
    """
    forced = prm["viscous"] != 0 or prm["air_density"] != 0
    lawful = prm["aniso"] != 0 or prm["stribeck"] != 0 or prm["gradient"] != 0
    if not lawful:
        rig.set_box_friction(friction)
    kv, limit = prm["servo_kv"], prm["force_limit"]

    start = np.array(rig.box_pose()[0])
    now, n_steps = 0.0, 0
    command = speed
    phase = 0  # 0 pushing, 1 release window, 2 sliding
    window_left = 0
    h = engine_step = st.push_step
    stop_time = st.max_time
    stroke_time = math.nan
    speed_before = 0.0
    impulse = impulse_time = 0.0
    track = None if track_times is None else np.zeros((track_times.size, 3))
    frame = 0

    def record() -> None:
        # a camera frame is taken at the first step that reaches its time (within half a step)
        nonlocal frame
        if track is None:
            return
        while frame < track_times.size and now >= track_times[frame] - h / 2:
            p, q = rig.box_pose()
            track[frame] = (p[0] - start[0], p[1] - start[1], float(yaw_of(np.array([q[3], q[0], q[1], q[2]]))))
            frame += 1

    record()
    while True:
        q, qd = rig.pusher_state()
        pos, quat = rig.box_pose()
        vel = rig.box_velocity()
        planar = math.hypot(vel[0], vel[1])
        ending = False
        if phase == 0:
            left = (stroke - q) / max(qd * st.push_step, 1e-12)
            h = st.push_step
            if left <= 0.0:
                stroke_time = now
                command, phase = 0.0, 1  # already at the stroke: the servo brakes now
                window_left = round(st.release_window / st.push_step)
            elif left < 1.0 or now + st.push_step >= st.max_time:
                ending = True
                h = min(max(left, 0.5), 1.0) * st.push_step
            elif left < 2.0:
                h = left / 2.0 * st.push_step
        if forced:
            f = np.array([-prm["viscous"] * v for v in vel])
            if prm["air_density"] != 0:
                rot = rig.rotation(quat)
                local = rot.T @ np.asarray(vel)
                f += rot @ (-0.5 * prm["air_density"] * np.asarray(area) * np.abs(local) * local)
            rig.push_box(f, pos)
        if lawful:
            theta = (math.atan2(vel[1], vel[0]) if planar > 1e-9 else 0.0) + direction
            factor = 1.0 + prm["aniso"] * math.cos(2.0 * (theta - prm["aniso_axis"]))
            factor *= 1.0 + prm["stribeck"] * math.exp(-((planar / prm["stribeck_speed"]) ** 2))
            grel = prm["gradient_azimuth"] - direction
            along = (pos[0] - start[0]) * math.cos(grel) + (pos[1] - start[1]) * math.sin(grel)
            factor *= max(1.0 + prm["gradient"] * along, 0.2)
            rig.set_box_friction(friction * factor)
        servo = min(max(kv * (command - qd), -limit), limit)
        rig.drive(servo)
        if h != engine_step:
            rig.set_step(h)
            engine_step = h
        rig.step()
        now += h
        n_steps += 1
        if phase == 0 and q > stroke / 2:
            # the servo's force over the second half of the stroke (a pull test's gauge)
            impulse += servo * h
            impulse_time += h
        record()
        vel = rig.box_velocity()
        after = math.hypot(vel[0], vel[1])
        if phase >= 1:
            if after < st.stop_speed and stop_time >= st.max_time:
                # interpolated within the step
                frac = (speed_before - st.stop_speed) / max(speed_before - after, 1e-300)
                stop_time = now - h * (1.0 - min(max(frac, 0.0), 1.0))
            if phase == 2 and (after < st.rest_speed or not math.isfinite(after) or now >= st.max_time):
                break
        speed_before = after
        if ending:
            stroke_time = now
            command, phase, h = 0.0, 1, st.push_step  # the servo brakes
            window_left = round(st.release_window / st.push_step)
        elif phase == 1:
            window_left -= 1
            if window_left <= 0:
                phase, h = 2, st.slide_step
        if phase == 0 and now >= st.max_time:
            break
    pos, quat = rig.box_pose()
    disp, lateral = pos[0] - start[0], pos[1] - start[1]
    # tipped: the box's up axis more than 0.1 rad from the vertical
    x, y = quat[0], quat[1]
    tipped = math.acos(min(max(1.0 - 2.0 * (x * x + y * y), -1.0), 1.0)) >= 0.1
    ok = math.isfinite(disp) and now < st.max_time and stop_time < st.max_time and not tipped and disp > 0
    if track is not None and frame < track_times.size:
        # frames due after the box came to rest see it where it stopped
        track[frame:] = (disp, lateral, float(yaw_of(np.array([quat[3], quat[0], quat[1], quat[2]]))))
    drive_force = impulse / impulse_time if impulse_time > 0 else math.nan
    return SteppedPush(disp, lateral, stop_time, ok, n_steps, stroke_time, drive_force, track)
