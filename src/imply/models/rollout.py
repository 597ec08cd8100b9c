"""Clip splits as predictor sequences, the latent readout, and deterministic rollouts.

Inputs are the clips stage's files (formats in :mod:`imply.data.clips` and
:mod:`imply.models.encoder`): ``results/clips/<split>.csv`` (one row per clip) and
``results/features/<split>.npz`` (``tokens`` float16 (n_clips, 8, n_patches, dim)),
read together by :func:`load_feature_split`.

* Training examples (:func:`training_sequences`): one per training object, its query
  clip, with the object's 2 calibration clips in context for the calibrated layout.
  Objects with a push that failed the simulator's checks (``ok`` = 0) are left out.
* Readout (:func:`fit_latent_readout`): the predictor lives in layer-normed token
  space (its inputs and targets are the encoder tokens through a parameter-free layer
  norm), so its rollouts are read with :class:`LatentReadout`, a ridge readout fit like
  the encoder's (:mod:`imply.readout`: last-frame tokens, log displacement, alpha by
  cross-validation) on
  layer-normed last-frame tokens of the training clips (see the class for the two
  differences).
* Rollouts (:func:`rollout_split`): for every held-out object and each of its K query
  speeds, the sequence's context (calibration steps, then the query's first frames)
  is kept and the rest is rolled out auto-regressively to the last frame, whose
  predicted tokens are read out to a displacement. No sampling: rollouts are
  deterministic. Contexts: ``own`` (the object's calibration clips), ``swap``
  (another object's, by a fixed derangement from ``derangement_seed``) and ``none``
  (the query's first frames only; the calibrated model then sees a shorter sequence).

Rollout table (CSV, one row per push; the calibration rows carry the object's own
observed calibration pushes, which anchoring uses whatever the context):

    object_id, context, context_object, role (calibration|rollout), speed,
    displacement (read from the rollout; observed for calibration rows),
    true_displacement (simulator), speed_index
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from tqdm import tqdm

from imply.models.ac_predictor import ACPredictor, normalise_tokens, rollout_cached
from imply.models.sequences import Layout, Sequences, build_sequences

log = logging.getLogger("imply.models.rollout")

CONTEXTS = ("own", "swap", "none")


@dataclass
class FeatureSplit:
    """A split's cached encoder tokens and clip metadata, rows aligned."""

    tokens: np.ndarray
    meta: pd.DataFrame
    grid: tuple[int, int]

    @property
    def n_frames(self) -> int:
        return self.tokens.shape[1]


def load_feature_split(features: str | Path, metadata: str | Path) -> FeatureSplit:
    """Read ``results/features/<split>.npz`` and ``results/clips/<split>.csv``."""
    meta = pd.read_csv(metadata, dtype={"object_id": str, "role": str, "split": str})
    with np.load(features) as z:
        tokens = z["tokens"]
        clip_id = z["clip_id"]
        grid = tuple(int(g) for g in z["grid"]) if "grid" in z else _square_grid(tokens.shape[2])
    if not np.array_equal(clip_id, meta["clip_id"].to_numpy()):
        raise ValueError(f"{features} and {metadata} list different clips")
    if grid[0] * grid[1] != tokens.shape[2]:
        raise ValueError(f"{features}: grid {grid} does not match {tokens.shape[2]} patches")
    return FeatureSplit(tokens=tokens, meta=meta, grid=grid)


