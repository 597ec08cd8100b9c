"""Section 5: scoring the action-conditioned predictor's latent rollouts.

Inputs: the rollout tables of :mod:`imply.models.rollout` (one per trained model: the
calibrated model with contexts own/swap/none, the model trained without calibration
with context none), for each data-order seed, and the push table.

Per model and context (rows of Table 3):

* tracks object r: Pearson correlation across objects of the mean over the K speeds
  of predicted log slide against the mean of true log slide;
* log error: per object the RMS over K of log(predicted) - log(true) (predictions
  floored at ``score.readout_floor``, as :func:`imply.study.stats.log_error`), averaged;
* self and anchored disagreement (:class:`imply.score.Scorer`; anchoring always uses
  the object's *own* two observed calibration pushes, whatever was in the context),
  averaged over objects, and each one's Pearson correlation across objects with the
  log error.

The object-blind baseline (``blind.calib_objects``): every held-out object of the
calibrated model predicted at the training set's typical slide for the speed
(:mod:`imply.models.object_blind`), scored the same way; ``blind.nocalib_objects`` is
the same on the held-out objects of the model trained without calibration. A model that uses its
calibration should beat it; a model without calibration can at best match it.

Own against swapped calibration (calibrated model): the percentage of objects whose
disagreement is lower with their own calibration in context than with another
object's (a tie counts as not lower), for self and for anchored disagreement, with the
counts, the exact binomial test against one half (two-sided for self: is its preference
consistent with chance; one-sided, greater, for anchored: does it prefer own) and each
share's exact 95% interval in percent (:func:`imply.stats.binomial_share`). Selection
among the three candidate sets: :mod:`imply.study.section5.selection`.

The model trained without calibration against the object-blind baseline on the same
objects (``nocalib_vs_blind``): the mean over objects of the model's log error minus
the baseline's, with the 95% percentile interval of a paired bootstrap over objects
(:func:`imply.stats.paired_bootstrap_difference`).

The result (:class:`Section5Result`) names every number by model and context: the
calibrated model's own-calibration tracking r of the first seed is
``seeds[0].calib["own"].track``, written to the result document as
``seeds.0.calib.own.track``, which is the registry's path of ``vjCTrack``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import pandas as pd

from imply import stats
from imply.models.object_blind import TypicalSlide
from imply.score import Scorer
from imply.study.section5.rollouts import MODELS, ContextRollouts, object_blind_rollouts, rollouts_by_context
from imply.study.section5.selection import CANDIDATES, CandidateSelection, select_candidates

log = logging.getLogger("imply.section5")


@dataclass(frozen=True)
class ContextScores:
    """One model x context over its objects (a row of Table 3): ``n`` objects; ``track``, the
    tracking r; ``error``, the mean log error; the mean self and anchored disagreement; and
    each disagreement's Pearson correlation with the log error across objects."""

    n: int
    track: float
    error: float
    self_disagreement: float
    anchored_disagreement: float
    corr_self: float
    corr_anchored: float


@dataclass(frozen=True)
class OwnLtSwap:
    """Objects whose disagreement is lower with their own calibration than with another's.

    ``self_disagreement`` and ``anchored_disagreement``: the percent of the ``n`` objects;
    ``self_count`` and ``anchored_count``: how many; ``self_p``: two-sided exact binomial
    test of the self share against one half; ``anchored_p``: one-sided (greater); ``*_low``
    and ``*_high``: each share's exact (Clopper-Pearson) two-sided 95% interval, in percent.
    """

    self_disagreement: float
    anchored_disagreement: float
    n: int
    self_count: int
    self_p: float
    self_low: float
    self_high: float
    anchored_count: int
    anchored_p: float
    anchored_low: float
    anchored_high: float


@dataclass(frozen=True)
class NocalibVsBlind:
    """The model without calibration against the object-blind baseline on the same objects: ``diff``,
    mean log error of the model minus the baseline's; ``low``, ``high``: paired bootstrap 95% interval."""

    diff: float
    low: float
    high: float


