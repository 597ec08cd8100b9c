"""Rendered push clips of the Section 5 study: objects, episodes, splits and their storage.

Splits (config ``clips``; object draws are independent per split, so no object is in two):

* ``train``: ``n_train_episodes`` (1,500) objects, one episode each: 2 calibration
  pushes at ``score.calibration_speeds`` and 1 query push at a speed drawn uniformly
  from ``clips.train_speed`` -> 3 clips per object (4,500).
* ``heldout_calib``: ``n_heldout_calib`` (300) objects for the model trained with
  calibration context; ``heldout_nocalib``: ``n_heldout_nocalib`` (500) objects for the
  model trained without it. Each held-out object has its 2 calibration pushes and one
  query push at each of the K ``score.query_speeds`` -> 2 + K clips per object.
* ``pretrain``: ``n_pretrain_episodes`` objects laid out like ``train``, used only to
  pretrain the CPU encoder (never for the readout or the predictor).
* ``validation``: ``n_validation`` (200) objects laid out like the held-out splits (2
  calibration pushes, a query push at each of the K query speeds), in no training or
  held-out set: the predictor's per-epoch validation computes every Table 3 quantity on
  them exactly as on the held-out objects, and every recipe choice is made there.

Objects: mass and friction log-uniform over ``clips.masses`` / ``clips.frictions`` (the
table's range by default); box half-extents are the scene's canonical box scaled per
axis by a factor uniform in ``clips.size_scale``.

Storage, per split ``S`` under the output folder (``results/clips/``):

``S.npz`` (zip-compressed; the same frames give the same bytes, :func:`imply.io.write_npz`)
    ``frames``   uint8 (n_clips, T, H, W, 3): T = len(frame_times) + 1 = 8 RGB frames;
                 H x W from ``clips.camera`` (32 x 128 by default, 1 cm per pixel, the
                 table from x = -0.13 m to 1.15 m; image columns run along the push
                 direction +x, rows along y; fixed orthographic top-down camera, 4x MSAA;
                 see :mod:`imply.sim.render`).
    ``clip_id``  int64 (n_clips,): the same ids, in the same order, as the CSV rows.
    ``frame_times_nominal`` float64 (T - 1,): ``clips.frame_times``.
    ``metres_per_pixel`` float64 scalar: the camera's scale.

``S.csv``: one row per clip, rows in ``clip_id`` order (0 .. n_clips - 1), columns

    clip_id       int, row index into ``frames``
    split         the split name
    object_id     str, e.g. ``train-00012`` (unique across splits)
    episode       int, object index within the split (one episode per object)
    role          ``calibration_0`` | ``calibration_1`` | ``query``
    speed_index   int: for held-out query clips the index k into score.query_speeds;
                  -1 for calibration clips and for training query clips
    speed         commanded pusher speed, m/s (the action)
    displacement  true slide of the box along +x at rest, metres, from the simulator
    stop_time     time the box was seen at rest, s (the last frame's time)
    ok            1 if the push passed the simulator's checks (settled, upright, straight)
    mass, friction        box mass (kg) and sliding friction
    size_x, size_y, size_z box half-extents, metres
    t0 .. t7      time of each frame, s: t0..t6 are ``frame_times`` (a box already at
                  rest is shown at rest), t7 is the rest state (= stop_time)

Within an object, clips are ordered calibration_0, calibration_1, then the query
clip(s) in speed order. Read a split with :func:`load_clips` (frames, metadata).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from imply.io import write_csv, write_npz
from imply.options import Config, Range, option
from imply.score import ScoreConfig
from imply.sim.render import CameraConfig, ClipRenderer, PushRecording, record_pushes
from imply.sim.scene import SceneConfig

log = logging.getLogger("imply.clips")

# appended, never reordered: a split's index seeds its objects' draws
SPLITS = ("train", "heldout_calib", "heldout_nocalib", "pretrain", "validation")
# splits laid out like the held-out ones: every object pushed at each query speed
QUERY_SPEED_SPLITS = ("heldout_calib", "heldout_nocalib", "validation")
ROLES = ("calibration_0", "calibration_1", "query")


@dataclass(frozen=True, kw_only=True)
class ClipsConfig(Config):
    """Config section ``clips`` (the speeds it renders at come from section ``score``)."""

    config_key: ClassVar[str] = "clips"

    seed: int = option(5, doc="seed of the objects' draws", minimum=0, required=True)
    n_train_episodes: int = option(1500, doc="training objects (3 clips each)", minimum=2, required=True)
    n_heldout_calib: int = option(
        300, doc="held-out objects for the model with calibration context", minimum=1, required=True
    )
    n_heldout_nocalib: int = option(500, doc="held-out objects for the model without it", minimum=1, required=True)
    n_pretrain_episodes: int = option(
        600, doc="frames for the CPU encoder's JEPA pretraining only", minimum=1, required=True
    )
    n_validation: int = option(
        200, doc="validation objects (2 + K clips each): the predictor's per-epoch validation", minimum=2
    )
    train_speed: Range = option(Range(min=0.15, max=1.05), doc="training query speeds, uniform (m/s)")
    masses: Range = option(Range(min=0.2, max=2.0), doc="log-uniform (kg)")
    frictions: Range = option(Range(min=0.1, max=0.6), doc="log-uniform")
    size_scale: Range = option(Range(min=0.85, max=1.15), doc="per-axis scale of the canonical box")
    frame_times: tuple[float, ...] = option(
        (0.0, 0.03, 0.06, 0.1, 0.15, 0.25, 0.4),
        doc="s; an 8th frame shows the box at rest",
        min_items=1,
        items={"minimum": 0},
        required=True,
    )
    camera: CameraConfig = option(CameraConfig(), doc="the top-down view", required=True)
    batch: int = option(500, doc="pushes simulated per batch", minimum=1)

    def n_objects(self, split: str) -> int:
        return {
            "train": self.n_train_episodes,
            "heldout_calib": self.n_heldout_calib,
            "heldout_nocalib": self.n_heldout_nocalib,
            "pretrain": self.n_pretrain_episodes,
            "validation": self.n_validation,
        }[split]


def sample_objects(cfg: ClipsConfig, split: str, scene: SceneConfig) -> pd.DataFrame:
    """The split's objects: object_id, episode, mass, friction, size_x/y/z (half-extents)."""
    if split not in SPLITS:
        raise ValueError(f"unknown split {split!r} (one of {', '.join(SPLITS)})")
    n = cfg.n_objects(split)
    # one stream per split from (seed, split index): splits never share draws
    rng = np.random.default_rng([cfg.seed, SPLITS.index(split)])
    mass = np.exp(rng.uniform(*np.log(cfg.masses.as_tuple()), n))
    friction = np.exp(rng.uniform(*np.log(cfg.frictions.as_tuple()), n))
    scale = rng.uniform(*cfg.size_scale.as_tuple(), (n, 3))
    he = np.asarray(scene.box_half_extents, dtype=float)[None, :] * scale
    query = rng.uniform(*cfg.train_speed.as_tuple(), n)
    return pd.DataFrame(
        {
            "object_id": [f"{split}-{i:05d}" for i in range(n)],
            "episode": np.arange(n),
            "mass": mass,
            "friction": friction,
            "size_x": he[:, 0],
            "size_y": he[:, 1],
            "size_z": he[:, 2],
            "train_query_speed": query,
        }
    )