def pool_tokens(split: FeatureSplit, grid: tuple[int, int] | None) -> FeatureSplit:
    """The split with its patch tokens average-pooled to ``grid`` (rows, columns); None keeps them.

    Each pooled token is the mean of a block of the encoder's patches, so every side of
    the encoder's grid must be a multiple of the pooled one. The box moves along the
    image's width, so a one-row grid keeps where it is and drops what the predictor does
    not need to carry from step to step (the table's rows above and below it).
    """
    if grid is None or tuple(grid) == tuple(split.grid):
        return split
    (gh, gw), (th, tw) = split.grid, (int(grid[0]), int(grid[1]))
    if th < 1 or tw < 1 or gh % th or gw % tw:
        raise ValueError(f"token grid {th}x{tw} does not divide the encoder's {gh}x{gw} patch grid")
    n, t, _, d = split.tokens.shape
    pooled = np.empty((n, t, th * tw, d), dtype=split.tokens.dtype)
    for lo in range(0, n, 256):  # in chunks: the float32 copy of a whole split would double its memory
        block = split.tokens[lo : lo + 256].astype(np.float32).reshape(-1, t, th, gh // th, tw, gw // tw, d)
        pooled[lo : lo + 256] = block.mean(axis=(3, 5)).reshape(-1, t, th * tw, d)
    return FeatureSplit(tokens=pooled, meta=split.meta, grid=(th, tw))


def _square_grid(p: int) -> tuple[int, int]:
    g = int(round(p**0.5))
    if g * g != p:
        raise ValueError(f"{p} patches and no grid given")
    return (g, g)


def frame_states(split: FeatureSplit, rest_state: float) -> np.ndarray:
    """(n_frames,) state of each frame index (see :mod:`imply.models.ac_predictor`).

    Frames 0..T-2 are at the clip's nominal frame times (the same for every clip);
    the last frame shows the box at rest, at a time that depends on the object, so it
    gets the constant ``rest_state`` instead: a state must not leak the outcome.
    """
    t = split.n_frames
    cols = [f"t{k}" for k in range(t - 1)]
    if all(c in split.meta.columns for c in cols):
        nominal = split.meta[cols].median(axis=0).to_numpy(dtype=float)
    else:
        nominal = np.arange(t - 1, dtype=float) / max(t - 1, 1)
    return np.append(nominal, rest_state)


def _clip_table(meta: pd.DataFrame) -> pd.DataFrame:
    """object_id -> clip ids of calibration_0, calibration_1 and the query clip(s)."""
    need = {"clip_id", "object_id", "role", "speed", "displacement"}
    missing = need - set(meta.columns)
    if missing:
        raise ValueError(f"clip metadata lacks column(s): {', '.join(sorted(missing))}")
    return meta


def _ok_objects(meta: pd.DataFrame) -> np.ndarray:
    if "ok" not in meta.columns:
        return meta["object_id"].unique()
    bad = set(meta.loc[meta["ok"] != 1, "object_id"])
    return np.array([o for o in meta["object_id"].unique() if o not in bad])


@dataclass
class TrainingObjects:
    """The training split's objects with every push ok: clip ids per object, in object order."""

    object_ids: np.ndarray  # (N,)
    query: np.ndarray  # (N,) clip id
    calib: np.ndarray  # (N, 2) clip ids

    def subset(self, rows: np.ndarray) -> TrainingObjects:
        return TrainingObjects(self.object_ids[rows], self.query[rows], self.calib[rows])

    def every_push_as_query(self, speed: np.ndarray) -> TrainingObjects:
        """Three examples per object: each of its three pushes predicted from the other two.

        ``speed``: (n_clips,) commanded speed of every clip; each example's context pair
        is put in order of speed, as the calibration pushes (slow, then fast) are.
        """
        clips = np.concatenate([self.query[:, None], self.calib], axis=1)  # (N, 3)
        queries, contexts = [], []
        for j in range(3):
            ctx = np.delete(clips, j, axis=1)
            swap = speed[ctx[:, 0]] > speed[ctx[:, 1]]
            ctx[swap] = ctx[swap][:, ::-1]
            queries.append(clips[:, j])
            contexts.append(ctx)
        return TrainingObjects(np.tile(self.object_ids, 3), np.concatenate(queries), np.concatenate(contexts, axis=0))


def training_objects(split: FeatureSplit) -> TrainingObjects:
    """The objects of a training split (objects with a push that failed the simulator's checks left out)."""
    meta = _clip_table(split.meta)
    keep = set(_ok_objects(meta))
    if len(keep) < meta["object_id"].nunique():
        log.info("training: leaving out %d object(s) with a failed push", meta["object_id"].nunique() - len(keep))
    meta = meta[meta["object_id"].isin(keep)]
    by_role = meta.pivot_table(index="object_id", columns="role", values="clip_id", aggfunc="first", sort=True)
    return TrainingObjects(
        object_ids=by_role.index.to_numpy(),
        query=by_role["query"].to_numpy(dtype=np.int64),
        calib=by_role[["calibration_0", "calibration_1"]].to_numpy(dtype=np.int64),
    )


def training_sequences(
    split: FeatureSplit,
    layout: Layout,
    rest_state: float,
    objects: TrainingObjects | None = None,
    *,
    calib_of: np.ndarray | None = None,
) -> Sequences:
    """One sequence per training object: its query clip, with calibration clips in context for a calibrated layout.

    ``objects`` defaults to all of :func:`training_objects`; ``calib_of`` (N,) takes
    object ``calib_of[i]``'s calibration clips for object i (the swap condition).
    """
    objects = training_objects(split) if objects is None else objects
    calib = objects.calib if calib_of is None else objects.calib[calib_of]
    states = np.broadcast_to(frame_states(split, rest_state), (len(split.meta), split.n_frames))
    return build_sequences(split.tokens, objects.query, calib, split.meta["speed"].to_numpy(), states, layout)


@dataclass
class HeldOut:
    """Held-out objects of a split: clip ids per object, in object order."""

    object_ids: np.ndarray  # (N,)
    calib: np.ndarray  # (N, 2) clip ids
    query: np.ndarray  # (N, K) clip ids, by speed_index
    speeds: np.ndarray  # (K,)


def heldout_objects(split: FeatureSplit) -> HeldOut:
    meta = _clip_table(split.meta)
    keep = set(_ok_objects(meta))
    n_all = meta["object_id"].nunique()
    if len(keep) < n_all:
        log.warning("held out: leaving out %d of %d object(s) with a failed push", n_all - len(keep), n_all)
    meta = meta[meta["object_id"].isin(keep)]
    cal = meta[meta["role"].str.startswith("calibration")]
    cal = cal.pivot_table(index="object_id", columns="role", values="clip_id", aggfunc="first", sort=True)
    q = meta[meta["role"] == "query"]
    qp = q.pivot_table(index="object_id", columns="speed_index", values="clip_id", aggfunc="first", sort=True)
    if qp.isna().any().any() or cal.isna().any().any():
        raise ValueError("every held-out object needs both calibration clips and a query clip at every speed")
    speeds = q.groupby("speed_index")["speed"].first().sort_index().to_numpy(dtype=float)
    objs = cal.index.to_numpy()
    return HeldOut(
        object_ids=objs,
        calib=cal.loc[objs, ["calibration_0", "calibration_1"]].to_numpy(dtype=np.int64),
        query=qp.loc[objs].to_numpy(dtype=np.int64),
        speeds=speeds,
    )


def derangement(n: int, seed: int) -> np.ndarray:
    """A permutation with no fixed point: object i takes object partner[i]'s calibration.

    A random cyclic order (from ``seed``), each object paired with the next one in it.
    """
    if n < 2:
        raise ValueError("a swap needs at least 2 objects")
    order = np.random.default_rng(seed).permutation(n)
    partner = np.empty(n, dtype=np.int64)
    partner[order] = np.roll(order, -1)
    return partner


@dataclass
class LatentReadout:
    """Displacement from predicted (layer-normed) last-frame tokens.

    A :class:`imply.readout.RidgeReadout` (log displacement, alpha by cross-validation
    over ``imply.readout.ALPHAS``) fit on layer-normed last-frame tokens of the training
    clips, with two differences from the encoder's readout, both because it reads
    *predicted* tokens: features are centred but not scaled per feature (layer-normed
    tokens already share one scale; dividing by the tiny spread of background patches
    would amplify a predictor's small errors there into huge displacements), and the
    read log displacement is clipped to the training range widened by ``margin`` (log
    units) on each side, so one wild rollout cannot dominate a mean.
    """

    ridge: object  # imply.readout.RidgeReadout
    log_min: float
    log_max: float

    def predict_log(self, tokens: np.ndarray) -> np.ndarray:
        return np.clip(self.ridge.predict_log(tokens), self.log_min, self.log_max)

    def predict(self, tokens: np.ndarray) -> np.ndarray:
        return np.exp(self.predict_log(tokens))

    def save(self, path: str | Path) -> None:
        from imply.io import write_npz

        r = self.ridge
        write_npz(
            path,
            format=np.asarray(LATENT_FORMAT),
            mean=r.mean,
            scale=r.scale,
            coef=r.coef,
            intercept=np.float64(r.intercept),
            alpha=np.float64(r.alpha),
            shape=np.asarray([r.n_patches, r.dim], dtype=np.int64),
            log_range=np.asarray([self.log_min, self.log_max]),
        )


LATENT_FORMAT = "imply-latent-readout-v1"


def load_latent_readout(path: str | Path) -> LatentReadout:
    from imply.readout import RidgeReadout

    with np.load(path) as z:
        if "format" not in z or str(z["format"]) != LATENT_FORMAT:
            raise ValueError(f"{path}: not a latent readout file (imply model readout writes one)")
        p, k = (int(v) for v in z["shape"])
        ridge = RidgeReadout(z["mean"], z["scale"], z["coef"], float(z["intercept"]), float(z["alpha"]), p, k)
        lo, hi = (float(v) for v in z["log_range"])
    return LatentReadout(ridge, lo, hi)


READOUT_MARGIN = float(np.log(2.0))  # log units the read slide may leave the training range by


def real_last_tokens(split: FeatureSplit, clips: np.ndarray) -> np.ndarray:
    """Layer-normed last-frame tokens of the given clips (row indices or a mask): (N, P, D) float32.

    What the predictor's rest-frame predictions are compared with and the real-token
    readout is fit on.
    """
    return normalise_tokens(torch.from_numpy(split.tokens[clips, -1].astype(np.float32))).numpy()


def _ridge_readout(tokens: np.ndarray, log_d: np.ndarray, margin: float) -> LatentReadout:
    """:class:`LatentReadout` of (N, P, D) tokens to log slides (alpha by cross-validation)."""
    from sklearn.linear_model import RidgeCV

    from imply.readout import ALPHAS, RidgeReadout

    n, p, k = tokens.shape
    flat = tokens.reshape(n, p * k).astype(np.float64)
    mean = flat.mean(axis=0)
    fit = RidgeCV(alphas=ALPHAS).fit(flat - mean, log_d)
    ridge = RidgeReadout(
        mean, np.ones_like(mean), np.asarray(fit.coef_, float), float(fit.intercept_), float(fit.alpha_), p, k
    )
    return LatentReadout(ridge, float(log_d.min() - margin), float(log_d.max() + margin))


def fit_latent_readout(split: FeatureSplit, margin: float = READOUT_MARGIN) -> LatentReadout:
    """:class:`LatentReadout` fit on the layer-normed last-frame tokens of every ok clip."""
    meta = split.meta
    ok = meta["ok"].to_numpy() == 1 if "ok" in meta.columns else np.ones(len(meta), bool)
    ok &= meta["displacement"].to_numpy() > 0
    return _ridge_readout(real_last_tokens(split, ok), np.log(meta["displacement"].to_numpy()[ok]), margin)


def fit_rollout_readout(
    model: ACPredictor, seqs: Sequences, displacement: np.ndarray, *, batch_size: int = 200,
    margin: float = READOUT_MARGIN,
) -> LatentReadout:  # fmt: skip
    """:class:`LatentReadout` fit on the model's own rolled-out last-frame tokens of ``seqs`` (its training sequences).

    ``displacement``: (N,) true slide of each sequence's query push (m, > 0). A readout fit
    on real tokens reads a predicted rest frame as if it were real, and a predicted frame is
    not: where the model cannot tell where the box stops it predicts a blend of the places
    it might, and the real-token readout reads that blend as a shorter slide (and its own
    small errors as object differences). Fit on the model's predictions, the readout maps
    what the model actually says to a slide, still a fixed linear map of the predicted
    tokens: it cannot see the context.
    """
    displacement = np.asarray(displacement, dtype=float)
    if displacement.shape != (len(seqs),) or not np.all(displacement > 0):
        raise ValueError("the rollout readout needs one positive slide per training sequence")
    tokens = final_tokens(model, seqs, batch_size, desc="rollout readout")
    return _ridge_readout(tokens, np.log(displacement), margin)


def latent_readout_report(readout: LatentReadout, heldout: dict[str, FeatureSplit]) -> dict:
    """The latent readout's alpha, clipping range and held-out R^2 (log slide) on real layer-normed tokens."""
    from imply.readout import r2_log

    report: dict = {"alpha": readout.ridge.alpha, "log_range": [readout.log_min, readout.log_max], "heldout_r2_log": {}}
    for name, split in heldout.items():
        meta = split.meta
        ok = (meta["ok"].to_numpy() == 1) if "ok" in meta.columns else np.ones(len(meta), bool)
        r2 = r2_log(meta["displacement"].to_numpy()[ok], readout.predict(real_last_tokens(split, ok)))
        report["heldout_r2_log"][name] = r2
        log.info("latent readout on %s: held-out R^2 (log slide) %.4f", name, r2)
    return report


@torch.no_grad()
def final_tokens(model: ACPredictor, seqs: Sequences, batch_size: int, desc: str = "rollout") -> np.ndarray:
    """Last-frame tokens of each sequence's rollout from its context: (N, P, D)."""
    out = []
    for lo in tqdm(range(0, len(seqs), batch_size), desc=desc, mininterval=5.0, leave=False):
        idx = np.arange(lo, min(lo + batch_size, len(seqs)))
        frames, actions, states = seqs.batch(idx)
        out.append(rollout_cached(model, frames, actions, states, seqs.n_context)[:, -1].numpy())
    return np.concatenate(out, axis=0)


def rollout_split(
    model: ACPredictor,
    layout: Layout,
    split: FeatureSplit,
    readout,
    contexts: tuple[str, ...],
    *,
    rest_state: float,
    derangement_seed: int,
    batch_size: int = 64,
) -> pd.DataFrame:
    """The rollout table (module docstring) for a held-out split under the given contexts."""
    held = heldout_objects(split)
    n, k = held.query.shape
    meta = split.meta.set_index("clip_id")
    speed = split.meta["speed"].to_numpy()
    disp = split.meta["displacement"].to_numpy()
    states = np.broadcast_to(frame_states(split, rest_state), (len(split.meta), split.n_frames))
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
        seqs = build_sequences(split.tokens, held.query.reshape(-1), calib, speed, states, ctx_layout)
        pred = readout.predict(final_tokens(model, seqs, batch_size, desc=f"rollout {ctx}"))
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
