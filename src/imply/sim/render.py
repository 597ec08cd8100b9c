"""Offscreen push clips: record pushes on ``mujoco.batch`` and render frames from a fixed camera.

Two steps, kept apart so the expensive one is batched:

1. :func:`record_pushes` simulates many pushes at once on ``mujoco.batch`` exactly as
   :func:`imply.sim.pushes.simulate_pushes` does (the same stepping, the same code), and
   stores the box's and the pusher's positions at the requested frame times plus once
   more when the box has settled.
   The last frame is therefore always the box at rest, and its travel is the true
   displacement of the push.
2. :class:`ClipRenderer` draws those states with ``mujoco.Renderer`` (EGL; set
   ``MUJOCO_GL=egl`` before importing mujoco, as this module does by default). Drawing
   needs no physics, so one render model serves every object: the box's and the
   pusher's sizes are written into it per object, and the recorded positions into its
   data before each frame.

The camera is fixed and orthographic, looking straight down on the push axis (image
columns run along +x, the push direction), so pixels map to metres linearly and the
same everywhere in the frame: a box's travel of d metres moves it d / metres_per_pixel
columns. :class:`CameraConfig` holds the view (config key ``clips.camera``).
"""

from __future__ import annotations

import importlib
import os
from dataclasses import dataclass
from typing import ClassVar

import mujoco
import numpy as np

from imply.options import Config, option
from imply.sim.pushes import batch_with_geometry, run_pushes
from imply.sim.scene import SceneConfig, build_model


def _use_egl() -> None:
    """Make offscreen rendering use EGL unless the user chose a backend.

    mujoco picks its GL backend when its rendering module is first imported, which
    happens with ``import mujoco`` (long before this module, e.g. via imply.sim). If
    no backend was chosen then, set EGL and re-run that choice; without it mujoco
    falls back to GLFW, which needs a display.
    """
    # small frames gain nothing from Mesa's software rasteriser threads, and on a busy
    # machine those threads wait on each other: one thread is several times faster
    os.environ.setdefault("LP_NUM_THREADS", "1")
    if os.environ.get("MUJOCO_GL"):
        return
    os.environ["MUJOCO_GL"] = "egl"
    from mujoco.rendering.classic import gl_context

    importlib.reload(gl_context)  # the renderer holds the module, so it sees the new choice


_use_egl()


@dataclass(frozen=True, kw_only=True)
class CameraConfig(Config):
    """A fixed orthographic top-down view of the push axis.

    x_min, x_max: the strip of table (metres along the push axis) that fills the image
    width; the image height covers the same metres per pixel, centred on y = 0.
    height, width: image size in pixels.
    multisample: OpenGL multisample anti-aliasing samples per pixel (0: off). The scene
      MJCF turns it off for speed; clips turn it back on because a box edge inside a
      pixel should shade it in proportion, as a camera's pixel integrates light, so that
      sub-pixel motion stays visible (without it, positions snap to whole pixels).
    supersample: additionally render supersample x supersample times larger and average
      (slower; 1: off).
    """

    config_key: ClassVar[str] = "clips.camera"

    x_min: float = option(-0.13, doc="left edge of the view along the push axis (m)")
    x_max: float = option(1.15, doc="right edge of the view along the push axis (m)")
    height: int = option(32, doc="image height (px)", minimum=8)
    width: int = option(128, doc="image width (px)", minimum=8)
    multisample: int = option(4, doc="OpenGL multisample anti-aliasing samples (0: off)", minimum=0, maximum=16)
    supersample: int = option(
        1, doc="render this many times larger per side and average (1: off)", minimum=1, maximum=8
    )

    def __post_init__(self) -> None:
        if (
            not self.x_max > self.x_min
            or min(self.height, self.width) < 8
            or self.supersample < 1
            or self.multisample < 0
        ):
            raise ValueError(
                "camera needs x_max > x_min, an image of at least 8 x 8 pixels, supersample >= 1, multisample >= 0"
            )

    @property
    def metres_per_pixel(self) -> float:
        return (self.x_max - self.x_min) / self.width


@dataclass(frozen=True)
class PushRecording:
    """States of n pushes at T frames (the last at rest).

    box_qpos: (n, T, 7) free-joint position and quaternion (w, x, y, z) of the box.
    pusher_q: (n, T) slide of the pusher along +x from its start, metres.
    times: (n, T) simulation time of each frame, seconds (the last is the settle time).
    displacement, stop_time, ok: (n,) as in :class:`imply.sim.pushes.PushResult`.
    half_extents: (n, 3) box half-extents used.
    """

    box_qpos: np.ndarray
    pusher_q: np.ndarray
    times: np.ndarray
    displacement: np.ndarray
    stop_time: np.ndarray
    ok: np.ndarray
    half_extents: np.ndarray


