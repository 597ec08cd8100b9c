"""Predictor input sequences built from cached encoder features and clip metadata.

A *sequence* is a list of (clip, frame) steps with an action and a state per step:

* ``nocalib`` layout: the query clip's ``query_frames`` (default all 8; the config
  takes 0, 1, 4, 7: two frames of the push, one of the slide, the box at rest); the
  first ``query_context`` are context (the config: 1, the box before the push; a
  second frame already shows the box sliding), the rest are predicted.
* ``calib`` layout: ``calib_frames`` (3 frames, default 0, 3, 7) of each of the
  object's 2 calibration clips, then the query frames (T = 6 + 4 = 10); context is
  the 6 calibration steps and the query's first ``query_context`` frames.

The last query frame must be the clip's last (the box at rest): that is the frame the
latent readout reads.

The action of a step is its push's commanded speed (m/s); the state is the frame's
nominal time divided by the layout's ``rest_state`` (:meth:`Layout.frame_states`; see
:mod:`imply.models.ac_predictor`).
Steps are gathered lazily from the float16 feature array, so a training set costs
its feature file and a few index arrays in memory.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from imply.models.ac_predictor import normalise_tokens
from imply.models.config import Layout
from imply.models.features import FeatureSplit


@dataclass
class Sequences:
    """N sequences of T steps over one feature array.

    features: (n_clips, n_frames, P, D) float16/float32 encoder tokens.
    clip, frame: (N, T) int indices into features; action, state: (N, T) float.
    """

    features: np.ndarray
    clip: np.ndarray
    frame: np.ndarray
    action: np.ndarray
    state: np.ndarray
    n_context: int

    def __len__(self) -> int:
        return self.clip.shape[0]

    @property
    def n_steps(self) -> int:
        return self.clip.shape[1]

    def batch(self, idx: np.ndarray) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(frames (B, T, P, D) normalised, actions (B, T, 1), states (B, T, 1))."""
        feats = torch.from_numpy(np.asarray(self.features[self.clip[idx], self.frame[idx]], dtype=np.float32))
        frames = normalise_tokens(feats)
        actions = torch.from_numpy(self.action[idx].astype(np.float32))[..., None]
        states = torch.from_numpy(self.state[idx].astype(np.float32))[..., None]
        return frames, actions, states


def build_sequences(
    split: FeatureSplit, layout: Layout, *, query_clip: np.ndarray, calib_clips: np.ndarray | None
) -> Sequences:
    """Sequences of ``split``'s clips for N queries.

    query_clip: (N,) clip index of each query push; calib_clips: (N, 2) clip indices
    of the calibration pushes placed in context (any object's: the swap condition
    passes another object's), required when ``layout.calib``. The action of a step is
    its clip's commanded speed (metadata ``speed``), its state from
    :meth:`Layout.frame_states`.
    """
    features = split.tokens
    n_frames = features.shape[1]
    if n_frames != layout.n_frames:
        raise ValueError(f"features have {n_frames} frames per clip, the layout expects {layout.n_frames}")
    if layout.calib_frames and max(layout.calib_frames) >= n_frames:
        raise ValueError(f"calibration frame {max(layout.calib_frames)} is out of range (clips have {n_frames})")
    query_clip = np.asarray(query_clip, dtype=np.int64)
    n = query_clip.shape[0]
    clips, frames = [], []
    if layout.calib:
        if calib_clips is None:
            raise ValueError("the calibrated layout needs calibration clips")
        calib_clips = np.asarray(calib_clips, dtype=np.int64).reshape(n, 2)
        for j in range(2):
            for f in layout.calib_frames:
                clips.append(calib_clips[:, j])
                frames.append(np.full(n, f))
    for f in layout.query_frame_indices:
        clips.append(query_clip)
        frames.append(np.full(n, f))
    clip = np.stack(clips, axis=1)
    frame = np.stack(frames, axis=1)
    speed = np.asarray(split.meta["speed"].to_numpy(), dtype=np.float64)
    state = np.asarray(np.broadcast_to(layout.frame_states(split.meta), (len(split.meta), n_frames)), dtype=np.float64)
    rel_state = state / np.maximum(state[:, -1:], 1e-9)  # the last frame's state is 1
    return Sequences(
        features=features,
        clip=clip,
        frame=frame,
        action=speed[clip],
        state=rel_state[clip, frame],
        n_context=layout.n_context,
    )
