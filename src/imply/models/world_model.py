"""The trained action-conditioned predictor as a world model that ``imply evaluate`` can run.

:class:`PredictorWorldModel` wraps a trained :class:`~imply.models.ac_predictor.ACPredictor`
and the frozen encoder it was trained on, with the interface of
:mod:`imply.evaluate.interface` (kind ``latents``):

* ``encode(frames)``: the encoder's patch tokens of each frame, pooled to the token grid
  the predictor was trained on and layer-normed, (N, P, D): the space the predictor
  predicts in, and the space the evaluation's readout is fitted in (on real clips);
* ``rollout(request)``: for each object and query speed, the sequence of the model's
  layout (:mod:`imply.models.sequences`) is built from the request's frames: the
  calibration clips' ``calib_frames`` (own or another object's, as the request shows
  them; none in condition ``none``, where a calibrated model sees the shorter sequence,
  as in :func:`imply.models.rollout.rollout_split`), then the query's first
  ``query_context`` frames. The rest is rolled out with the one rollout loop
  (:func:`imply.models.rollout.rollout`); the predicted tokens of the last frame (the box
  at rest) are returned, (B, K, P, D).

Actions are commanded speeds, states the frame times over the layout's ``rest_state``
(the rest frame's state is 1), as in training. Rollouts are deterministic.

:func:`trained_predictor` is the factory ``imply evaluate`` names::

    imply evaluate --model imply.models.world_model:trained_predictor,checkpoint=results/model/calib/seed0/model.pt,encoder=results/encoder/encoder.pt ...
"""

from __future__ import annotations

import os

import numpy as np
import torch

from imply.models.ac_predictor import ACPredictor, normalise_tokens
from imply.models.config import Layout
from imply.models.encoder import EncoderConfig, FrameEncoder, load_encoder
from imply.models.features import pool_tokens
from imply.models.rollout import rollout
from imply.models.train import load_model


class PredictorWorldModel:
    """A trained predictor and its frozen encoder behind the ``imply evaluate`` interface (module docstring)."""

    kind = "latents"
    stochastic = False

    def __init__(
        self,
        predictor: ACPredictor,
        layout: Layout,
        encoder: FrameEncoder,
        *,
        token_grid: tuple[int, int],
        name: str = "predictor",
        batch_size: int = 100,
    ) -> None:
        self.predictor = predictor.eval()
        self.layout = layout
        self.encoder = encoder
        self.token_grid = (int(token_grid[0]), int(token_grid[1]))
        self.name = name
        self.batch_size = int(batch_size)

    @torch.no_grad()
    def encode(self, frames: np.ndarray) -> np.ndarray:
        """uint8 (N, H, W, 3) -> float32 (N, P, D): pooled, layer-normed encoder tokens."""
        tokens = self.encoder.encode(frames).numpy()
        if self.token_grid != tuple(self.encoder.grid):
            tokens = pool_tokens(tokens[:, None], self.encoder.grid, self.token_grid)[:, 0]
        return normalise_tokens(torch.from_numpy(np.ascontiguousarray(tokens, dtype=np.float32))).numpy()

    def _encode_frames(self, frames: np.ndarray) -> np.ndarray:
        """uint8 (..., H, W, 3) -> (..., P, D)."""
        flat = self.encode(frames.reshape(-1, *frames.shape[-3:]))
        return flat.reshape(*frames.shape[:-3], *flat.shape[1:])

    def _states(self, frame_times: np.ndarray) -> np.ndarray:
        """(n_frames,) state of each frame index: nominal time over the rest state; the rest frame's is 1."""
        times = np.asarray(frame_times, dtype=float)
        if times.shape != (self.layout.n_frames - 1,):
            raise ValueError(
                f"the model was trained on clips of {self.layout.n_frames} frames; the request has "
                f"{times.shape[0] + 1} (frame_times {times.tolist()})"
            )
        state = np.append(times, self.layout.rest_state)
        return state / max(state[-1], 1e-9)

    @torch.no_grad()
    def rollout(self, request) -> np.ndarray:
        """Predicted rest-frame tokens (B, K, P, D) of the request's pushes (module docstring)."""
        layout = self.layout
        calibrated = layout.calib and request.calibration_frames is not None
        run_layout = layout if calibrated else layout.without_calibration()
        b, k, n_ctx_given = request.context_frames.shape[:3]
        if n_ctx_given < layout.query_context:
            raise ValueError(
                f"the model needs the first {layout.query_context} frames of each query push; "
                f"the request shows {n_ctx_given}"
            )
        state = self._states(request.frame_times)
        speeds = np.asarray(request.query_speeds, dtype=np.float32)
        query = self._encode_frames(request.context_frames[:, :, : layout.query_context])  # (B, K, c, P, D)
        p, d = query.shape[-2:]
        steps: list[torch.Tensor] = []
        actions: list[np.ndarray] = []
        states: list[np.ndarray] = []
        if calibrated:
            cf = list(layout.calib_frames)
            calib = self._encode_frames(request.calibration_frames[:, :, cf])  # (B, 2, F, P, D)
            for j in range(2):
                for i, f in enumerate(cf):
                    steps.append(torch.from_numpy(np.repeat(calib[:, j, i][:, None], k, axis=1)))
                    actions.append(np.full((b, k), float(request.calibration_speeds[j]), np.float32))
                    states.append(np.full((b, k), state[f], np.float32))
        qf = run_layout.query_frame_indices
        for i, f in enumerate(qf):
            # frames after the context are placeholders: the rollout predicts them
            tok = query[:, :, i] if i < layout.query_context else np.zeros((b, k, p, d), np.float32)
            steps.append(torch.from_numpy(np.ascontiguousarray(tok)))
            actions.append(np.broadcast_to(speeds[None, :], (b, k)).astype(np.float32))
            states.append(np.full((b, k), state[f], np.float32))
        frames = torch.stack(steps, dim=2).reshape(b * k, len(steps), p, d).float()
        act = torch.from_numpy(np.stack(actions, axis=2).reshape(b * k, len(steps), 1))
        st = torch.from_numpy(np.stack(states, axis=2).reshape(b * k, len(steps), 1))
        rolled = rollout(self.predictor, frames, act, st, n_context=run_layout.n_context)
        return rolled[:, -1].numpy().reshape(b, k, p, d)


def trained_predictor(
    *,
    checkpoint: str | os.PathLike,
    encoder: str | os.PathLike,
    encoder_kind: str = "cpu",
    name: str | None = None,
    batch_size: int | str = 100,
) -> PredictorWorldModel:
    """The predictor trained by ``imply study model train`` (``checkpoint``) with its frozen encoder.

    ``encoder``: the CPU default's weights (``results/encoder/encoder.pt``) or, with
    ``encoder_kind`` ``vjepa2_hf`` / ``vjepa2_pt``, released V-JEPA 2 weights. ``name``
    defaults to the checkpoint's folder names (e.g. ``calib_seed0``).
    """
    predictor, layout, payload = load_model(checkpoint)
    enc = load_encoder(EncoderConfig(kind=encoder_kind, device="cpu"), encoder)
    grid = tuple(payload.get("token_grid") or enc.grid)
    if name is None:
        parts = os.path.normpath(str(checkpoint)).split(os.sep)
        name = "_".join(parts[-3:-1]) if len(parts) >= 3 else "predictor"
    return PredictorWorldModel(predictor, layout, enc, token_grid=grid, name=name, batch_size=int(batch_size))