@dataclass(frozen=True)
class SeedScores:
    """Everything Section 5 reports for one data-order seed.

    ``calib`` and ``nocalib``: each model's scores by context (``own``, ``swap``,
    ``none``); ``blind``: the object-blind baseline on each model's held-out objects
    (``calib_objects``, ``nocalib_objects``); ``nocalib_vs_blind``: the model without
    calibration minus the baseline on its objects (:class:`NocalibVsBlind`).
    """

    seed: int
    calib: dict[str, ContextScores]
    nocalib: dict[str, ContextScores]
    blind: dict[str, ContextScores]
    own_lt_swap: OwnLtSwap
    nocalib_vs_blind: NocalibVsBlind
    selection: CandidateSelection
    readouts: dict[str, ReadoutUsed] | None = None


@dataclass(frozen=True)
class ReadoutUsed:
    """The readout that read a model's rollouts (from its ``imply evaluate`` report): its name,
    what it was fitted on, and its R^2 and mean |log error| of log slide on real check clips."""

    name: str
    fitted_on: str
    r2_check: float
    error_check: float


@dataclass(frozen=True)
class Section5Result:
    """Section 5's result: one :class:`SeedScores` per data-order seed, in the order given."""

    seeds: list[SeedScores]


def score_context(rollouts: ContextRollouts, scorer: Scorer) -> pd.DataFrame:
    """Per-object scores and errors of one model x context."""
    floor = scorer.floor
    pred = np.maximum(np.nan_to_num(rollouts.pred, nan=floor), floor)
    s = scorer.score(rollouts.speeds, pred, rollouts.calib_speeds, rollouts.calib_disp)
    return pd.DataFrame(
        {
            "object_id": rollouts.object_ids,
            "mean_log_pred": np.log(pred).mean(axis=1),
            "mean_log_true": np.log(np.maximum(rollouts.true, floor)).mean(axis=1),
            "log_error": stats.log_error(pred, rollouts.true, floor),
            "self_disagreement": s.self_disagreement,
            "anchored_disagreement": s.anchored_disagreement,
        }
    )


def context_scores(per_object: pd.DataFrame) -> ContextScores:
    """The row of Table 3 of one model x context, from its per-object scores (:func:`score_context`)."""
    f = per_object
    return ContextScores(
        n=int(len(f)),
        track=stats.pearson(f["mean_log_pred"], f["mean_log_true"]),
        error=float(f["log_error"].mean()),
        self_disagreement=float(f["self_disagreement"].mean()),
        anchored_disagreement=float(f["anchored_disagreement"].mean()),
        corr_self=stats.pearson(f["self_disagreement"], f["log_error"]),
        corr_anchored=stats.pearson(f["anchored_disagreement"], f["log_error"]),
    )


def own_lt_swap(own: pd.DataFrame, swap: pd.DataFrame) -> OwnLtSwap:
    """Objects whose disagreement is lower with own than swapped calibration, with their tests."""
    if not np.array_equal(own["object_id"].to_numpy(), swap["object_id"].to_numpy()):
        raise ValueError("own and swapped rollouts cover different objects")
    n = len(own)
    self_lower = own["self_disagreement"].to_numpy() < swap["self_disagreement"].to_numpy()
    anchored_lower = own["anchored_disagreement"].to_numpy() < swap["anchored_disagreement"].to_numpy()
    self_count, anchored_count = int(self_lower.sum()), int(anchored_lower.sum())
    self_test = stats.binomial_share(self_count, n, alternative="two-sided")
    anchored_test = stats.binomial_share(anchored_count, n, alternative="greater")
    return OwnLtSwap(
        self_disagreement=100.0 * float(np.mean(self_lower)),
        anchored_disagreement=100.0 * float(np.mean(anchored_lower)),
        n=n,
        self_count=self_count,
        self_p=self_test.p,
        self_low=100.0 * self_test.low,
        self_high=100.0 * self_test.high,
        anchored_count=anchored_count,
        anchored_p=anchored_test.p,
        anchored_low=100.0 * anchored_test.low,
        anchored_high=100.0 * anchored_test.high,
    )


