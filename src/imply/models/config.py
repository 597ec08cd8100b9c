"""Settings of the learned models: config sections ``model`` (the predictor, its training and scoring) and the ViT presets.

Torch-free on purpose: the workflow's config check builds these when Snakemake reads the
Snakefile, and the CLI takes its flags' defaults from them, neither of which should pay
for importing torch. The modules that use them (:mod:`imply.models.sequences`,
:mod:`imply.models.ac_predictor`, :mod:`imply.models.train`,
:mod:`imply.models.vision_transformer`) import them from here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from imply.options import Config, option

if TYPE_CHECKING:
    import pandas as pd


@dataclass(frozen=True, kw_only=True)
class ViTConfig(Config):
    """Architecture of :class:`imply.models.vision_transformer.VisionTransformer`."""

    config_key: ClassVar[str] = "encoder architecture"

    patch_size: int = option(16, doc="pixels per patch side", minimum=1)
    tubelet_size: int = option(2, doc="frames per tubelet", minimum=1)
    in_chans: int = option(3, doc="input channels", minimum=1)
    embed_dim: int = option(64, doc="token width", minimum=1)
    depth: int = option(4, doc="transformer blocks", minimum=1)
    num_heads: int = option(4, doc="attention heads", minimum=1)
    mlp_ratio: float = option(4.0, doc="MLP width / token width", exclusive_minimum=0)
    qkv_bias: bool = option(True, doc="bias in the fused qkv projection")

    def __post_init__(self) -> None:
        if self.embed_dim % self.num_heads:
            raise ValueError("embed_dim must be a multiple of num_heads")


PRESETS: dict[str, ViTConfig] = {
    "tiny": ViTConfig(embed_dim=64, depth=4, num_heads=4),
    "vit_large": ViTConfig(embed_dim=1024, depth=24, num_heads=16),
    "vit_huge": ViTConfig(embed_dim=1280, depth=32, num_heads=16),
    "vit_giant_xformers": ViTConfig(embed_dim=1408, depth=40, num_heads=22, mlp_ratio=48 / 11),
}


@dataclass(frozen=True, kw_only=True)
class PredictorPreset(Config):
    """A predictor size (config ``model.presets.<name>``): everything but what the features fix."""

    config_key: ClassVar[str] = "model.presets"

    width: int = option(64, doc="token width", minimum=8, required=True)
    depth: int = option(3, doc="transformer blocks", minimum=1, required=True)
    heads: int = option(4, doc="attention heads", minimum=1, required=True)
    mlp_ratio: float = option(4.0, doc="MLP width / token width", exclusive_minimum=0)
    rope_theta: float = option(10000.0, doc="base of the rotary position frequencies", exclusive_minimum=0)
    residual: bool = option(True, doc="predict each frame's change from the previous frame, not the frame")

    def predictor(self, *, embed_dim: int, grid: tuple[int, int], max_steps: int) -> PredictorConfig:
        """The full :class:`PredictorConfig` for features of width ``embed_dim`` on a ``grid`` of patches."""
        return PredictorConfig(embed_dim=embed_dim, grid=grid, max_steps=max_steps, **self.to_dict())


@dataclass(frozen=True, kw_only=True)
class PredictorConfig(PredictorPreset):
    """Shape of a predictor: a preset plus what the encoder's features and the sequence fix.

    ``embed_dim`` and ``grid`` come from the features, ``max_steps`` from the layout; built
    by :meth:`PredictorPreset.predictor`, and saved with every model.
    """

    config_key: ClassVar[str] = "predictor"

    embed_dim: int = option(doc="width of the encoder's tokens", minimum=1)
    grid: tuple[int, int] = option(doc="patch grid of the encoder's tokens (rows, columns)")
    action_dim: int = option(1, doc="action values per step", minimum=1)
    state_dim: int = option(1, doc="state values per step", minimum=1)
    max_steps: int = option(32, doc="time steps the positions cover", minimum=1)

    def __post_init__(self) -> None:
        if self.width % self.heads:
            raise ValueError(f"width {self.width} is not divisible by {self.heads} heads")

    @property
    def n_patches(self) -> int:
        return self.grid[0] * self.grid[1]

    @property
    def tokens_per_step(self) -> int:
        # one action token, one state token, then the patches
        return 2 + self.n_patches


@dataclass(frozen=True, kw_only=True)
class Layout(Config):
    """How a variant lays out its sequence (config ``model.variants.<name>``; see :mod:`imply.models.sequences`)."""

    config_key: ClassVar[str] = "model.variants"

    calib: bool = option(doc="the object's two calibration clips come first")
    calib_frames: tuple[int, ...] = option(
        (0, 3, 7), doc="frames of each calibration clip", min_items=1, items={"minimum": 0}
    )
    query_context: int = option(1, doc="query frames given as context (the rest are predicted)", minimum=1)
    n_frames: int = option(8, doc="frames of a clip", minimum=2)
    query_frames: tuple[int, ...] | None = option(
        (0, 1, 4, 7),
        doc="frames of the query clip, ending at the last (null: every frame)",
        min_items=2,
        unique=True,
        items={"minimum": 0},
    )
    rest_state: float = option(
        1.0, doc="state token of the clip's last frame (the study sets it once, as model.rest_state)"
    )

    def __post_init__(self) -> None:
        if self.query_context < 1 or self.n_frames < 2 or (self.calib and not self.calib_frames):
            raise ValueError("a layout needs query_context >= 1, n_frames >= 2 and, with calib, calib_frames")
        q = self.query_frame_indices
        if list(q) != sorted(set(q)) or q[0] < 0 or q[-1] != self.n_frames - 1:
            raise ValueError(
                f"query_frames {list(q)} must increase and end at the clip's last frame ({self.n_frames - 1})"
            )
        if self.query_context >= len(q):
            raise ValueError(f"query_context {self.query_context} leaves none of the {len(q)} query frames to predict")

    @property
    def query_frame_indices(self) -> tuple[int, ...]:
        """Frames of the query clip in the sequence, in order."""
        return tuple(range(self.n_frames)) if self.query_frames is None else tuple(self.query_frames)

    def without_calibration(self) -> Layout:
        """The same query steps with no calibration steps (the context-free condition)."""
        return Layout(
            calib=False,
            query_context=self.query_context,
            n_frames=self.n_frames,
            query_frames=self.query_frames,
            rest_state=self.rest_state,
        )

    def frame_states(self, meta: pd.DataFrame) -> np.ndarray:
        """(n_frames,) state of each frame index of the clips in ``meta`` (their metadata).

        Frames 0..T-2 are at the clip's nominal frame times (the same for every clip;
        the median of columns ``t0``.. where present, else evenly spaced); the last frame
        shows the box at rest, at a time that depends on the object, so it gets the
        constant ``rest_state`` instead: a state must not leak the outcome.
        """
        t = self.n_frames
        cols = [f"t{k}" for k in range(t - 1)]
        if all(c in meta.columns for c in cols):
            nominal = meta[cols].median(axis=0).to_numpy(dtype=float)
        else:
            nominal = np.arange(t - 1, dtype=float) / max(t - 1, 1)
        return np.append(nominal, self.rest_state)

    def teacher_forcing_weights(self, *, final_weight: float, calib_targets: bool) -> np.ndarray:
        """(n_steps - 1,) weight of each teacher-forcing target, step t + 1 predicted from steps <= t.

        The query's frames after its first are targets; with ``calib_targets`` so is every calibration frame
        that shows a push under way or done (not a clip's frame 0, the box before its push), so the second
        calibration push is predicted with the first in context: the same inference as the query's. A target
        weighs 1, and ``final_weight`` where it is a clip's last frame (the box at rest).
        """
        slots = [(j, f) for j in range(2) for f in self.calib_frames] if self.calib else []
        slots += [(2, f) for f in self.query_frame_indices]
        w = np.zeros(len(slots) - 1)
        for t in range(1, len(slots)):
            clip, frame = slots[t]
            query_target = clip == 2 and slots[t - 1][0] == 2
            if frame == 0 or not (query_target or (clip < 2 and calib_targets)):
                continue
            w[t - 1] = final_weight if frame == self.n_frames - 1 else 1.0
        return w

    @property
    def n_calib_steps(self) -> int:
        return 2 * len(self.calib_frames) if self.calib else 0

    @property
    def n_steps(self) -> int:
        return self.n_calib_steps + len(self.query_frame_indices)

    @property
    def n_context(self) -> int:
        return self.n_calib_steps + self.query_context


@dataclass(frozen=True, kw_only=True)
class TrainConfig(Config):
    """Config section ``model.train``: the optimiser, its schedule and the loss's rollout term."""

    config_key: ClassVar[str] = "model.train"

    epochs: int = option(
        40,
        doc="passes over the training sequences (40: the calibrated models of 4 data-order seeds under 2 roundings "
        "learned to use their calibration by epoch 22; benchmarks/s5_robustness.py)",
        minimum=1,
    )
    context_free_epochs: int | None = option(
        15,
        doc="epochs of a variant without calibration (null: epochs). Such a model learns the object-blind answer, "
        "which has no threshold to cross (15: every Section 5 target and claim held or failed in the same 8 validation "
        "runs as with 40; docs/notes/section5-recipe.md)",
        minimum=1,
    )
    batch_size: int = option(16, doc="sequences per step", minimum=1)
    lr: float = option(2.0e-3, doc="peak learning rate", exclusive_minimum=0)
    start_lr: float = option(1.0e-4, doc="learning rate at the first warmup step", minimum=0)
    final_lr: float = option(1.0e-5, doc="learning rate at the end of the anneal", minimum=0)
    warmup: float = option(0.05, doc="share of the steps spent warming up", minimum=0, maximum=1)
    anneal: float = option(0.3, doc="share of the steps spent annealing (linearly, at the end)", minimum=0, maximum=1)
    weight_decay: float = option(0.04, doc="AdamW weight decay", minimum=0)
    beta1: float = option(0.9, doc="AdamW beta1", minimum=0, exclusive_maximum=1)
    beta2: float = option(0.999, doc="AdamW beta2", minimum=0, exclusive_maximum=1)
    grad_clip: float = option(1.0, doc="gradient norm clip (0: none)", minimum=0)
    rollout_weight: float = option(1.0, doc="weight of the rollout loss beside the teacher-forcing loss", minimum=0)
    rollout_steps: int = option(2, doc="steps of the loss's auto-regressive rollout", minimum=0)
    final_weight: float = option(
        10.0, doc="weight of the last query frame (the box at rest) in both losses", exclusive_minimum=0
    )
    every_push_as_query: bool = option(False, doc="also train on the calibration pushes as queries")
    calib_targets: bool = option(
        True,
        doc="teacher forcing also predicts each calibration clip's later frames (the second push's rest frame with "
        "the first push in context), not only the query's",
    )
    init_seed: int = option(0, doc="seed of the predictor's initial weights", minimum=0)
    validate_every: int = option(
        10,
        doc="epochs between validations (the first and the last are always validated; validation changes no "
        "weight, only what the history records)",
        minimum=1,
    )

    def for_layout(self, layout: Layout) -> TrainConfig:
        """The recipe one variant trains with: ``context_free_epochs`` (when set) replaces ``epochs`` for a layout
        without calibration, and is dropped from the result, so the recipe a model records is the one it ran."""
        if layout.calib or self.context_free_epochs is None:
            return self.replace(context_free_epochs=None)
        return self.replace(epochs=self.context_free_epochs, context_free_epochs=None)


@dataclass(frozen=True, kw_only=True)
class ModelResources(Config):
    """Config ``model.resources``: what the Section 5 rules ask for (threads, memory, runtime, GPUs): the one place for them."""

    config_key: ClassVar[str] = "model.resources"

    gpu: int = option(
        0, doc="GPUs per model job (encoder_encode asks for one unless encoder.kind is cpu)", minimum=0, required=True
    )
    encode_threads: int = option(1, doc="CPU threads of encoder_encode", minimum=1, required=True)
    encode_mem_mb: int = option(8000, doc="memory of encoder_encode (MB)", minimum=100, required=True)
    encode_runtime: int = option(60, doc="minutes of encoder_encode", minimum=1, required=True)
    train_threads: int = option(
        1, doc="torch threads per training run (two small runs side by side beat one with 2)", minimum=1, required=True
    )
    train_mem_mb: int = option(4000, doc="memory of a training job (MB)", minimum=100, required=True)
    train_runtime: int = option(30, doc="minutes of a training job", minimum=1, required=True)
    rollout_threads: int = option(1, doc="CPU threads of a rollout job", minimum=1, required=True)
    rollout_mem_mb: int = option(4000, doc="memory of a rollout job (MB)", minimum=100, required=True)
    rollout_runtime: int = option(15, doc="minutes of a rollout job", minimum=1, required=True)


def _study_presets() -> dict[str, PredictorPreset]:
    return {
        "tiny": PredictorPreset(),
        "vitg-300m": PredictorPreset(width=1024, depth=24, heads=16),
    }


@dataclass(frozen=True, kw_only=True)
class ModelVariants(Config):
    """Config ``model.variants``: the sequence layout of the context-free and the calibrated model."""

    config_key: ClassVar[str] = "model.variants"

    nocalib: Layout = option(
        Layout(calib=False, query_frames=(0, 4, 7)), doc="the context-free model's layout", required=True
    )
    calib: Layout = option(
        Layout(calib=True, calib_frames=(7,), query_frames=(0, 4, 7)),
        doc="the calibrated model's layout",
        required=True,
    )


@dataclass(frozen=True, kw_only=True)
class ModelConfig(Config):
    """Config section ``model``: the action-conditioned predictor, its training, rollouts and Section 5 scoring."""

    config_key: ClassVar[str] = "model"

    preset: str = option("tiny", doc="the predictor size, one of presets", required=True)
    presets: dict[str, PredictorPreset] = option(_study_presets(), doc="predictor sizes by name", required=True)
    token_grid: tuple[int, int] | None = option(
        (1, 8),
        doc="the encoder's patch tokens average-pooled to this grid (null: keep)",
        required=True,
        items={"minimum": 1},
    )
    variants: ModelVariants = option(ModelVariants(), doc="sequence layout of each variant", required=True)
    seeds: tuple[int, ...] = option(
        (0, 1),
        doc="data-order seeds (the second is the replication)",
        required=True,
        min_items=1,
        unique=True,
        items={"minimum": 0},
    )
    rest_state: float = option(1.0, doc="state token of the last frame (box at rest)", required=True)
    train: TrainConfig = option(TrainConfig(), doc="training (imply.models.config.TrainConfig)", required=True)
    rollout_batch: int = option(100, doc="objects rolled out per call of imply evaluate", minimum=1, required=True)
    derangement_seed: int = option(
        11, doc="which object's calibration each object gets in the swap condition", minimum=0, required=True
    )
    selection_seed: int = option(12, doc="the random-candidate selection rule of Section 5", minimum=0, required=True)
    device: str = option("cpu", doc="torch device for training and rollouts", required=True)
    resources: ModelResources = option(ModelResources(), doc="scheduler resources of its jobs", required=True)


@dataclass(frozen=True, kw_only=True)
class PixelVideoConfig(Config):
    """Config section ``pixel.recipe``: the network's size and its training recipe (both variants)."""

    config_key: ClassVar[str] = "pixel.recipe"

    width: int = option(32, doc="conv channels and MLP width", minimum=1)
    latent: int = option(4, doc="size of the latent z drawn once per sample set", minimum=1)
    frames: tuple[int, ...] = option(
        (1, 4, 7),
        doc="clip frame indices generated after the first (the last: at rest)",
        min_items=1,
        items={"minimum": 1},
    )
    keypoint_sd: float = option(0.1, doc="sd of the keypoints' log slide in the ELBO's likelihood", exclusive_minimum=0)
    pixel_weight: float = option(100.0, doc="weight of the pixel error beside the ELBO's nats per push", minimum=0)
    pixels_move_box: bool = option(True, doc="false: the pixel error fits the mask and table only, not the slides")
    profile_weight: float = option(30.0, doc="weight of the column-profile error within the pixel error", minimum=0)
    epochs: int = option(20, doc="passes over the training objects", minimum=1)
    batch_size: int = option(32, doc="objects per step", minimum=1)
    lr: float = option(2e-3, doc="peak learning rate (one-cycle)", exclusive_minimum=0)
    seed: int = option(0, doc="initialisation and data order", minimum=0)