def plan_clips(cfg: ClipsConfig, split: str, *, scene: SceneConfig, speeds: ScoreConfig) -> pd.DataFrame:
    """One row per clip of the split (before simulation): ids, role, speed, object physics.

    Calibration pushes are at ``speeds.calibration_speeds``, held-out queries at every
    ``speeds.query_speeds``.
    """
    objects = sample_objects(cfg, split, scene)
    heldout = split in QUERY_SPEED_SPLITS
    rows = []
    for obj in objects.itertuples(index=False):
        calib = speeds.calibration_speeds
        pushes = [("calibration_0", -1, calib[0]), ("calibration_1", -1, calib[1])]
        if heldout:
            pushes += [("query", k, v) for k, v in enumerate(speeds.query_speeds)]
        else:
            pushes.append(("query", -1, float(obj.train_query_speed)))
        for role, k, v in pushes:
            rows.append(
                {
                    "split": split,
                    "object_id": obj.object_id,
                    "episode": obj.episode,
                    "role": role,
                    "speed_index": k,
                    "speed": float(v),
                    "mass": obj.mass,
                    "friction": obj.friction,
                    "size_x": obj.size_x,
                    "size_y": obj.size_y,
                    "size_z": obj.size_z,
                }
            )
    plan = pd.DataFrame(rows)
    plan.insert(0, "clip_id", np.arange(len(plan)))
    return plan


def record_planned(plan: pd.DataFrame, frame_times, *, scene: SceneConfig, nthread: int = 1) -> PushRecording:
    """Simulate the pushes of planned clip rows (speed, mass, friction, size_x/y/z) in one batch."""
    return record_pushes(
        plan["speed"].to_numpy(),
        plan["mass"].to_numpy(),
        plan["friction"].to_numpy(),
        plan[["size_x", "size_y", "size_z"]].to_numpy(),
        frame_times,
        scene=scene,
        nthread=nthread,
    )


