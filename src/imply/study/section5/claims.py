"""The qualitative claims of Section 5 (the learned model), checked on its reproduced numbers.

Thresholds were fixed before any result was seen; a claim that does not hold is
reported as failing. The paper's own values in the details come from the registry.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from imply.results import Claim, Values

# Thresholds of the claims, fixed before the final run. "Tracks" is r > 0.5; "does not
# track" the object is |r| < 0.2; a score "tracks error" when its r with error exceeds 0.5.
TRACKS, BLIND, CORR = 0.5, 0.2, 0.5
# Binomial tests of own-vs-swapped preference: self "consistent with chance" is a two-sided
# p >= ALPHA; anchored "prefers own" is a one-sided (greater) p < ALPHA.
ALPHA = 0.05
# Self-disagreement "does not track the error": |r| with the error below this, in both
# calibration conditions, and below anchored's r.
SELF_ERROR_CORR = 0.4
# The second seed's replication: anchored prefers own on more than this share (%).
ANCHORED_SHARE = 60.0
# The study's targets on the held-out objects, per data-order seed: own-calibration
# tracking r at least TARGET_OWN_TRACK, another object's |r| at most TARGET_SWAP_TRACK, anchored
# prefers own on at least TARGET_ANCHORED_SHARE % of objects, error with own calibration below
# the no-calibration model's, self's preference consistent with chance (two-sided p >= ALPHA).
TARGET_OWN_TRACK, TARGET_SWAP_TRACK, TARGET_ANCHORED_SHARE = 0.9, 0.2, 80.0

# The names of one data-order seed's numbers that the targets read.
_TARGET_NUMBERS = {
    0: dict(
        own="vjCTrack",
        swap="vjSTrack",
        anch="vjAnchOwnLtSwap",
        own_err="vjCErr",
        none_err="vjQErr",
        self_p="vjSelfOwnLtSwapP",
        self_share="vjSelfOwnLtSwap",
    ),
    1: dict(
        own="vjSOneCTrack",
        swap="vjSOneSTrack",
        anch="vjSOneAnchOwnLtSwap",
        own_err="vjSOneCErr",
        none_err="vjSOneQErr",
        self_p="vjSOneSelfOwnLtSwapP",
        self_share="vjSOneSelfOwnLtSwap",
    ),
}


def _f(x: float, spec: str = ".2f") -> str:
    return format(x, spec) if np.isfinite(x) else "nan"


def _p(x: float) -> str:
    return format(x, ".2g") if np.isfinite(x) else "nan"


def targets_claim(v: Values, seed: int) -> Claim:
    """The study's targets on the held-out objects of data-order seed ``seed`` (0 or 1)."""
    n = _TARGET_NUMBERS[seed]
    own, swap, anch, self_p = v[n["own"]], v[n["swap"]], v[n["anch"]], v[n["self_p"]]
    own_err, none_err = v[n["own_err"]], v[n["none_err"]]
    # (what the target asks, its value as reported, whether it is reached); NaN reaches nothing
    targets = [
        (f"own-calibration r >= {TARGET_OWN_TRACK}", _f(own), bool(own >= TARGET_OWN_TRACK)),
        (f"another object's |r| <= {TARGET_SWAP_TRACK}", _f(abs(swap)), bool(abs(swap) <= TARGET_SWAP_TRACK)),
        (
            f"anchored prefers own >= {TARGET_ANCHORED_SHARE:.0f}%",
            f"{v[n['anch']]:.1f}%",
            bool(anch >= TARGET_ANCHORED_SHARE),
        ),
        (
            "error with own calibration < without calibration",
            f"{_f(own_err, '.3f')} vs {_f(none_err, '.3f')}",
            bool(own_err < none_err),
        ),
        (
            f"self's preference consistent with chance (p >= {ALPHA})",
            f"{v[n['self_share']]:.1f}%, p = {_p(self_p)}",
            bool(self_p >= ALPHA),
        ),
    ]
    reached = {f"{what}: {value}": ok for what, value, ok in targets}
    missed = [k for k, ok in reached.items() if not ok]
    return Claim(
        f"s5-targets-seed{seed}",
        "5",
        f"Targets on the held-out objects, data-order seed {seed}: own-calibration tracking r >= "
        f"{TARGET_OWN_TRACK}, another object's |r| <= {TARGET_SWAP_TRACK}, anchored prefers own on >= "
        f"{TARGET_ANCHORED_SHARE:.0f}% of objects, error with own calibration below the no-calibration "
        f"model's, self-disagreement's preference consistent with chance (two-sided binomial p >= {ALPHA}).",
        not missed,
        "; ".join(reached) + (f". Not reached: {'; '.join(missed)}" if missed else ". All reached"),
    )


