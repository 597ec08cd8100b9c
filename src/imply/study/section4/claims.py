"""The qualitative claims of the controlled validation, checked on its reproduced numbers."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from imply.results import Claim, Values

# the readout-noise levels of Table 2, lowest first (as many as section4.noise.sds has)
NOISE_ORACLE = ("noiseAOracle", "noiseBOracle", "noiseCOracle", "noiseDOracle", "noiseEOracle")
NOISE_JITTER = ("noiseAJitter", "noiseBJitter", "noiseCJitter", "noiseDJitter", "noiseEJitter")
NOISE_COLLAPSE = ("noiseACollapse", "noiseBCollapse", "noiseCCollapse", "noiseDCollapse", "noiseECollapse")

# "Self-consistency cannot see the object-blind model" under realistic readout noise,
# checked at the sweep's smallest nonzero level (the zero-noise number is reported, not
# claimed): blind's self AUROC against the oracle at most this ...
NOISY_BLIND_SELF_AUROC_MAX = 0.75
# ... while its anchored AUROC at the same level stays at least this.
NOISY_BLIND_ANCHORED_AUROC_MIN = 0.9


def section4_claims(v: Values, results: Mapping[str, Any] | None = None) -> list[Claim]:
    """The qualitative claims of Section 4 as checks with fixed, stated thresholds.

    ``v`` maps registered number names to unrounded values (``results``, the stage's
    result documents, are not needed here). The thresholds were set from the paper's
    wording before any result was seen; a claim that fails is reported.
    """

    def claim(cid: str, statement: str, holds: bool, detail: str) -> Claim:
        return Claim(id=cid, section="4", statement=statement, holds=bool(holds), detail=detail)

    oracle_scores = [v[name] for name in NOISE_ORACLE if name in v]
    other_aurocs = [v[name] for name in NOISE_JITTER + NOISE_COLLAPSE if name in v]
    return [
        claim(
            "s4-oracle-near-zero",
            "The oracle's mean self-disagreement is near zero: below 0.02 (log units).",
            v["OrSelf"] < 0.02,
            f"oracle self {v['OrSelf']:.4f}",
        ),
        claim(
            "s4-oracle-recovers-physics",
            "The oracle's implied physics recovers the object: R^2 of implied log mass and of log friction both at least 0.9.",
            v["orMassR"] >= 0.9 and v["orFricR"] >= 0.9,
            f"mass R^2 {v['orMassR']:.3f}, friction R^2 {v['orFricR']:.3f}",
        ),
        claim(
            "s4-self-catches-jitter-collapse",
            "Self-disagreement alone separates jitter and collapse from the oracle perfectly: both self AUROCs at least 0.99.",
            v["JitAurocSelf"] >= 0.99 and v["ColAurocSelf"] >= 0.99,
            f"jitter {v['JitAurocSelf']:.3f}, collapse {v['ColAurocSelf']:.3f}",
        ),
        claim(
            "s4-blind-self-like-oracle",
            "The object-blind model's mean self-disagreement is near zero like the oracle's: below 0.02.",
            v["BlSelf"] < 0.02,
            f"blind self {v['BlSelf']:.4f} vs oracle {v['OrSelf']:.4f}",
        ),
        claim(
            "s4-blind-self-auroc-far-below-anchored",
            "Self-disagreement AUROC of the object-blind model is far below anchored: lower by at least 0.2.",
            v["BlAurocAnch"] - v["BlAurocSelf"] >= 0.2,
            f"self {v['BlAurocSelf']:.3f} vs anchored {v['BlAurocAnch']:.3f}",
        ),
        claim(
            "s4-blind-error-as-large-as-jitter",
            "The object-blind model's log error is as large as jitter's: at least 0.75 times it.",
            v["BlErr"] >= 0.75 * v["JitErr"],
            f"blind {v['BlErr']:.3f} vs jitter {v['JitErr']:.3f}",
        ),
        claim(
            "s4-anchored-exposes-blind",
            "Anchoring exposes the object-blind model: anchored AUROC against the oracle at least 0.95, "
            "and its mean anchored disagreement at least 5 times its self-disagreement.",
            v["BlAurocAnch"] >= 0.95 and v["BlAnch"] >= 5 * v["BlSelf"],
            f"AUROC {v['BlAurocAnch']:.3f}; anchored {v['BlAnch']:.3f} vs self {v['BlSelf']:.4f}",
        ),
        claim(
            "s4-anchored-tracks-error",
            "Anchored disagreement correlates with log error within the jitter model and within the object-blind "
            "model: both Pearson r at least 0.8.",
            v["JitCorr"] >= 0.8 and v["BlCorr"] >= 0.8,
            f"jitter r {v['JitCorr']:.3f}, blind r {v['BlCorr']:.3f}",
        ),
        claim(
            "s4-collapse-far",
            "Collapse is far from the oracle: mean self and anchored disagreement both above 1 (log units).",
            v["ColSelf"] > 1 and v["ColAnch"] > 1,
            f"self {v['ColSelf']:.3f}, anchored {v['ColAnch']:.3f}",
        ),
        claim(
            "s4-noise-oracle-rises",
            "The oracle's anchored score rises with readout noise: strictly increasing over the noise levels.",
            bool(np.all(np.diff(oracle_scores) > 0)),
            "oracle score " + ", ".join(f"{s:.3f}" for s in oracle_scores),
        ),
        claim(
            "s4-noise-separation-survives",
            "Jitter and collapse stay separated from the oracle at every noise level: anchored AUROC at least 0.9.",
            min(other_aurocs) >= 0.9,
            f"lowest {min(other_aurocs):.3f}",
        ),
        claim(
            "s4-noise-max-blind-separated",
            f"At the largest readout noise (sd {v['noiseMax']:g}) the object-blind model is still separated: "
            "anchored AUROC at least 0.7.",
            v["noiseMaxAurocBlind"] >= 0.7,
            f"AUROC {v['noiseMaxAurocBlind']:.3f}",
        ),
        claim(
            "s4-noise-self-misses-blind",
            "Self-consistency cannot see the object-blind model under readout noise: at the smallest nonzero "
            f"readout noise (sd {v['noiseMinSd']:g}) its self AUROC against the oracle is at most "
            f"{NOISY_BLIND_SELF_AUROC_MAX:g}, while its anchored AUROC there is at least "
            f"{NOISY_BLIND_ANCHORED_AUROC_MIN:g}.",
            v["noiseMinSd"] > 0
            and v["noiseMinBlindSelf"] <= NOISY_BLIND_SELF_AUROC_MAX
            and v["noiseMinBlindAnch"] >= NOISY_BLIND_ANCHORED_AUROC_MIN,
            f"self {v['noiseMinBlindSelf']:.3f} vs anchored {v['noiseMinBlindAnch']:.3f}"
            if v["noiseMinSd"] > 0
            else "the sweep has no readout-noise level above zero",
        ),
        claim(
            "s4-sel-anchored-picks-oracle",
            "Lowest anchored disagreement picks the oracle candidate most of the time: more than 50% of objects.",
            v["selPickedOracle"] > 50,
            f"{v['selPickedOracle']:.1f}%",
        ),
        claim(
            "s4-sel-anchored-beats-first-and-consensus",
            "Selecting by anchored disagreement lowers the median miss below both the first candidate's and the consensus'.",
            v["selAnchMiss"] < v["selFirstMiss"] and v["selAnchMiss"] < v["selConsMiss"],
            f"anchored {v['selAnchMiss']:.2f} mm, first {v['selFirstMiss']:.2f} mm, consensus {v['selConsMiss']:.2f} mm",
        ),
        claim(
            "s4-sel-consensus-no-better",
            "Consensus does no better than the first candidate: its median miss is not lower.",
            v["selConsMiss"] >= v["selFirstMiss"],
            f"consensus {v['selConsMiss']:.2f} mm vs first {v['selFirstMiss']:.2f} mm",
        ),
        claim(
            "s4-sel-anchored-near-oracle",
            "Anchored selection's median miss is close to the oracle candidate's: within 1 mm.",
            abs(v["selAnchMiss"] - v["selOracMiss"]) <= 1.0,
            f"anchored {v['selAnchMiss']:.2f} mm vs oracle {v['selOracMiss']:.2f} mm",
        ),
    ]