def render_split(
    cfg: ClipsConfig,
    split: str,
    *,
    scene: SceneConfig,
    speeds: ScoreConfig,
    nthread: int = 1,
    progress: bool = True,
) -> tuple[np.ndarray, pd.DataFrame]:
    """Simulate and render every clip of a split: (frames, metadata) as stored."""
    plan = plan_clips(cfg, split, scene=scene, speeds=speeds)
    n = len(plan)
    cam = cfg.camera
    n_frames = len(cfg.frame_times) + 1
    frames = np.zeros((n, n_frames, cam.height, cam.width, 3), dtype=np.uint8)
    disp = np.zeros(n)
    stop = np.zeros(n)
    ok = np.zeros(n, dtype=bool)
    times = np.zeros((n, n_frames))
    t_sim = t_draw = 0.0
    bar = tqdm(total=n * n_frames, desc=f"render {split}", unit="frame", disable=not progress, mininterval=2.0)
    with ClipRenderer(scene, cam) as renderer:
        for lo in range(0, n, cfg.batch):
            part = plan.iloc[lo : lo + cfg.batch]
            t0 = time.perf_counter()
            rec = record_planned(part, cfg.frame_times, scene=scene, nthread=nthread)
            t1 = time.perf_counter()
            for j in range(len(part)):
                frames[lo + j] = renderer.render(rec, j)
                bar.update(n_frames)
            t_draw += time.perf_counter() - t1
            t_sim += t1 - t0
            sl = slice(lo, lo + len(part))
            disp[sl], stop[sl], ok[sl], times[sl] = rec.displacement, rec.stop_time, rec.ok, rec.times
    bar.close()
    n_img = n * n_frames
    log.info(
        "%s: %d clips, %d frames; simulation %.1f s, drawing %.1f s (%.0f frames/s drawn, %.0f frames/s overall)",
        split,
        n,
        n_img,
        t_sim,
        t_draw,
        n_img / max(t_draw, 1e-9),
        n_img / max(t_sim + t_draw, 1e-9),
    )
    if not ok.all():
        log.warning("%s: %d of %d pushes failed the simulator's checks (kept, ok=0)", split, int((~ok).sum()), n)
    meta = plan.copy()
    cols = list(meta.columns)
    meta["displacement"] = disp
    meta["stop_time"] = stop
    meta["ok"] = ok.astype(int)
    for k in range(n_frames):
        meta[f"t{k}"] = times[:, k]
    order = cols[:7] + ["displacement", "stop_time", "ok"] + cols[7:] + [f"t{k}" for k in range(n_frames)]
    return frames, meta[order]


def save_split(
    npz_path: str | Path, csv_path: str | Path, *, frames: np.ndarray, meta: pd.DataFrame, cfg: ClipsConfig
) -> None:
    """Write a split's frames (.npz) and metadata (.csv); format in the module docstring."""
    write_npz(
        npz_path,
        compressed=True,
        frames=frames,
        clip_id=meta["clip_id"].to_numpy(dtype=np.int64),
        frame_times_nominal=np.asarray(cfg.frame_times, dtype=float),
        metres_per_pixel=np.float64(cfg.camera.metres_per_pixel),
    )
    write_csv(csv_path, meta)


def load_meta(csv_path: str | Path) -> pd.DataFrame:
    """A split's metadata CSV (object_id and role as strings)."""
    meta = pd.read_csv(csv_path, dtype={"object_id": str, "role": str, "split": str})
    if not np.array_equal(meta["clip_id"].to_numpy(), np.arange(len(meta))):
        raise ValueError(f"{csv_path}: clip_id must run 0..n-1 in row order")
    return meta


def load_clips(npz_path: str | Path, csv_path: str | Path | None = None) -> tuple[np.ndarray, pd.DataFrame]:
    """(frames uint8 (n_clips, T, H, W, 3), metadata) of a split written by :func:`save_split`."""
    npz_path = Path(npz_path)
    csv_path = Path(csv_path) if csv_path is not None else npz_path.with_suffix(".csv")
    with np.load(npz_path) as z:
        frames = z["frames"]
        ids = z["clip_id"]
    meta = load_meta(csv_path)
    if not np.array_equal(ids, meta["clip_id"].to_numpy()):
        raise ValueError(f"{npz_path} and {csv_path} list different clips")
    return frames, meta
