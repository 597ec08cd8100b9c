"""Section 4's stand-in world models as frames-kind models of :mod:`imply.evaluate.interface`.

Known answers for ``imply evaluate``: each stand-in draws the rest frame of every query
push with the project's renderer (:class:`imply.sim.render.ClipRenderer`, the suite's
camera), the box of the object's own size (a model sees it in the context frame) placed
where the stand-in believes it stops:

* ``oracle`` -- at the true slide (it reads the suite's sealed truth: it is the world);
* ``jitter`` -- at the slide of a perturbed object: per rollout, mass and friction drawn
  log-normally around the truth (``JITTER_SD``, as Section 4's jitter stand-in) and read
  off the push table; a model with no stable object in its head;
* ``blind`` -- at the slide typical of the suite's training pushes at that speed
  (:class:`imply.models.object_blind.TypicalSlide`), whatever the object;
* ``collapse`` -- nowhere: the rest frame is the context frame, nothing moved.

Run them with ``imply evaluate --model imply.evaluate.standins:oracle --suite DIR -o OUT``
(likewise ``:jitter``, ``:blind``, ``:collapse``). They ignore the calibration they are
shown, so their own- and other-calibration rollouts differ only by the jitter's draws.
"""

from __future__ import annotations

import zlib

import numpy as np

from imply.evaluate.interface import RolloutRequest
from imply.evaluate.suite import Suite, load_truth, suite_table_path
from imply.models.object_blind import fit_typical_slide
from imply.table import PushTable

JITTER_SD = 0.25  # log sd of the jitter's mass and friction, as the study's section4.standins.jitter_sd
JITTER_SEED = 7


class RestFrameModel:
    """Base of the stand-ins: renders each rollout's rest frame with the box moved by :meth:`slides`."""

    kind = "frames"
    batch_size = 64
    name = "stand-in"

    def __init__(self, suite: Suite) -> None:
        from imply.sim.render import CameraConfig, ClipRenderer
        from imply.sim.scene import SceneConfig

        self.suite = suite
        self.truth = load_truth(suite)
        self.index = {str(o): i for i, o in enumerate(suite.object_ids)}
        scene = SceneConfig.from_dict(suite.manifest["config"]["scene"])
        camera = CameraConfig.from_dict(suite.manifest["camera"])
        self._renderer = ClipRenderer(scene, camera)
        self._stroke = scene.stroke

    def objects(self, request: RolloutRequest) -> np.ndarray:
        return np.array([self.index[o] for o in request.object_ids])

    def slides(self, request: RolloutRequest, objects: np.ndarray) -> np.ndarray:
        """(B, K) metres: where the box stops."""
        raise NotImplementedError

    def rollout(self, request: RolloutRequest) -> np.ndarray:
        objects = self.objects(request)
        slides = self.slides(request, objects)
        b, k = slides.shape
        h, w, _ = self.suite.frame_shape
        out = np.empty((b, k, 1, h, w, 3), dtype=np.uint8)
        for i, n in enumerate(objects):
            he = self.truth.half_extents[n]
            self._renderer.set_object(he)
            for j in range(k):
                qpos = np.array([slides[i, j], 0.0, he[2], 1.0, 0.0, 0.0, 0.0])
                out[i, j, 0] = self._renderer.render_state(qpos, self._stroke)
        return out


class Oracle(RestFrameModel):
    name = "oracle"

    def slides(self, request: RolloutRequest, objects: np.ndarray) -> np.ndarray:
        return self.truth.displacement[objects]


class ObjectBlind(RestFrameModel):
    name = "object-blind"

    def __init__(self, suite: Suite) -> None:
        super().__init__(suite)
        self._typical = fit_typical_slide(suite.train_speed, suite.train_displacement)

    def slides(self, request: RolloutRequest, objects: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self._typical.slide(request.query_speeds), (len(objects), len(request.query_speeds)))


class Jitter(RestFrameModel):
    name = "jitter"

    def __init__(self, suite: Suite, *, sd: float = JITTER_SD, seed: int = JITTER_SEED) -> None:
        super().__init__(suite)
        self._table = PushTable.load(suite_table_path(suite))
        self._sd = sd
        self._seed = seed

    def slides(self, request: RolloutRequest, objects: np.ndarray) -> np.ndarray:
        k = len(request.query_speeds)
        cond = zlib.crc32(request.condition.encode())
        # one stream per (object, condition, sample): the same request gives the same rollouts
        z = np.stack(
            [np.random.default_rng([self._seed, int(n), cond, request.sample]).standard_normal((2, k)) for n in objects]
        )
        mass = np.clip(self.truth.mass[objects, None] * np.exp(self._sd * z[:, 0]), *self._table.mass_range)
        friction = np.clip(self.truth.friction[objects, None] * np.exp(self._sd * z[:, 1]), *self._table.friction_range)
        speeds = np.broadcast_to(request.query_speeds, mass.shape)
        return np.exp(self._table.log_displacement(speeds, mass, friction))


class Collapse:
    """Nothing moves: the rest frame is the query's first context frame."""

    kind = "frames"
    batch_size = 256
    name = "collapse"

    def rollout(self, request: RolloutRequest) -> np.ndarray:
        return request.context_frames[:, :, :1].copy()


def oracle(suite: Suite) -> Oracle:
    return Oracle(suite)


def jitter(suite: Suite) -> Jitter:
    return Jitter(suite)


def blind(suite: Suite) -> ObjectBlind:
    return ObjectBlind(suite)


def collapse(suite: Suite | None = None) -> Collapse:
    return Collapse()


STANDINS = {"oracle": oracle, "jitter": jitter, "blind": blind, "collapse": collapse}
