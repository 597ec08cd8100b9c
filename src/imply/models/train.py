"""Fine-tuning the action-conditioned predictor on cached encoder features.

Objective (as V-JEPA 2-AC's): an L1 loss on layer-normed encoder tokens, the sum of

* a teacher-forcing term: every query frame after the first predicted from the true
  frames, actions and states before it (one pass, thanks to the block-causal mask), and
  with ``calib_targets`` every calibration frame that shows a push under way or done, so
  the second calibration push is predicted with the first in context
  (:meth:`imply.models.config.Layout.teacher_forcing_weights`);
* a rollout term: from the context (calibration steps, if any, and the query's first
  ``query_context`` frames) the model rolls out auto-regressively, feeding its own
  predictions back, for ``rollout_steps`` steps (:func:`imply.models.rollout.rollout`,
  the loop every rollout runs); each predicted frame is compared with the true one.
  The gradient flows through the whole rollout.

In both terms the last query frame (the box at rest, the frame the readout reads) is
weighted ``final_weight`` times the other frames: it is the only frame whose content
depends on the object's friction over the whole slide, and a plain mean over frames
lets the easy frames (the push, the pusher) dominate the loss.

With ``every_push_as_query`` each training object gives three examples, each of its
pushes predicted with the other two in context (calibration pushes are ordinary pushes
at fixed speeds), which triples the examples of inferring an object from two pushes.

Validation: a ``validate`` function of the model, when given, runs after the first epoch,
every ``validate_every`` epochs and the last, and its numbers join the epoch's history (the study passes Section 5's validation on the
validation objects, :mod:`imply.study.section5.validation`; a model does not know what
validates it).

Optimiser: AdamW; learning rate warms up linearly from ``start_lr`` to ``lr`` over the
first ``warmup`` fraction of steps, stays constant, and anneals linearly to
``final_lr`` over the last ``anneal`` fraction; gradients clipped at ``grad_clip``.

Determinism: the initial weights come from ``init_seed`` (the same for every data
seed, as fine-tuning starts from one checkpoint) and the order of examples in epoch e
from ``numpy.random.default_rng([data_seed, e])``; no dropout, so nothing else is
random. A checkpoint (weights, optimiser state, step, per-epoch losses, and a digest
of everything that defines the run) is written atomically after every epoch; a run
that finds a checkpoint with the same digest resumes after its last epoch and ends
with the same weights as an uninterrupted run (same thread count).
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import math
import os
import pickle
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from imply.io import atomic_path
from imply.models.ac_predictor import ACPredictor
from imply.models.config import Layout, PredictorConfig, PredictorPreset, TrainConfig
from imply.models.examples import training_objects, training_sequences
from imply.models.features import FeatureSplit
from imply.models.rollout import rollout
from imply.models.sequences import Sequences

log = logging.getLogger("imply.models.train")


class PhaseClock:
    """Wall seconds spent in each named phase of a loop (``with clock("forward"): ...``), summed over the run."""

    def __init__(self, names: tuple[str, ...]):
        self.seconds = dict.fromkeys(names, 0.0)
        self._phase: str | None = None

    def __call__(self, name: str) -> PhaseClock:
        self._phase = name
        return self

    def __enter__(self) -> None:
        self._start = time.perf_counter()

    def __exit__(self, *exc) -> None:
        self.seconds[self._phase] += time.perf_counter() - self._start

    def summary(self) -> str:
        """Each phase's seconds and share of the total, one line."""
        total = sum(self.seconds.values()) or 1.0
        return ", ".join(f"{k} {v:.1f} s ({v / total:.0%})" for k, v in self.seconds.items())


def lr_at(step: int, total: int, cfg: TrainConfig) -> float:
    """Warmup, constant, linear anneal (step counts from 0)."""

    warm = max(1, int(round(cfg.warmup * total))) if cfg.warmup > 0 else 0
    anneal = int(round(cfg.anneal * total))
    if step < warm:
        return cfg.start_lr + (cfg.lr - cfg.start_lr) * (step + 1) / warm
    start_anneal = total - anneal
    if anneal > 0 and step >= start_anneal:
        frac = (step - start_anneal + 1) / anneal
        return cfg.lr + (cfg.final_lr - cfg.lr) * min(frac, 1.0)
    return cfg.lr


