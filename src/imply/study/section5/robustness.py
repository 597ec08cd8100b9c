"""Section 5 across data-order seeds and floating-point roundings: does anything but the recipe decide a verdict?

A *run* is one data-order seed trained under one rounding (a kernel path or a thread
count): its calibrated and its context-free model, rolled out on the validation objects
(never the held-out ones). :func:`run_outcome` scores a run with the study's own Section 5
code (:func:`imply.study.section5.scoring.section5_results`, one seed) and checks every
Section 5 claim on it with the paper part's own function (passed in), as on the held-out objects; the per-seed targets
(``s5-targets-seed0``, read for this run's seed) are split into their parts with the
distance each part clears its threshold by. :func:`robustness_report` puts the runs side by
side: every target and claim per run, each Table 3 quantity's range, the share of runs in
which self-disagreement's chance test falls below its level (which a paper that is right
expects in one run in twenty), and the learning margin: the first validated epoch at which
the own-calibration tracking r reached the target.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import pandas as pd

from imply.models.object_blind import TypicalSlide
from imply.results import Claim
from imply.score import Scorer
from imply.study.section5.claims import ALPHA, TARGET_ANCHORED_SHARE, TARGET_OWN_TRACK, TARGET_SWAP_TRACK
from imply.study.section5.scoring import Section5Result, section5_results

# a Section 5 result -> its registered numbers (name -> value) and its claims checked on them: what the paper part
# of the stage computes (the command line passes it in, as it ties every stage to its claims)
PartFunction = Callable[[Section5Result], tuple[Mapping[str, float], list[Claim]]]

# Table 3's quantities (first seed's names) whose spread across runs is reported: each of the table's rows (the
# context-free model, the calibrated one with its own, another object's and no calibration, the object-blind
# baseline, which no run moves) by each column, then the own-vs-swap shares and the selection. Written out: the
# study does not import the paper's table layout (imply.paper.latex_tables), and every name stays greppable
TABLE3 = (
    *("vjQTrack", "vjQErr", "vjQSelf", "vjQAnch", "vjQCorrSelf", "vjQCorrAnch"),
    *("vjCTrack", "vjCErr", "vjCSelf", "vjCAnch", "vjCCorrSelf", "vjCCorrAnch"),
    *("vjSTrack", "vjSErr", "vjSSelf", "vjSAnch", "vjSCorrSelf", "vjSCorrAnch"),
    *("vjCQTrack", "vjCQErr", "vjCQSelf", "vjCQAnch", "vjCQCorrSelf", "vjCQCorrAnch"),
    *("vjBErr", "vjBSelf", "vjBAnch", "vjBCorrSelf", "vjBCorrAnch"),
    "vjAnchOwnLtSwap",
    "vjSelfOwnLtSwap",
    "vjSelAnch",
    "vjSelOrac",
    "vjSelGapOrac",
)


@dataclass(frozen=True)
class TargetMargins:
    """How far each per-seed threshold target is cleared in one run (positive: held, by that much).

    ``own_track``: own-calibration r minus its threshold; ``swap_track``: the threshold minus
    another object's |r|; ``anchored_share``: anchored's preference for the own calibration
    minus its threshold (points); ``error_ratio``: the no-calibration model's error over the
    calibrated model's with its own calibration, minus 1. ``self_p``: self-disagreement's
    two-sided binomial p (not a threshold target: it falls below ``ALPHA`` by chance).
    """

    own_track: float
    swap_track: float
    anchored_share: float
    error_ratio: float
    self_p: float

    @property
    def thresholds_hold(self) -> bool:
        """Every threshold target holds (self's chance test is counted apart)."""
        parts = (self.own_track, self.swap_track, self.anchored_share, self.error_ratio)
        return all(math.isfinite(x) and x >= 0 for x in parts)


@dataclass(frozen=True)
class RunOutcome:
    """One (seed, rounding) run scored on the validation objects."""

    seed: int
    rounding: str
    numbers: dict[str, float]
    claims: dict[str, bool]
    margins: TargetMargins
    learned_at: int | None
    epochs: int


def target_margins(numbers: Mapping[str, float]) -> TargetMargins:
    """The per-seed targets' margins from a run's first-seed numbers (``vjCTrack`` ...)."""
    return TargetMargins(
        own_track=numbers["vjCTrack"] - TARGET_OWN_TRACK,
        swap_track=TARGET_SWAP_TRACK - abs(numbers["vjSTrack"]),
        anchored_share=numbers["vjAnchOwnLtSwap"] - TARGET_ANCHORED_SHARE,
        error_ratio=numbers["vjQErr"] / numbers["vjCErr"] - 1.0,
        self_p=numbers["vjSelfOwnLtSwapP"],
    )


def learned_at(history: Sequence[Mapping[str, float]], *, key: str = "own_track", threshold: float = TARGET_OWN_TRACK):
    """The first validated epoch of a training history whose ``key`` reached ``threshold`` (None: never)."""
    for entry in history:
        value = entry.get(key)
        if value is not None and math.isfinite(value) and value >= threshold:
            return int(entry["epoch"])
    return None


def run_outcome(
    *,
    seed: int,
    rounding: str,
    calib: pd.DataFrame,
    nocalib: pd.DataFrame,
    history: Sequence[Mapping[str, float]],
    scorer: Scorer,
    typical: TypicalSlide,
    selection_seed: int,
    part: PartFunction,
) -> RunOutcome:
    """Score one run: ``calib`` and ``nocalib`` are its two models' rollout tables on the same validation objects
    (:func:`imply.models.rollout.rollout_split`; contexts own/swap/none and none), ``history`` the calibrated
    model's training history (its validated epochs give the learning margin); ``part`` gives the result's numbers and
    claims (``imply.cli.section5.section5_part``)."""
    result, _ = section5_results(
        {("calib", seed): calib, ("nocalib", seed): nocalib},
        scorer,
        seeds=[seed],
        selection_seed=selection_seed,
        typical=typical,
    )
    numbers, claims = part(result)
    return RunOutcome(
        seed=seed,
        rounding=rounding,
        numbers={k: float(v) for k, v in numbers.items()},
        claims={c.id.replace("seed0", "seed"): bool(c.holds) for c in claims},
        margins=target_margins(numbers),
        learned_at=learned_at(history),
        epochs=int(history[-1]["epoch"]) if history else 0,
    )


def _f(x: float, spec: str = ".3f") -> str:
    return format(x, spec) if math.isfinite(x) else "nan"


def robustness_report(runs: Sequence[RunOutcome], *, recipe: str) -> str:
    """The runs side by side (Markdown): targets, claims, Table 3's spreads, self's chance test, learning margin."""
    runs = sorted(runs, key=lambda r: (r.rounding, r.seed))
    head = "| quantity | " + " | ".join(f"seed {r.seed}, {r.rounding}" for r in runs) + " | worst |"
    rule = "|---|" + "---|" * (len(runs) + 1)
    lines = [f"Section 5 on the validation objects, {len(runs)} runs; recipe: {recipe}", "", "Per-seed targets:", ""]
    lines += [head, rule]
    m = [r.margins for r in runs]

    def row(name: str, values: list[str], worst: str) -> None:
        lines.append(f"| {name} | " + " | ".join(values) + f" | {worst} |")

    row(
        f"own-calibration r (>= {TARGET_OWN_TRACK})",
        [_f(r.numbers["vjCTrack"]) for r in runs],
        f"clears by {_f(min(x.own_track for x in m))}",
    )
    row(
        f"another object's abs r (<= {TARGET_SWAP_TRACK})",
        [_f(abs(r.numbers["vjSTrack"])) for r in runs],
        f"clears by {_f(min(x.swap_track for x in m))}",
    )
    row(
        f"anchored prefers own, % (>= {TARGET_ANCHORED_SHARE:.0f})",
        [_f(r.numbers["vjAnchOwnLtSwap"], ".1f") for r in runs],
        f"clears by {_f(min(x.anchored_share for x in m), '.1f')} points",
    )
    row(
        "error, own / no calibration (< 1)",
        [f"{_f(r.numbers['vjCErr'])} / {_f(r.numbers['vjQErr'])}" for r in runs],
        f"no-calibration error at least {_f(1 + min(x.error_ratio for x in m), '.2f')} x own",
    )
    below = sum(x.self_p < ALPHA for x in m)
    row(
        f"self prefers own, % (two-sided p; chance test at {ALPHA})",
        [f"{_f(r.numbers['vjSelfOwnLtSwap'], '.1f')} (p {_f(x.self_p, '.2g')})" for r, x in zip(runs, m, strict=True)],
        f"p < {ALPHA} in {below} of {len(runs)} runs",
    )
    row(
        "threshold targets hold",
        ["yes" if x.thresholds_hold else "**no**" for x in m],
        f"{sum(x.thresholds_hold for x in m)} of {len(runs)}",
    )
    learned = [r.learned_at for r in runs]
    latest = None if any(x is None for x in learned) else max(learned)
    row(
        f"learning margin: first validated epoch with own r >= {TARGET_OWN_TRACK}",
        [f"{x} of {r.epochs}" if x is not None else f"never ({r.epochs})" for r, x in zip(runs, learned, strict=True)],
        f"latest {latest} of {max(r.epochs for r in runs)}" if latest is not None else "**a run never learned**",
    )
    claim_ids = list(runs[0].claims)
    lines += ["", "Section 5's claims (validation objects):", "", head, rule]
    for cid in claim_ids:
        held = [r.claims.get(cid) for r in runs]
        row(cid, ["holds" if h else "**fails**" for h in held], f"holds in {sum(bool(h) for h in held)} of {len(runs)}")
    row(
        "anchored selection above the oracle (the abstract's 0.003)",
        [_f(r.numbers["vjSelGapOrac"]) for r in runs],
        f"largest {_f(max(r.numbers['vjSelGapOrac'] for r in runs))}",
    )
    lines += ["", "Table 3's quantities across the runs:", "", "| number | min | max | range |", "|---|---|---|---|"]
    for name in TABLE3:
        vals = [r.numbers[name] for r in runs if name in r.numbers]
        if vals:
            lo, hi = min(vals), max(vals)
            lines.append(f"| {name} | {_f(lo)} | {_f(hi)} | {_f(hi - lo)} |")
    return "\n".join(lines) + "\n"