def nocalib_vs_blind(model: pd.DataFrame, blind: pd.DataFrame, *, resamples: int, seed: int) -> NocalibVsBlind:
    """The per-object log error of ``model`` minus ``blind``'s (same objects, same order), bootstrapped."""
    if not np.array_equal(model["object_id"].to_numpy(), blind["object_id"].to_numpy()):
        raise ValueError("the model without calibration and the object-blind baseline cover different objects")
    d = stats.paired_bootstrap_difference(model["log_error"], blind["log_error"], resamples=resamples, seed=seed)
    return NocalibVsBlind(diff=d.diff, low=d.low, high=d.high)


# the object-blind baseline's two rows: (name in the result, the model whose held-out objects it
# predicts, that model's context whose objects are used, the model column of per_object.csv)
BLIND_ROWS = (
    ("calib_objects", "calib", "own", "blind"),
    ("nocalib_objects", "nocalib", "none", "blind_nocalib_objects"),
)


def section5_results(
    tables: dict[tuple[str, int], pd.DataFrame],
    scorer: Scorer,
    *,
    seeds: list[int],
    selection_seed: int,
    typical: TypicalSlide,
    bootstrap: int = 1000,
    bootstrap_seed: int = 0,
    readouts: dict[tuple[str, int], dict] | None = None,
) -> tuple[Section5Result, pd.DataFrame]:
    """All Section 5 results. ``tables``: (model, data-order seed) -> rollout table.

    ``bootstrap`` resamples of the objects, drawn from ``bootstrap_seed`` afresh for each
    data-order seed, give the interval of the no-calibration model's difference from the
    object-blind baseline.

    ``readouts``: (model, seed) -> the readout description of its ``imply evaluate`` report
    (``name``, ``fitted_on``, ``r2_check``, ``error_check``), kept beside the seed's scores
    so every number says which readout produced it.

    Returns the result (:class:`Section5Result`) and the per-object scores with seed,
    model and context columns.
    """
    per_seed: list[SeedScores] = []
    frames = []
    for seed in seeds:
        scored: dict[str, dict[str, pd.DataFrame]] = {}
        rollouts: dict[str, dict[str, ContextRollouts]] = {}
        for model in MODELS:
            rollouts[model] = rollouts_by_context(tables[(model, seed)])
            scored[model] = {}
            for ctx, r in rollouts[model].items():
                scored[model][ctx] = score_context(r, scorer)
                f = scored[model][ctx].copy()
                f.insert(0, "context", ctx)
                f.insert(0, "model", model)
                f.insert(0, "seed", seed)
                frames.append(f)
        blind = {
            name: score_context(object_blind_rollouts(rollouts[model][ctx], typical), scorer)
            for name, model, ctx, _ in BLIND_ROWS
        }
        for name, _, _, column in BLIND_ROWS:
            f = blind[name].copy()
            f.insert(0, "context", "typical")
            f.insert(0, "model", column)
            f.insert(0, "seed", seed)
            frames.append(f)
        result = SeedScores(
            seed=int(seed),
            calib={ctx: context_scores(f) for ctx, f in scored["calib"].items()},
            nocalib={ctx: context_scores(f) for ctx, f in scored["nocalib"].items()},
            blind={name: context_scores(f) for name, f in blind.items()},
            own_lt_swap=own_lt_swap(scored["calib"]["own"], scored["calib"]["swap"]),
            nocalib_vs_blind=nocalib_vs_blind(
                scored["nocalib"]["none"], blind["nocalib_objects"], resamples=bootstrap, seed=bootstrap_seed
            ),
            selection=select_candidates(
                rollouts["calib"], {c: scored["calib"][c] for c in CANDIDATES}, floor=scorer.floor, seed=selection_seed
            ),
            readouts=None
            if readouts is None
            else {
                model: ReadoutUsed(
                    **{k: readouts[(model, seed)][k] for k in ("name", "fitted_on", "r2_check", "error_check")}
                )
                for model in MODELS
            },
        )
        per_seed.append(result)
        tracks = {f"{model}.{ctx}": round(s.track, 3) for model in MODELS for ctx, s in getattr(result, model).items()}
        log.info("seed %d: %s", seed, tracks)
    return Section5Result(seeds=per_seed), pd.concat(frames, ignore_index=True)
