"""Section 5's validation: every Table 3 quantity, computed on the validation objects.

The validation split (``clips.n_validation`` objects, in no training or held-out set; see
:mod:`imply.data.clips`) is laid out like the held-out splits: two calibration pushes and
one query push at each of the K query speeds. :func:`validation_scores` rolls a model out
on it under the contexts its layout allows (``own``, ``swap`` with a fixed derangement,
``none``), reads each rollout with a readout fitted on real training clips, and scores
the result with Section 5's own functions (:mod:`imply.study.section5.scoring`): tracking
r, log error, self and anchored disagreement and their correlation with the error per
context, the own-vs-swap shares, and the object-blind baseline's error on the same
objects. The training run calls it after every epoch (:func:`section5_validator`); every
recipe choice of Section 5 is made on these numbers, and the held-out objects are scored
once, by the final recipe.
"""

from __future__ import annotations

from collections.abc import Callable

from imply.models.ac_predictor import ACPredictor
from imply.models.config import Layout
from imply.models.features import FeatureSplit
from imply.models.object_blind import TypicalSlide
from imply.models.rollout import TokenReadout, rollout_split
from imply.score import Scorer
from imply.study.section5.rollouts import object_blind_rollouts, rollouts_by_context
from imply.study.section5.scoring import context_scores, own_lt_swap, score_context

SCORE_FIELDS = ("track", "error", "self_disagreement", "anchored_disagreement", "corr_self", "corr_anchored")


def validation_scores(
    model: ACPredictor,
    layout: Layout,
    split: FeatureSplit,
    *,
    readout: TokenReadout,
    scorer: Scorer,
    typical: TypicalSlide,
    derangement_seed: int,
    batch_size: int = 200,
) -> dict[str, float]:
    """Table 3's quantities on ``split`` (pooled like the model's tokens), as a flat dict.

    Keys: ``<context>_<field>`` for each context and each of :data:`SCORE_FIELDS`;
    ``own_lt_swap_self`` and ``own_lt_swap_anchored`` (percent) for a calibrated layout;
    ``blind_error``: the object-blind baseline's mean log error on the same objects.
    """
    contexts = ("own", "swap", "none") if layout.calib else ("none",)
    table = rollout_split(
        model,
        layout,
        split,
        readout=readout,
        contexts=contexts,
        derangement_seed=derangement_seed,
        batch_size=batch_size,
    )
    rollouts = rollouts_by_context(table)
    scored = {ctx: score_context(r, scorer) for ctx, r in rollouts.items()}
    out: dict[str, float] = {}
    for ctx, per_object in scored.items():
        s = context_scores(per_object)
        out.update({f"{ctx}_{f}": float(getattr(s, f)) for f in SCORE_FIELDS})
    if layout.calib:
        shares = own_lt_swap(scored["own"], scored["swap"])
        out["own_lt_swap_self"] = float(shares.self_disagreement)
        out["own_lt_swap_anchored"] = float(shares.anchored_disagreement)
    first = rollouts[contexts[0]]
    blind = context_scores(score_context(object_blind_rollouts(first, typical), scorer))
    out["blind_error"] = float(blind.error)
    return out


def section5_validator(
    split: FeatureSplit,
    layout: Layout,
    *,
    readout: TokenReadout,
    scorer: Scorer,
    typical: TypicalSlide,
    derangement_seed: int,
) -> Callable[[ACPredictor], dict[str, float]]:
    """The per-epoch validation a training run calls: a function of the model (:func:`validation_scores`)."""

    def run(model: ACPredictor) -> dict[str, float]:
        return validation_scores(
            model, layout, split, readout=readout, scorer=scorer, typical=typical, derangement_seed=derangement_seed
        )

    return run
