"""The frozen evaluation suite: what every world model is shown, and the sealed truth it is scored on.

TODO(helper S): module docstring with the on-disk layout (manifest.json, suite.npz,
truth.npz, table.npz), build/write/load.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from imply.evaluate.config import CONDITIONS  # noqa: F401 (re-exported: the conditions a suite serves)

SUITE_FORMAT = "imply-suite"
SUITE_VERSION = 1


class SuiteError(ValueError):
    """A suite that cannot be used: missing files, another format or version, a broken checksum."""


@dataclass(frozen=True, eq=False)
class Suite:
    """What a model may see, for N held-out objects, K query speeds and M + M_c real readout clips.

    object_ids: (N,) str.
    partner: (N,) int64; the object whose calibration is shown in condition ``other``
      (never the object itself).
    calibration_speeds: (2,) m/s. calibration_frames: uint8 (N, 2, T, H, W, 3), the full
      calibration clips (frame_times, then the rest frame). calibration_displacement: (N, 2)
      observed slide of each calibration push, metres.
    query_speeds: (K,) m/s. context_frames: uint8 (N, K, C, H, W, 3), the first C frames
      of each query push (C = ``context_frames`` of the config; frame 0 shows the box before
      the push).
    frame_times: (T - 1,) nominal frame times (s); the T-th frame shows the box at rest.
    train_frames: uint8 (M, 2, H, W, 3), first and rest frame of real training clips;
      train_speed, train_displacement: (M,) their commanded speed and true slide (public:
      readouts are fitted on them).
    check_frames: uint8 (M_c, 2, H, W, 3), first and rest frame of real clips of other
      training objects, on which a readout's R^2 is measured (their slides are sealed).
    metres_per_pixel: the camera's scale. manifest: the parsed manifest.json.
    """

    path: Path
    manifest: dict[str, Any]
    object_ids: np.ndarray
    partner: np.ndarray
    calibration_speeds: np.ndarray
    calibration_frames: np.ndarray
    calibration_displacement: np.ndarray
    query_speeds: np.ndarray
    context_frames: np.ndarray
    frame_times: np.ndarray
    train_frames: np.ndarray
    train_speed: np.ndarray
    train_displacement: np.ndarray
    check_frames: np.ndarray
    metres_per_pixel: float

    @property
    def n_objects(self) -> int:
        return len(self.object_ids)

    @property
    def n_speeds(self) -> int:
        return len(self.query_speeds)

    @property
    def frame_shape(self) -> tuple[int, int, int]:
        """(H, W, 3)."""
        return tuple(self.context_frames.shape[-3:])

    @property
    def checksum(self) -> str:
        """The sha256 of suite.npz as the manifest records it: names this suite in reports and caches."""
        return str(self.manifest["files"]["suite.npz"])


@dataclass(frozen=True, eq=False)
class SuiteTruth:
    """The sealed answers (truth.npz), read only when scoring.

    displacement: (N, K) true slide of each query push, metres. mass, friction: (N,).
    half_extents: (N, 3) metres. rest_frames: uint8 (N, K, H, W, 3), each query push's true
    rest frame. check_displacement: (M_c,) true slide of each check clip.
    """

    displacement: np.ndarray
    mass: np.ndarray
    friction: np.ndarray
    half_extents: np.ndarray
    rest_frames: np.ndarray
    check_displacement: np.ndarray


def load_suite(path):  # placeholder until the suite branch lands
    raise NotImplementedError


def load_truth(suite):
    raise NotImplementedError


def suite_table_path(suite):
    raise NotImplementedError
