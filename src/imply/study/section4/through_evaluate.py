"""Section 4's stand-ins measured through ``imply evaluate``: known answers, from pixels.

The four stand-ins (:mod:`imply.evaluate.standins`) draw rest frames; ``imply evaluate``
reads them with the frame-difference readout fitted on the suite's real clips and scores
them as it would score any user's model. Their answers are known: the oracle's anchored
disagreement should sit at the readout's own noise, the object-blind model should be
exposed by anchoring and not by self-disagreement, collapse should be flagged static, and
jitter should be separated from the oracle by both scores.

:func:`known_answers` summarises the evaluations as the result document of the paper stage
``evaluate`` (registry paths such as ``standins.blind.auroc_anchored``);
:func:`known_answer_claims` checks the pattern with thresholds fixed before the first run.
Separation is the AUROC of a stand-in's per-object score against the oracle's on the same
objects (own condition, sample set 0), as Section 4 measures it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from imply import stats
from imply.evaluate.config import EvaluateConfig
from imply.evaluate.evaluation import Evaluation
from imply.evaluate.harness import evaluate
from imply.evaluate.standins import STANDINS
from imply.evaluate.suite import load_suite
from imply.results import Claim, Values
from imply.score import ScoreConfig

# the readout's floor: the oracle's anchored disagreement may exceed the readout's own mean
# |log error| on real clips by at most this factor (its rollouts are the truth, read)
FLOOR_FACTOR = 1.5
EXPOSED_AUROC = 0.9  # a score that separates a stand-in from the oracle
HIDDEN_AUROC = 0.75  # a score that does not (the paper's object-blind self AUROC: 0.70)
STATIC_SHARE = 0.95


def run_standins(
    suite_dir: str | Path,
    *,
    settings: EvaluateConfig,
    score: ScoreConfig,
    cache_dir: str | Path | None = None,
    progress: bool = False,
) -> list[Evaluation]:
    """Evaluate the four stand-ins on the suite, in the order of :data:`STANDINS`."""
    suite = load_suite(suite_dir)
    models = [factory(suite) for factory in STANDINS.values()]
    return evaluate(models, suite=suite, settings=settings, score=score, cache_dir=cache_dir, progress=progress)


def known_answers(evaluations: Sequence[Evaluation]) -> dict[str, Any]:
    """The result document of stage ``evaluate``: per stand-in its own-condition scores and AUROCs against the oracle."""
    by_name = dict(zip(STANDINS, evaluations, strict=True))
    per_object = {}
    for name, ev in by_name.items():
        ci = ev.readings.conditions.index("own") if "own" in ev.readings.conditions else 0
        per_object[name] = {"self": ev.sets.self_disagreement[ci, 0], "anchored": ev.sets.anchored_disagreement[ci, 0]}
    oracle = per_object["oracle"]
    out: dict[str, Any] = {}
    for name, ev in by_name.items():
        cond = ev.condition("own") or ev.conditions[0]
        deg = next(d for d in ev.degenerate if d.condition == cond.condition)
        row = {
            "model": ev.model,
            "condition": cond.condition,
            "track": cond.track.value,
            "error": cond.error.value,
            "self": cond.self_disagreement.value,
            "anchored": cond.anchored_disagreement.value,
            "static_share": deg.static / deg.n_sets,
            "not_growing_share": deg.not_growing / deg.n_sets,
        }
        if name != "oracle":
            row["auroc_self"] = stats.auroc(oracle["self"], per_object[name]["self"])
            row["auroc_anchored"] = stats.auroc(oracle["anchored"], per_object[name]["anchored"])
        out[name] = row
    readout = evaluations[0].readout
    return {
        "suite": evaluations[0].suite,
        "n_objects": evaluations[0].n_objects,
        "readout": {"name": readout.name, "r2_check": readout.r2_check, "error_check": readout.error_check},
        "standins": out,
    }


def known_answer_claims(v: Values, results: Mapping[str, Any] | None = None) -> list[Claim]:
    """The stand-ins' known answers through ``imply evaluate``, with the thresholds above."""

    def claim(cid: str, statement: str, holds: bool, detail: str) -> Claim:
        return Claim(id=cid, section="evaluate", statement=statement, holds=bool(holds), detail=detail)

    floor = FLOOR_FACTOR * v["evReadoutErr"]
    return [
        claim(
            "ev-oracle-at-readout-floor",
            f"Read from its frames, the oracle's mean anchored disagreement is at the readout's floor: at most "
            f"{FLOOR_FACTOR} times the readout's mean |log error| on real clips.",
            v["evOracleAnch"] <= floor,
            f"oracle anchored {v['evOracleAnch']:.3f}, floor {floor:.3f}",
        ),
        claim(
            "ev-blind-exposed-by-anchoring",
            f"Anchored disagreement separates the object-blind model from the oracle: AUROC at least {EXPOSED_AUROC}.",
            v["evBlindAurocAnch"] >= EXPOSED_AUROC,
            f"AUROC {v['evBlindAurocAnch']:.3f}",
        ),
        claim(
            "ev-blind-hidden-from-self",
            f"Self-disagreement does not separate the object-blind model from the oracle: AUROC at most {HIDDEN_AUROC}.",
            v["evBlindAurocSelf"] <= HIDDEN_AUROC,
            f"AUROC {v['evBlindAurocSelf']:.3f}",
        ),
        claim(
            "ev-collapse-flagged-static",
            f"Collapse is flagged static in at least {STATIC_SHARE:.0%} of its sets, the oracle in none.",
            v["evCollapseStatic"] >= STATIC_SHARE and v["evOracleStatic"] == 0,
            f"collapse {v['evCollapseStatic']:.1%}, oracle {v['evOracleStatic']:.1%}",
        ),
        claim(
            "ev-jitter-separated-by-both",
            f"Both scores separate jitter from the oracle: self and anchored AUROC at least {EXPOSED_AUROC}.",
            v["evJitterAurocSelf"] >= EXPOSED_AUROC and v["evJitterAurocAnch"] >= EXPOSED_AUROC,
            f"self {v['evJitterAurocSelf']:.3f}, anchored {v['evJitterAurocAnch']:.3f}",
        ),
    ]
