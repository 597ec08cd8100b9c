"""The scores of one model's readings, each with a bootstrap 95% interval over objects.

Per condition (read on sample set 0, the deterministic use of a model):

* tracking r -- Pearson r across objects of the mean over the K speeds of read log slide
  against the mean true log slide (does the rollout know which object it is pushing?);
* log error -- per object the RMS over K of read minus true log slide, averaged;
* self and anchored disagreement (:class:`imply.score.Scorer`; anchoring always uses the
  object's own two observed calibration pushes, whatever the model was shown), their means
  and each one's Pearson r with the per-object log error.

Own against other: the share of objects whose score is lower with their own calibration
in context than with their partner's (a tie counts one half, so a model that ignores
its context sits at 50%). Selection: per object, the candidate set with the lowest
anchored or self disagreement, against a random candidate and against an oracle that
picks by true error; candidates are the conditions and, for a stochastic model, the
sample sets of each condition. Degenerate rollouts are counted per condition over all
sample sets (:class:`~imply.evaluate.evaluation.Degenerate`).

Intervals: percentiles 2.5 and 97.5 of each number recomputed on ``bootstrap`` resamples
of the objects (with replacement; one set of resamples shared by every number, drawn
from ``seed``), so intervals of different numbers are comparable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imply.evaluate.evaluation import (
    ConditionScores,
    Degenerate,
    Estimate,
    FrameQuality,
    OwnVsOther,
    Readings,
    Scores,
    Selection,
    SelectionRow,
    SetScores,
)
from imply.score import Scorer


@dataclass(frozen=True)
class Bootstrap:
    """Resamples of N objects: ``index`` (B, N); each statistic f(per-object arrays) -> Estimate."""

    index: np.ndarray

    @classmethod
    def draw(cls, n: int, *, resamples: int, seed: int) -> Bootstrap:
        rng = np.random.default_rng(seed)
        return cls(rng.integers(0, n, size=(resamples, n)))

    def mean(self, x: np.ndarray) -> Estimate:
        x = np.asarray(x, dtype=float)
        return self._estimate(float(x.mean()), x[self.index].mean(axis=1))

    def pearson(self, x: np.ndarray, y: np.ndarray) -> Estimate:
        return self._estimate(float(_pearson_rows(x[None], y[None])[0]), _pearson_rows(x[self.index], y[self.index]))

    def _estimate(self, value: float, draws: np.ndarray) -> Estimate:
        if len(self.index) == 0 or not np.isfinite(value):
            return Estimate(value, float("nan"), float("nan"))
        draws = draws[np.isfinite(draws)]
        if draws.size < 0.9 * len(self.index):
            return Estimate(value, float("nan"), float("nan"))
        low, high = np.percentile(draws, [2.5, 97.5])
        return Estimate(value, float(low), float(high))


def _pearson_rows(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Pearson r of each row pair of (B, N) arrays (NaN where either row is constant)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    xc = x - x.mean(axis=1, keepdims=True)
    yc = y - y.mean(axis=1, keepdims=True)
    sx = np.sqrt((xc * xc).sum(axis=1))
    sy = np.sqrt((yc * yc).sum(axis=1))
    with np.errstate(invalid="ignore", divide="ignore"):
        r = (xc * yc).sum(axis=1) / (sx * sy)
    # a constant row (a model that gives every object the same slide) has no correlation; its
    # deviations from the mean are rounding, not signal
    n = x.shape[1]
    flat_x = sx <= 1e-9 * np.sqrt(n) * (1.0 + np.abs(x).max(axis=1))
    flat_y = sy <= 1e-9 * np.sqrt(n) * (1.0 + np.abs(y).max(axis=1))
    return np.where(flat_x | flat_y, np.nan, r)


def score_sets(readings: Readings, scorer: Scorer) -> SetScores:
    """Score every (condition, sample, object) set at once: one matrix search for all of them."""
    d = readings.displacement
    c, s, n, k = d.shape
    floor = scorer.floor
    flat = np.maximum(d.reshape(c * s * n, k), floor)
    calib = np.tile(readings.calibration_displacement, (c * s, 1))
    scores = scorer.score(readings.query_speeds, flat, readings.calibration_speeds, calib)
    log_read = np.log(flat).reshape(c, s, n, k)
    log_true = np.log(np.maximum(readings.true_displacement, floor))
    return SetScores(
        self_disagreement=scores.self_disagreement.reshape(c, s, n),
        anchored_disagreement=scores.anchored_disagreement.reshape(c, s, n),
        error=np.sqrt(((log_read - log_true) ** 2).mean(axis=3)),
        mean_log=log_read.mean(axis=3),
    )


def condition_scores(
    condition: str, ci: int, sets: SetScores, true_mean_log: np.ndarray, boot: Bootstrap
) -> ConditionScores:
    err = sets.error[ci, 0]
    self_d = sets.self_disagreement[ci, 0]
    anch = sets.anchored_disagreement[ci, 0]
    return ConditionScores(
        condition=condition,
        n_objects=int(err.size),
        track=boot.pearson(sets.mean_log[ci, 0], true_mean_log),
        error=boot.mean(err),
        self_disagreement=boot.mean(self_d),
        anchored_disagreement=boot.mean(anch),
        corr_self=boot.pearson(self_d, err),
        corr_anchored=boot.pearson(anch, err),
    )


def own_vs_other(conditions: tuple[str, ...], sets: SetScores, boot: Bootstrap) -> OwnVsOther | None:
    if "own" not in conditions or "other" not in conditions:
        return None
    own, other = conditions.index("own"), conditions.index("other")

    def lower(score: np.ndarray) -> np.ndarray:
        a, b = score[own, 0], score[other, 0]
        return np.where(a < b, 1.0, np.where(a == b, 0.5, 0.0))

    return OwnVsOther(
        n_objects=int(sets.error.shape[2]),
        self_disagreement=boot.mean(lower(sets.self_disagreement)),
        anchored_disagreement=boot.mean(lower(sets.anchored_disagreement)),
    )


def select(
    among: str,
    *,
    anchored: np.ndarray,
    self_d: np.ndarray,
    error: np.ndarray,
    mean_log: np.ndarray,
    true_mean_log: np.ndarray,
    boot: Bootstrap,
    rng: np.random.Generator,
) -> Selection:
    """Choose one of M candidates per object; arrays (M, N). Ties go to the first candidate."""
    m, n = error.shape
    picks: dict[str, np.ndarray] = {
        "lowest anchored": np.argmin(anchored, axis=0),
        "lowest self": np.argmin(self_d, axis=0),
        "random": rng.integers(0, m, size=n),
        "oracle (true error)": np.argmin(error, axis=0),
    }
    cols = np.arange(n)
    rows = tuple(
        SelectionRow(rule, boot.pearson(mean_log[pick, cols], true_mean_log), boot.mean(error[pick, cols]))
        for rule, pick in picks.items()
    )
    return Selection(among=among, n_candidates=m, rows=rows)


# a read slide this many times the largest real one (of the suite's pushes) is no physics: a units slip, say
UNPHYSICAL_FACTOR = 10.0


def degenerate(condition: str, ci: int, readings: Readings, *, static_limit: float, floor: float) -> Degenerate:
    raw = readings.displacement[ci]
    largest = max(float(np.max(readings.true_displacement)), float(np.max(readings.calibration_displacement)))
    d = np.maximum(raw, floor)  # (S, N, K)
    static = (d < static_limit).all(axis=2)
    logv = np.log(readings.query_speeds)
    logv = logv - logv.mean()
    slope = (np.log(d) * logv).sum(axis=2) / (logv * logv).sum()
    return Degenerate(
        condition=condition,
        n_sets=int(static.size),
        n_rollouts=int(d.size),
        static=int(static.sum()),
        not_growing=int((slope <= 1e-9).sum()),  # a flat set's slope is rounding, not growth
        no_box=int((~readings.box_found[ci]).sum()),
        unphysical=int((raw > UNPHYSICAL_FACTOR * largest).sum()),
    )


def frame_quality(readings: Readings, boot: Bootstrap) -> FrameQuality | None:
    if not np.isfinite(readings.psnr).any():
        return None
    ci = readings.conditions.index("own") if "own" in readings.conditions else 0
    return FrameQuality(
        condition=readings.conditions[ci],
        saliency_ratio=boot.mean(readings.saliency_ratio[ci, 0].mean(axis=1)),
        psnr=boot.mean(readings.psnr[ci, 0].mean(axis=1)),
    )


def score_readings(
    readings: Readings,
    scorer: Scorer,
    *,
    bootstrap: int,
    seed: int,
    static_limit: float,
) -> Scores:
    """All scores of one model's readings (see the module docstring)."""
    conds = readings.conditions
    sets = score_sets(readings, scorer)
    n = readings.true_displacement.shape[0]
    boot = Bootstrap.draw(n, resamples=bootstrap, seed=seed)
    rng = np.random.default_rng([seed, 1])
    true_mean_log = np.log(np.maximum(readings.true_displacement, scorer.floor)).mean(axis=1)
    per_condition = tuple(condition_scores(c, i, sets, true_mean_log, boot) for i, c in enumerate(conds))
    by_conditions = None
    if len(conds) > 1:
        by_conditions = select(
            f"conditions ({', '.join(conds)}), sample set 0",
            anchored=sets.anchored_disagreement[:, 0],
            self_d=sets.self_disagreement[:, 0],
            error=sets.error[:, 0],
            mean_log=sets.mean_log[:, 0],
            true_mean_log=true_mean_log,
            boot=boot,
            rng=rng,
        )
    by_samples: list[Selection] = []
    spread: dict[str, Estimate] = {}
    if readings.n_samples > 1:
        for i, c in enumerate(conds):
            by_samples.append(
                select(
                    f"{readings.n_samples} sample sets, condition {c}",
                    anchored=sets.anchored_disagreement[i],
                    self_d=sets.self_disagreement[i],
                    error=sets.error[i],
                    mean_log=sets.mean_log[i],
                    true_mean_log=true_mean_log,
                    boot=boot,
                    rng=rng,
                )
            )
            spread[c] = boot.mean(sets.mean_log[i].std(axis=0, ddof=1))
    return Scores(
        sets=sets,
        conditions=per_condition,
        own_vs_other=own_vs_other(conds, sets, boot),
        selection_conditions=by_conditions,
        selection_samples=tuple(by_samples),
        spread=spread,
        degenerate=tuple(
            degenerate(c, i, readings, static_limit=static_limit, floor=scorer.floor) for i, c in enumerate(conds)
        ),
        frame_quality=frame_quality(readings, boot),
    )