def _weighted_l1(pred: torch.Tensor, target: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """Mean L1 over (B, S, P, D), step s weighted ``weights[s]`` (S,)."""
    per_step = (pred - target).abs().mean(dim=(0, 2, 3))
    return (per_step * weights).sum() / weights.sum()


def losses(
    model: ACPredictor,
    frames: torch.Tensor,
    actions: torch.Tensor,
    states: torch.Tensor,
    *,
    n_context: int,
    tf_weights: torch.Tensor,
    cfg: TrainConfig,
) -> tuple[torch.Tensor, torch.Tensor]:
    """(teacher-forcing L1, rollout L1) for one batch; ``tf_weights`` (T - 1,) weighs each teacher-forcing target
    (:meth:`imply.models.config.Layout.teacher_forcing_weights`).

    The teacher-forcing pass also yields the keys and values of the true context, so
    the rollout (:func:`imply.models.rollout.rollout`) continues from them: its first
    step is the teacher-forcing prediction from the context, and each later step runs
    only its own tokens (gradients flow through the fed-back predictions).
    """
    tf_pass = model.run(frames, actions, states)
    tf = _weighted_l1(tf_pass[0][:, :-1], frames[:, 1:], tf_weights)
    t = frames.shape[1]
    steps = min(cfg.rollout_steps, t - n_context)
    if cfg.rollout_weight == 0 or steps <= 0:
        return tf, torch.zeros((), device=frames.device)
    rolled = rollout(model, frames, actions, states, n_context=n_context, steps=steps, context_pass=tf_pass)
    target = frames[:, n_context : n_context + steps]
    ar_weights = torch.ones(steps, device=frames.device)
    if n_context + steps == t:  # the rollout reaches the box at rest
        ar_weights[-1] = cfg.final_weight
    ar = _weighted_l1(rolled, target, ar_weights)
    return tf, ar


def run_digest(
    *, predictor: PredictorConfig, config: TrainConfig, layout: Layout, data_seed: int, data_key: str
) -> str:
    """What defines a training run, hashed: a checkpoint is resumed only by the run with the same digest."""
    blob = json.dumps(
        {
            "predictor": predictor.to_dict(),
            "train": config.to_dict(),
            "layout": layout.to_dict(),
            "seed": data_seed,
            "data": data_key,
        },
        sort_keys=True,
    )
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _plain(obj):
    """``obj`` with numpy scalars as Python numbers (tensors and plain types only: loadable with weights_only)."""
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return type(obj)(_plain(v) for v in obj)
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _save(path: Path, obj: dict) -> None:
    buf = io.BytesIO()
    torch.save(_plain(obj), buf)
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.getvalue())


def _load(path: str | os.PathLike, *, map_location: str) -> dict:
    """A model or checkpoint file, read as tensors and plain types only: a file whose pickle would build any other
    object (and so could run code) is refused (ValueError naming it)."""
    try:
        return torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(
            f"{path}: not a plain model file (it would build other objects than tensors when read, "
            f"so it is not loaded): {first}"
        ) from None


