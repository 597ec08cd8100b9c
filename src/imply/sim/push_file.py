"""Pushes listed in a file, simulated into a push log (``imply sim pushes``).

The pushes file lists ``object_id,speed`` and, on the built-in scene, optional
``mass,friction,size_x,size_y,size_z``; the push log adds ``displacement``,
``stop_time`` (when the box's speed falls below :data:`imply.sim.track.STOP_SPEED`, read
from its positions every millisecond as the diagnostic's tables read it), ``pusher_speed`` (the pusher's mean speed over its stroke, as a robot's
encoders give it) and ``ok`` (the simulator's checks). A user MJCF must keep the names the
simulator relies on (:func:`imply.sim.pushes.simulate_pushes`).

Beside the log, :func:`simulate_push_table` can film each push: the box's track as the
rows ``object_id,push,t,x,y,yaw`` of :mod:`imply.diagnose.inputs.track_file` (``push`` the log's
row number; positions in the model's frame, the push along +x; no noise added), from the
start of the push until shortly after the box comes to rest.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np
import pandas as pd

from imply.input_files import InputError, read_table_lines, row_error
from imply.sim.pushes import PushStepping, simulate_pushes_run
from imply.sim.scene import SceneConfig, build_model
from imply.sim.track import filmed, pusher_speed, stop_frame_times, stop_times, track_frame_times, yaw_of

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
    track_rate: float | None = None,
) -> tuple[pd.DataFrame, pd.DataFrame | None]:
    """The push log of ``pushes`` (as :func:`read_pushes` returns it) on ``model`` or the built-in ``scene``, and
    with ``track_rate`` (frames per second) the boxes' tracks (None without)."""
    has_size = all(c in pushes for c in SIZE_COLUMNS)
    if model is not None and has_size:
        raise InputError("size_x/size_y/size_z columns cannot vary the box of a user model; edit the MJCF instead")
    # the box every millisecond for its stop time, and at the camera's frames for its track
    stop_frames = stop_frame_times()
    track_frames = None
    if track_rate is not None:
        if not track_rate > 0:
            raise ValueError(f"the track's rate must be positive, not {track_rate:g}")
        track_frames = track_frame_times(track_rate)
    frame_times = stop_frames if track_frames is None else np.union1d(stop_frames, track_frames)
    run = simulate_pushes_run(
        pushes["speed"].to_numpy(),
        pushes["mass"].to_numpy() if "mass" in pushes else None,
        pushes["friction"].to_numpy() if "friction" in pushes else None,
        pushes[SIZE_COLUMNS].to_numpy() if has_size else None,
        scene=None if model is not None else scene,
        model=model,
        nthread=nthread,
        progress=progress,
        frame_times=frame_times,
    )
    result = run.result
    at_stop = np.isin(frame_times, stop_frames)
    out = pushes.copy()
    out["displacement"] = result.displacement
    out["stop_time"] = stop_times(run.frames_box_qpos[:, at_stop, :2], run.frames_time[:, at_stop])
    stroke = PushStepping.of(model if model is not None else build_model(scene or SceneConfig())).stroke
    out["pusher_speed"] = pusher_speed(stroke, result.stroke_time)
    out["ok"] = result.ok
    return out, (None if track_frames is None else _track_rows(out, run, np.isin(frame_times, track_frames)))


def _track_rows(log_frame: pd.DataFrame, run, frames: np.ndarray) -> pd.DataFrame:
    """The rows of :mod:`imply.diagnose.inputs.track_file` of every push of a run, at its frames ``frames`` (mask)."""
    q = run.frames_box_qpos[:, frames]
    yaw = yaw_of(q[:, :, 3:7])
    parts = []
    for i in range(q.shape[0]):
        t = run.frames_time[i, frames]
        keep = filmed(t, log_frame["stop_time"].iloc[i])
        parts.append(
            pd.DataFrame(
                {
                    "object_id": log_frame["object_id"].iloc[i],
                    "push": i + 1,
                    "t": np.round(t[keep], 6),
                    "x": q[i, keep, 0],
                    "y": q[i, keep, 1],
                    "yaw": yaw[i, keep],
                }
            )
        )
    return pd.concat(parts, ignore_index=True)
