"""Pushes listed in a file, simulated into a push log (``imply sim pushes``).

The pushes file lists ``object_id,speed`` and, on the built-in scene, optional
``mass,friction,size_x,size_y,size_z``; the push log adds ``displacement``,
``stop_time``, ``pusher_speed`` (the pusher's mean speed over its stroke, as a robot's
encoders give it) and ``ok`` (the simulator's checks). A user MJCF must keep the names the
simulator relies on (:func:`imply.sim.pushes.simulate_pushes`).
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np
import pandas as pd

from imply.input_files import InputError, read_table_lines, row_error
from imply.sim.pushes import PushStepping, simulate_pushes
from imply.sim.scene import SceneConfig, build_model
from imply.sim.track import pusher_speed

SIZE_COLUMNS = ["size_x", "size_y", "size_z"]


def read_pushes(path: str | os.PathLike) -> pd.DataFrame:
    """The pushes file, checked: every speed, mass, friction and size positive (errors name the row)."""
    frame, lines = read_table_lines(path, ["object_id", "speed"], ["speed"], ["mass", "friction", *SIZE_COLUMNS])
    for col in ["speed", "mass", "friction", *SIZE_COLUMNS]:
        if col in frame and (frame[col] <= 0).any():
            i = int(np.flatnonzero(frame[col].to_numpy() <= 0)[0])
            raise row_error(path, i, col, "must be positive", lines)
    return frame


def load_push_model(path: str | os.PathLike) -> mujoco.MjModel:
    """A user's push scene (MJCF); ValueError naming the file if it does not load or cannot be stepped."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except Exception as exc:
        raise ValueError(f"{path}: {exc}") from exc
    if not model.opt.timestep > 0:
        raise ValueError(f"{path}: timestep {model.opt.timestep:g} must be positive")
    return model


def simulate_push_table(
    pushes: pd.DataFrame,
    *,
    model: mujoco.MjModel | None = None,
    scene: SceneConfig | None = None,
    nthread: int = 0,
    progress: bool = False,
) -> pd.DataFrame:
    """The push log of ``pushes`` (as :func:`read_pushes` returns it) on ``model`` or the built-in ``scene``."""
    has_size = all(c in pushes for c in SIZE_COLUMNS)
    if model is not None and has_size:
        raise InputError("size_x/size_y/size_z columns cannot vary the box of a user model; edit the MJCF instead")
    result = simulate_pushes(
        pushes["speed"].to_numpy(),
        pushes["mass"].to_numpy() if "mass" in pushes else None,
        pushes["friction"].to_numpy() if "friction" in pushes else None,
        pushes[SIZE_COLUMNS].to_numpy() if has_size else None,
        scene=None if model is not None else scene, model=model, nthread=nthread, progress=progress,
    )  # fmt: skip
    out = pushes.copy()
    out["displacement"] = result.displacement
    out["stop_time"] = result.stop_time
    stroke = PushStepping.of(model if model is not None else build_model(scene or SceneConfig())).stroke
    out["pusher_speed"] = pusher_speed(stroke, result.stroke_time)
    out["ok"] = result.ok
    return out