def train(
    seqs: Sequences,
    *,
    layout: Layout,
    predictor: PredictorConfig,
    config: TrainConfig,
    data_seed: int,
    out: str | os.PathLike,
    checkpoint: str | os.PathLike,
    data_key: str = "",
    stop_after_epoch: int | None = None,
    device: str = "cpu",
    validate: Callable[[ACPredictor], dict[str, float]] | None = None,
    extra: dict | None = None,
) -> dict | None:
    """Train (or resume) and write the final model to ``out``; returns its payload.

    ``checkpoint`` is rewritten after every epoch. ``stop_after_epoch`` ends the run
    after that epoch without writing ``out`` and returns None (how tests simulate a
    killed run). ``validate``, when given, is run on the model after the first epoch, every
    ``config.validate_every`` epochs and the last, and its metrics join the epoch's history; ``extra`` entries are stored in the payload.
    """
    checkpoint = Path(checkpoint)
    digest = run_digest(predictor=predictor, config=config, layout=layout, data_seed=data_seed, data_key=data_key)
    torch.manual_seed(config.init_seed)
    model = ACPredictor(predictor).to(device)
    opt = torch.optim.AdamW(
        model.parameters(), lr=config.lr, betas=(config.beta1, config.beta2), weight_decay=config.weight_decay
    )
    n = len(seqs)
    per_epoch = math.ceil(n / config.batch_size)
    total = per_epoch * config.epochs
    start_epoch, history = 0, []
    if checkpoint.exists():
        state = _load(checkpoint, map_location=device)
        if state.get("digest") == digest:
            model.load_state_dict(state["model"])
            opt.load_state_dict(state["optimizer"])
            start_epoch, history = state["epoch"], state["history"]
            log.info("resuming from %s after epoch %d", checkpoint, start_epoch)
        else:
            log.info("ignoring checkpoint %s: it belongs to a different run", checkpoint)
    log.info(
        "predictor: %d parameters, %d sequences of %d steps, %d epochs x %d steps",
        model.n_parameters(),
        n,
        seqs.n_steps,
        config.epochs,
        per_epoch,
    )
    tf_weights = torch.as_tensor(
        layout.teacher_forcing_weights(final_weight=config.final_weight, calib_targets=config.calib_targets),
        dtype=torch.float32,
        device=device,
    )
    model.train()
    # where the run's time goes, logged at the end (never stored: the outputs stay the same bytes on every run)
    phases = PhaseClock(("data", "forward", "backward", "optimiser", "validation", "checkpoint"))
    for epoch in range(start_epoch, config.epochs):
        order = np.random.default_rng([data_seed, epoch]).permutation(n)
        sums = np.zeros(2)
        bar = tqdm(range(per_epoch), desc=f"epoch {epoch + 1}/{config.epochs}", mininterval=5.0, leave=False)
        for b in bar:
            step = epoch * per_epoch + b
            for group in opt.param_groups:
                group["lr"] = lr_at(step, total, config)
            idx = np.sort(order[b * config.batch_size : (b + 1) * config.batch_size])
            with phases("data"):
                frames, actions, states = (x.to(device) for x in seqs.batch(idx))
            with phases("forward"):
                tf, ar = losses(
                    model, frames, actions, states, n_context=seqs.n_context, tf_weights=tf_weights, cfg=config
                )
                loss = tf + config.rollout_weight * ar
            with phases("backward"):
                opt.zero_grad(set_to_none=True)
                loss.backward()
            with phases("optimiser"):
                if config.grad_clip > 0:
                    torch.nn.utils.clip_grad_norm_(model.parameters(), config.grad_clip)
                opt.step()
            sums += [tf.item(), ar.item()]
            bar.set_postfix(tf=f"{tf.item():.4f}", ar=f"{ar.item():.4f}", refresh=False)
        entry = {"epoch": epoch + 1, "teacher_forcing": sums[0] / per_epoch, "rollout": sums[1] / per_epoch}
        due = epoch == 0 or (epoch + 1) % config.validate_every == 0 or epoch + 1 == config.epochs
        if validate is not None and due:
            model.eval()
            with phases("validation"):
                entry.update(validate(model))
            model.train()
        history.append(entry)
        log.info("epoch %d: %s", epoch + 1, ", ".join(f"{k} {v:.4f}" for k, v in entry.items() if k != "epoch"))
        with phases("checkpoint"):
            _save(
                checkpoint,
                {
                    "digest": digest,
                    "epoch": epoch + 1,
                    "model": model.state_dict(),
                    "optimizer": opt.state_dict(),
                    "history": history,
                },
            )
        log.info("time so far: %s", phases.summary())
        if stop_after_epoch is not None and epoch + 1 >= stop_after_epoch and epoch + 1 < config.epochs:
            return None
    payload = {
        "digest": digest,
        "predictor": predictor.to_dict(),
        "layout": layout.to_dict(),
        "train": config.to_dict(),
        "data_seed": data_seed,
        "history": history,
        **(extra or {}),
        "model": {k: v.cpu() for k, v in model.state_dict().items()},
    }
    _save(Path(out), payload)
    return payload


def train_variant(
    split: FeatureSplit,
    *,
    preset: PredictorPreset,
    layout: Layout,
    config: TrainConfig,
    data_seed: int,
    out: str | os.PathLike,
    checkpoint: str | os.PathLike,
    token_grid: tuple[int, int] | None = None,
    validate: Callable[[ACPredictor], dict[str, float]] | None = None,
    device: str = "cpu",
) -> dict | None:
    """Train (or resume) one variant on a training split's cached features: one sequence per object.

    The features are pooled to ``token_grid`` (:meth:`imply.models.features.FeatureSplit.pooled`;
    None keeps the encoder's grid). The predictor's width comes from ``preset``, its
    token width and patch grid from the pooled features. ``validate`` runs after the epochs
    :func:`train` says. ``config`` is resolved for the layout (:meth:`TrainConfig.for_layout`). Returns the saved
    payload (see :func:`train`).
    """
    config = config.for_layout(layout)
    split = split.pooled(token_grid)
    objects = training_objects(split)
    examples = objects
    if config.every_push_as_query:
        examples = objects.every_push_as_query(split.meta["speed"].to_numpy(dtype=float))
    seqs = training_sequences(split, layout, examples)
    pred_cfg = preset.predictor(embed_dim=int(split.tokens.shape[-1]), grid=split.grid, max_steps=layout.n_steps)
    data_key = f"{split.tokens.shape}:{split.grid}:{len(seqs)}:{layout.rest_state}"
    return train(
        seqs,
        layout=layout,
        predictor=pred_cfg,
        config=config,
        data_seed=data_seed,
        out=out,
        checkpoint=checkpoint,
        data_key=data_key,
        device=device,
        validate=validate,
        extra={"token_grid": list(split.grid)},
    )


def load_model(path: str | os.PathLike) -> tuple[ACPredictor, Layout, dict]:
    """A trained predictor (eval mode), its layout and the saved payload."""
    payload = _load(path, map_location="cpu")
    model = ACPredictor(PredictorConfig.from_dict(payload["predictor"]))
    model.load_state_dict(payload["model"])
    model.eval()
    # model files written before the layout carried rest_state kept it beside the layout
    layout = (
        {"rest_state": payload["rest_state"], **payload["layout"]} if "rest_state" in payload else payload["layout"]
    )
    return model, Layout.from_dict(layout), payload
