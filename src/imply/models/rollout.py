"""Deterministic latent rollouts: the one rollout loop, and the held-out rollout table.

:func:`rollout` is the one loop that feeds the predictor's own predictions back in. The
training loss's rollout term (:func:`imply.models.train.losses`), per-epoch validation,
the rollout readout and the held-out rollouts all run it. It continues from keys and
values of the context: a pass over the context alone, or, in training, the
teacher-forcing pass over the whole sequence, whose first prediction after the context
and whose cached context it reuses (block-causal attention makes both the same up to
floating-point summation order). Each later step runs only its own tokens against the
cache. No sampling, no dropout: rollouts are deterministic.

Held-out rollouts (:func:`rollout_split`): for every held-out object
(:func:`imply.models.examples.heldout_objects`) and each of its K query speeds, the
sequence's context (calibration steps, then the query's first frames) is kept and the
rest is rolled out to the last frame, whose predicted tokens are read out to a
displacement (:mod:`imply.models.latent_readout`). Contexts: ``own`` (the object's
calibration clips), ``swap`` (another object's, by a fixed derangement from
``derangement_seed``) and ``none`` (the query's first frames only; the calibrated model
then sees a shorter sequence).

Rollout table (CSV, one row per push; the calibration rows carry the object's own
observed calibration pushes, which anchoring uses whatever the context):

    object_id, context, context_object, role (calibration|rollout), speed,
    displacement (read from the rollout; observed for calibration rows),
    true_displacement (simulator), speed_index
"""

from __future__ import annotations

import logging
from typing import Protocol

import numpy as np
import pandas as pd
import torch
from tqdm import tqdm

from imply.models.ac_predictor import ACPredictor
from imply.models.config import Layout
from imply.models.examples import heldout_objects
from imply.models.features import FeatureSplit
from imply.models.modules import KeyValue
from imply.models.sequences import Sequences, build_sequences
from imply.stats import derangement

log = logging.getLogger("imply.models.rollout")


class TokenReadout(Protocol):
    """What a rollout is read with (e.g. :class:`imply.models.latent_readout.LatentReadout`).

    A protocol, so that the rollout does not import the readout, which fits itself on rollouts.
    """

    def predict(self, tokens: np.ndarray) -> np.ndarray:
        """(n,) displacements (m) from (n, P, D) rest-frame tokens."""
        ...


CONTEXTS = ("own", "swap", "none")


def rollout(
    model: ACPredictor,
    frames: torch.Tensor,
    actions: torch.Tensor,
    states: torch.Tensor,
    *,
    n_context: int,
    steps: int | None = None,
    context_pass: tuple[torch.Tensor, list[KeyValue]] | None = None,
) -> torch.Tensor:
    """Predicted frames of steps ``n_context`` .. ``n_context + steps - 1``: (B, steps, P, D).

    The first ``n_context`` steps of ``frames`` are the context; every later step is
    predicted from the steps before it, predicted frames fed back in. ``steps``
    defaults to the rest of the sequence; ``actions`` and ``states`` (B, T, 1) must
    cover the steps rolled out. ``context_pass``: the predictions and keys/values of a
    :meth:`ACPredictor.run` that already covered the context (training's
    teacher-forcing pass over the whole sequence; its keys and values are cut to the
    context); without it the context runs once here. Gradients flow through the fed-back
    predictions unless the caller turns them off.
    """
    t = frames.shape[1]
    steps = t - n_context if steps is None else steps
    if not 1 <= n_context < t or not 1 <= steps <= t - n_context:
        raise ValueError(f"n_context {n_context} and steps {steps} do not fit a sequence of {t} steps")
    if context_pass is None:
        pred, cache = model.run(frames[:, :n_context], actions[:, :n_context], states[:, :n_context])
    else:
        pred, cache = context_pass
        n_tok = n_context * model.cfg.tokens_per_step
        cache = [(k[:, :, :n_tok], v[:, :, :n_tok]) for k, v in cache]
    nxt = pred[:, n_context - 1]
    rolled = [nxt]
    for s in range(n_context, n_context + steps - 1):
        out, cache = model.run(nxt[:, None], actions[:, s : s + 1], states[:, s : s + 1], t0=s, cache=cache)
        nxt = out[:, -1]
        rolled.append(nxt)
    return torch.stack(rolled, dim=1)


@torch.no_grad()
def final_tokens(model: ACPredictor, seqs: Sequences, *, batch_size: int, desc: str = "rollout") -> np.ndarray:
    """Last-frame tokens of each sequence's rollout from its context: (N, P, D)."""
    out = []
    for lo in tqdm(range(0, len(seqs), batch_size), desc=desc, mininterval=5.0, leave=False):
        idx = np.arange(lo, min(lo + batch_size, len(seqs)))
        frames, actions, states = seqs.batch(idx)
        out.append(rollout(model, frames, actions, states, n_context=seqs.n_context)[:, -1].numpy())
    return np.concatenate(out, axis=0)


def rollout_split(
    model: ACPredictor,
    layout: Layout,
    split: FeatureSplit,
    *,
    readout: TokenReadout,
    contexts: tuple[str, ...],
    derangement_seed: int,
    batch_size: int = 64,
) -> pd.DataFrame:
    """The rollout table (module docstring) for a held-out split under the given contexts."""
    held = heldout_objects(split)
    n, k = held.query.shape
    meta = split.meta.set_index("clip_id")
    speed = split.meta["speed"].to_numpy()
    disp = split.meta["displacement"].to_numpy()
    partner = derangement(n, derangement_seed)
    rows = []
    cal_rows = pd.DataFrame(
        {
            "object_id": np.repeat(held.object_ids, 2),
            "role": "calibration",
            "speed": speed[held.calib.reshape(-1)],
            "displacement": disp[held.calib.reshape(-1)],
            "true_displacement": disp[held.calib.reshape(-1)],
            "speed_index": -1,
        }
    )
    for ctx in contexts:
        if ctx not in CONTEXTS:
            raise ValueError(f"unknown context {ctx!r} (one of {', '.join(CONTEXTS)})")
        if ctx != "none" and not layout.calib:
            raise ValueError(f"context {ctx!r} needs a model trained with calibration context")
        ctx_layout = layout if ctx != "none" else layout.without_calibration()
        calib_obj = np.arange(n) if ctx == "own" else partner
        calib = np.repeat(held.calib[calib_obj], k, axis=0) if ctx != "none" else None
        seqs = build_sequences(split, ctx_layout, query_clip=held.query.reshape(-1), calib_clips=calib)
        pred = readout.predict(final_tokens(model, seqs, batch_size=batch_size, desc=f"rollout {ctx}"))
        q = held.query.reshape(-1)
        rollouts = pd.DataFrame(
            {
                "object_id": np.repeat(held.object_ids, k),
                "role": "rollout",
                "speed": speed[q],
                "displacement": pred,
                "true_displacement": disp[q],
                "speed_index": meta.loc[q, "speed_index"].to_numpy()
                if "speed_index" in meta.columns
                else np.tile(np.arange(k), n),
            }
        )
        both = pd.concat([cal_rows, rollouts], ignore_index=True)
        both.insert(1, "context", ctx)
        ctx_of = dict(zip(held.object_ids, held.object_ids[calib_obj], strict=True)) if ctx != "none" else {}
        both.insert(2, "context_object", both["object_id"].map(ctx_of).fillna("") if ctx_of else "")
        rows.append(both.sort_values(["object_id", "role", "speed_index"], kind="stable"))
        log.info("context %s: %d objects x %d speeds rolled out", ctx, n, k)
    return pd.concat(rows, ignore_index=True)