def section5_claims(v: Values, results: Mapping[str, Any] | None = None) -> list[Claim]:
    """The claims of Section 5, checked on the first data-order seed (and the second, if run)."""

    def paper(*names: str) -> str:
        return ", ".join(v.registry[n].paper for n in names)

    out = [
        Claim(
            "s5-blind-no-context",
            "5",
            f"Trained without calibration context, the model does not track the object (|r| < {BLIND}).",
            bool(abs(v["vjQTrack"]) < BLIND),
            f"r = {_f(v['vjQTrack'])} (paper {paper('vjQTrack')})",
        ),
        Claim(
            "s5-blind-anchored-sees",
            "5",
            f"Without context, anchored disagreement tracks the rollouts' error (r > {CORR}) and "
            "self-disagreement correlates less with it.",
            bool(v["vjQCorrAnch"] > CORR and v["vjQCorrAnch"] > v["vjQCorrSelf"]),
            f"anchored {_f(v['vjQCorrAnch'])}, self {_f(v['vjQCorrSelf'])} (paper {paper('vjQCorrAnch', 'vjQCorrSelf')})",
        ),
        Claim(
            "s5-own-tracks",
            "5",
            f"With its own calibration in context the model tracks the object (r > {TRACKS}) and its "
            "error is lower than without calibration context.",
            bool(v["vjCTrack"] > TRACKS and v["vjCErr"] < v["vjQErr"]),
            f"r = {_f(v['vjCTrack'])}, error {_f(v['vjCErr'], '.3f')} vs {_f(v['vjQErr'], '.3f')} "
            f"(paper {paper('vjCTrack')}; {paper('vjCErr')} vs {paper('vjQErr')})",
        ),
        Claim(
            "s5-own-beats-blind",
            "5",
            "With its own calibration in context the model's error is below the object-blind baseline's "
            "(the training set's typical slide for the speed, on the same objects).",
            bool(v["vjCErr"] < v["vjBErr"] and ("vjSOneCErr" not in v or v["vjSOneCErr"] < v["vjBErr"])),
            f"error {_f(v['vjCErr'], '.3f')}"
            + (f" (second seed {_f(v['vjSOneCErr'], '.3f')})" if "vjSOneCErr" in v else "")
            + f" vs baseline {_f(v['vjBErr'], '.3f')} (not in the paper)",
        ),
        Claim(
            "s5-nocalib-blind",
            "5",
            f"Trained without calibration context, the model is object-blind (|r| < {BLIND}); its error is "
            "reported beside the object-blind baseline's on the same objects, not claimed to match it.",
            bool(abs(v["vjQTrack"]) < BLIND),
            f"r = {_f(v['vjQTrack'])}; error {_f(v['vjQErr'], '.3f')} vs baseline {_f(v['vjBQErr'], '.3f')}, "
            f"difference {_f(v['vjQBlindDiff'], '+.3f')} (paired bootstrap 95% interval "
            f"{_f(v['vjQBlindDiffLow'], '+.3f')} to {_f(v['vjQBlindDiffHigh'], '+.3f')}) (paper {paper('vjQTrack')}; "
            f"error {paper('vjQErr')})",
        ),
        Claim(
            "s5-swap-collapses",
            "5",
            f"With another object's calibration, tracking collapses (|r| < {BLIND}) and error rises above own.",
            bool(abs(v["vjSTrack"]) < BLIND and v["vjSErr"] > v["vjCErr"]),
            f"r = {_f(v['vjSTrack'])}, error {_f(v['vjSErr'], '.3f')} vs own {_f(v['vjCErr'], '.3f')} "
            f"(paper {paper('vjSTrack')}; {paper('vjSErr')})",
        ),
        Claim(
            "s5-self-chance",
            "5",
            "Self-disagreement's preference for the object's own calibration is consistent with chance "
            f"(two-sided exact binomial test against one half, p >= {ALPHA}).",
            bool(v["vjSelfOwnLtSwapP"] >= ALPHA),
            f"{v['vjSelfOwnLtSwapCount']} of {v['vjOwnLtSwapN']} ({v['vjSelfOwnLtSwap']:.1f}%), p = "
            f"{_p(v['vjSelfOwnLtSwapP'])}, 95% interval {v['vjSelfOwnLtSwapLow']:.1f}-{v['vjSelfOwnLtSwapHigh']:.1f}% "
            f"(paper {paper('vjSelfOwnLtSwap')}%)",
        ),
        Claim(
            "s5-self-no-error-track",
            "5",
            f"Self-disagreement does not track the rollouts' error: |r| < {SELF_ERROR_CORR} with own and with "
            "swapped calibration, and below anchored disagreement's r in both.",
            bool(
                abs(v["vjCCorrSelf"]) < SELF_ERROR_CORR
                and abs(v["vjSCorrSelf"]) < SELF_ERROR_CORR
                and abs(v["vjCCorrSelf"]) < v["vjCCorrAnch"]
                and abs(v["vjSCorrSelf"]) < v["vjSCorrAnch"]
            ),
            f"self {_f(v['vjCCorrSelf'])}/{_f(v['vjSCorrSelf'])}, anchored {_f(v['vjCCorrAnch'])}/"
            f"{_f(v['vjSCorrAnch'])} (own/swapped; paper {paper('vjCCorrSelf')}/{paper('vjSCorrSelf')}, "
            f"{paper('vjCCorrAnch')}/{paper('vjSCorrAnch')})",
        ),
        Claim(
            "s5-anchored-prefers-own",
            "5",
            "Anchored disagreement is lower with the object's own calibration on more than half the objects "
            f"(one-sided exact binomial test, p < {ALPHA}) and more often than self-disagreement.",
            bool(v["vjAnchOwnLtSwapP"] < ALPHA and v["vjAnchOwnLtSwap"] > v["vjSelfOwnLtSwap"]),
            f"anchored {v['vjAnchOwnLtSwapCount']} of {v['vjOwnLtSwapN']} ({v['vjAnchOwnLtSwap']:.1f}%), p = "
            f"{_p(v['vjAnchOwnLtSwapP'])}, 95% interval {v['vjAnchOwnLtSwapLow']:.1f}-"
            f"{v['vjAnchOwnLtSwapHigh']:.1f}%; self {v['vjSelfOwnLtSwap']:.1f}% (paper {paper('vjAnchOwnLtSwap')}% "
            f"vs {paper('vjSelfOwnLtSwap')}%)",
        ),
        Claim(
            "s5-anchored-separates",
            "5",
            "Mean anchored disagreement is lower with own than with swapped calibration, by more than "
            "the gap in mean self-disagreement.",
            bool(v["vjSAnch"] - v["vjCAnch"] > abs(v["vjSSelf"] - v["vjCSelf"])),
            f"anchored {_f(v['vjCAnch'], '.3f')} vs {_f(v['vjSAnch'], '.3f')}; self {_f(v['vjCSelf'], '.3f')} vs "
            f"{_f(v['vjSSelf'], '.3f')} (paper {paper('vjCAnch')} vs {paper('vjSAnch')}; {paper('vjCSelf')} vs "
            f"{paper('vjSSelf')})",
        ),
        Claim(
            "s5-anchored-tracks-error",
            "5",
            f"Anchored disagreement tracks the error in both calibration conditions (r > {CORR}).",
            bool(v["vjCCorrAnch"] > CORR and v["vjSCorrAnch"] > CORR),
            f"anchored {_f(v['vjCCorrAnch'])}/{_f(v['vjSCorrAnch'])} (own/swapped; paper "
            f"{paper('vjCCorrAnch')}/{paper('vjSCorrAnch')})",
        ),
        Claim(
            "s5-selection-beats",
            "5",
            "Selecting by anchored disagreement gives a lower mean log error than self-disagreement, "
            "consensus and a random candidate.",
            bool(
                v["vjSelAnch"] < v["vjSelSelf"] and v["vjSelAnch"] < v["vjSelCons"] and v["vjSelAnch"] < v["vjSelFirst"]
            ),
            f"anchored {v['vjSelAnch']:.3f}, self {v['vjSelSelf']:.3f}, consensus {v['vjSelCons']:.3f}, random "
            f"{v['vjSelFirst']:.3f} (paper {paper('vjSelAnch', 'vjSelSelf', 'vjSelCons', 'vjSelFirst')})",
        ),
        Claim(
            "s5-selection-near-oracle",
            "abstract",
            "Anchored selection comes within 0.003 of the oracle's mean log error.",
            bool(v["vjSelGapOrac"] <= 0.003),
            f"anchored {v['vjSelAnch']:.3f} vs oracle {v['vjSelOrac']:.3f} (paper {paper('vjSelAnch')} vs "
            f"{paper('vjSelOrac')})",
        ),
        Claim(
            "s5-selection-own",
            "5",
            "Anchored selection picks the own-calibration set for more objects than self-disagreement does.",
            bool(v["vjSelAnchOwn"] > v["vjSelSelfOwn"]),
            f"anchored {v['vjSelAnchOwn']}, self {v['vjSelSelfOwn']} of {v['vjSelN']} (paper "
            f"{paper('vjSelAnchOwn', 'vjSelSelfOwn')} of {paper('vjSelN')})",
        ),
    ]
    out.append(targets_claim(v, 0))
    if "vjSOneCTrack" in v:
        out.append(
            Claim(
                "s5-second-seed",
                "5",
                "A second data-order seed reproduces the finding: own calibration tracks (r > "
                f"{TRACKS}), swapped does not (|r| < {BLIND}), anchored prefers own on more than "
                f"{ANCHORED_SHARE:.0f}% of objects while self's preference is consistent with chance (two-sided "
                f"binomial p >= {ALPHA}), and anchored tracks error (r > {CORR}) in both conditions.",
                bool(
                    v["vjSOneCTrack"] > TRACKS
                    and abs(v["vjSOneSTrack"]) < BLIND
                    and v["vjSOneAnchOwnLtSwap"] > ANCHORED_SHARE
                    and v["vjSOneSelfOwnLtSwapP"] >= ALPHA
                    and v["vjSOneCCorrAnch"] > CORR
                    and v["vjSOneSCorrAnch"] > CORR
                ),
                f"tracking {_f(v['vjSOneCTrack'])}/{_f(v['vjSOneSTrack'])}, own<swap anchored "
                f"{v['vjSOneAnchOwnLtSwap']:.1f}%, self {v['vjSOneSelfOwnLtSwapCount']} of {v['vjSOneOwnLtSwapN']} "
                f"({v['vjSOneSelfOwnLtSwap']:.1f}%, p = {_p(v['vjSOneSelfOwnLtSwapP'])}, 95% interval "
                f"{v['vjSOneSelfOwnLtSwapLow']:.1f}-{v['vjSOneSelfOwnLtSwapHigh']:.1f}%), anchored corr "
                f"{_f(v['vjSOneCCorrAnch'])}/{_f(v['vjSOneSCorrAnch'])} (paper {paper('vjSOneCTrack')}/"
                f"{paper('vjSOneSTrack')}, {paper('vjSOneAnchOwnLtSwap')}%/{paper('vjSOneSelfOwnLtSwap')}%, "
                f"{paper('vjSOneCCorrAnch')}/{paper('vjSOneSCorrAnch')})",
            )
        )
        out.append(targets_claim(v, 1))
    return out


def section5_read_by(results: Mapping[str, Any]) -> str | None:
    """One line naming the readout that read each model's rollouts, from the result document's
    ``readouts`` (None for a result without them)."""
    doc = next((r for name, r in results.items() if name.endswith("section5_results")), None)
    if not doc:
        return None
    parts = []
    for seed in doc.get("seeds", []):
        for model, r in sorted((seed.get("readouts") or {}).items()):
            r2 = r.get("r2_check")
            check = f" (R^2 {r2:.3f} on real check clips)" if isinstance(r2, int | float) else ""
            parts.append(f"{model} seed {seed['seed']}: {r['name']}, fitted on {r['fitted_on']}{check}")
    return "; ".join(parts) + "; never fitted on rollouts" if parts else None