def record_pushes(
    speeds: np.ndarray,
    masses: np.ndarray,
    frictions: np.ndarray,
    half_extents: np.ndarray,
    frame_times: list[float] | np.ndarray,
    *,
    scene: SceneConfig | None = None,
    nthread: int = 1,
    chunk: int = 10,
) -> PushRecording:
    """Simulate n pushes in one batch and record states at ``frame_times`` and at rest.

    The pushes are stepped exactly as :func:`imply.sim.pushes.simulate_pushes` steps
    them (:func:`imply.sim.pushes.run_pushes`), so a clip's last frame shows the same
    displacement the table holds for that push.

    Args:
      speeds, masses, frictions: (n,) push speed (m/s), box mass (kg), sliding friction.
      half_extents: (n, 3) box half-extents (m).
      frame_times: increasing times (s) of the frames before the final, at-rest one.
        A push that settles before a frame time shows its rest state in that frame.
      nthread: batch threads; results do not depend on it (each push is independent).
      chunk: substeps between checks for settled boxes while sliding.
    """
    speeds = np.asarray(speeds, dtype=float).ravel()
    n = speeds.size
    masses = np.broadcast_to(np.asarray(masses, dtype=float), (n,))
    frictions = np.broadcast_to(np.asarray(frictions, dtype=float), (n,))
    he = np.broadcast_to(np.asarray(half_extents, dtype=float), (n, 3)).copy()
    ft = np.asarray(frame_times, dtype=float)
    if ft.ndim != 1 or ft.size < 1 or np.any(np.diff(ft) <= 0) or ft[0] < 0:
        raise ValueError("frame_times must be increasing and non-negative")

    batch, per_sim = batch_with_geometry(n, he, masses, frictions, scene=scene, nthread=nthread)
    run = run_pushes(batch, per_sim[0], speeds, models=per_sim, frame_times=ft, chunk=chunk)
    return PushRecording(
        box_qpos=np.concatenate([run.frames_box_qpos, run.final_box_qpos[:, None]], axis=1),
        pusher_q=np.concatenate([run.frames_pusher, run.final_pusher[:, None]], axis=1),
        times=np.concatenate([run.frames_time, run.result.stop_time[:, None]], axis=1),
        displacement=run.result.displacement,
        stop_time=run.result.stop_time,
        ok=run.result.ok,
        half_extents=he,
    )


class ClipRenderer:
    """Draws recorded push states from the fixed camera; one instance per process.

    Usage: ``with ClipRenderer(scene, camera) as r: frames = r.render(rec, i)`` gives
    the (T, H, W, 3) uint8 frames of push ``i`` of a :class:`PushRecording`.
    """

    def __init__(self, scene: SceneConfig | None = None, camera: CameraConfig | None = None) -> None:
        self.scene = scene or SceneConfig()
        self.camera = camera or CameraConfig()
        cam = self.camera
        self.model = build_model(self.scene)
        extent_y = cam.metres_per_pixel * cam.height
        # the offscreen buffer must hold the image; fovy is the view's height in metres
        # for an orthographic camera
        ss = cam.supersample
        self.model.vis.global_.offwidth = max(int(self.model.vis.global_.offwidth), cam.width * ss)
        self.model.vis.global_.offheight = max(int(self.model.vis.global_.offheight), cam.height * ss)
        self.model.vis.global_.fovy = extent_y
        self.model.vis.quality.offsamples = cam.multisample
        self.data = mujoco.MjData(self.model)
        self._renderer = mujoco.Renderer(self.model, height=cam.height * ss, width=cam.width * ss)
        self._cam = mujoco.MjvCamera()
        self._cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        self._cam.orthographic = 1
        self._cam.lookat[:] = [(cam.x_min + cam.x_max) / 2, 0.0, 0.0]
        self._cam.distance = 2.0
        self._cam.azimuth = 90.0  # image right = +x
        self._cam.elevation = -90.0
        self._box_geom = self.model.geom("box").id
        self._pusher_geom = self.model.geom("pusher").id
        self._pusher_body = self.model.body("pusher").id
        self._box_q = int(self.model.jnt_qposadr[self.model.joint("box").id])
        self._push_q = int(self.model.jnt_qposadr[self.model.joint("push").id])
        self._pusher_half_x = float(self.model.geom_size[self._pusher_geom, 0])
        self._pusher_half_z = float(self.model.geom_size[self._pusher_geom, 2])

    def __enter__(self) -> ClipRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self._renderer.close()

    def set_object(self, half_extents: np.ndarray) -> None:
        """Give the render model this object's box size (and the pusher's matching place)."""
        hx, hy, hz = (float(x) for x in half_extents)
        self.model.geom_size[self._box_geom] = [hx, hy, hz]
        self.model.geom_rbound[self._box_geom] = float(np.sqrt(hx * hx + hy * hy + hz * hz))
        self.model.geom_size[self._pusher_geom, 1] = 0.8 * hy
        # as in scene.build_xml: the pusher face starts 0.1 mm behind the box, at its centre height
        self.model.body_pos[self._pusher_body] = [-hx - self._pusher_half_x - 1e-4, 0.0, hz]

    def render_state(self, box_qpos: np.ndarray, pusher_q: float) -> np.ndarray:
        """One (H, W, 3) uint8 frame of the box at ``box_qpos`` and the pusher at slide ``pusher_q``."""
        self.data.qpos[self._box_q : self._box_q + 7] = box_qpos
        self.data.qpos[self._push_q] = pusher_q
        mujoco.mj_kinematics(self.model, self.data)
        self._renderer.update_scene(self.data, camera=self._cam)
        img = self._renderer.render()
        ss = self.camera.supersample
        if ss == 1:
            return img.copy()
        h, w = self.camera.height, self.camera.width
        # mean of ss x ss samples, rounded to nearest (integer arithmetic: exact and fast)
        acc = img.reshape(h, ss, w, ss, 3).sum(axis=(1, 3), dtype=np.uint32)
        return ((acc + (ss * ss) // 2) // (ss * ss)).astype(np.uint8)

    def render(self, rec: PushRecording, i: int) -> np.ndarray:
        """The (T, H, W, 3) uint8 frames of push ``i`` of ``rec``."""
        self.set_object(rec.half_extents[i])
        return np.stack([self.render_state(rec.box_qpos[i, k], rec.pusher_q[i, k]) for k in range(rec.times.shape[1])])
