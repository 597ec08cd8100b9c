"""Section 5 across seeds and roundings: one run's verdicts from the study's own code, and the side-by-side report."""

from __future__ import annotations

import numpy as np
import pytest

from imply.cli.section5 import section5_part
from imply.models.object_blind import TypicalSlide
from imply.paper.latex_tables import TABLE3_CALIB_ROWS, TABLE3_NOCALIB_ROWS
from imply.score import ScoreConfig
from imply.study.section5.robustness import TABLE3, learned_at, robustness_report, run_outcome, target_margins
from section5_helpers import rollout_table


def _typical() -> TypicalSlide:
    # log d = 2 log v + log(0.05 / 0.3): the slide of the typical friction
    return TypicalSlide(coef=np.array([2.0, np.log(0.05 / 0.3)]))


def _run(analytic_table, *, seed: int, own_noise: float, rounding: str = "a", history=None):
    rng = np.random.default_rng(seed)
    mu = rng.uniform(0.15, 0.5, 100)
    own = mu * np.exp(rng.normal(0, own_noise, mu.size))
    # another object's calibration: a friction that has nothing to do with this object's
    swap = 0.3 * np.exp(rng.normal(0, 0.2, mu.size))
    calib = rollout_table(mu, {"own": own, "swap": swap, "none": np.full(mu.size, 0.3)})
    nocalib = rollout_table(mu, {"none": np.full(mu.size, 0.3)})
    return run_outcome(
        seed=seed,
        rounding=rounding,
        calib=calib,
        nocalib=nocalib,
        history=history or [{"epoch": 1, "own_track": 0.2}, {"epoch": 4, "own_track": 0.95}],
        scorer=ScoreConfig().scorer(analytic_table),
        typical=_typical(),
        selection_seed=0,
        part=section5_part,
    )


def test_a_run_that_tracks_its_calibration_holds_the_targets_with_margins(analytic_table):
    run = _run(analytic_table, seed=3, own_noise=0.02)
    assert run.numbers["vjCTrack"] > 0.95
    assert run.claims["s5-own-tracks"] and run.claims["s5-own-beats-blind"]
    assert run.margins.thresholds_hold
    assert run.margins.own_track == pytest.approx(run.numbers["vjCTrack"] - 0.9)
    assert run.margins.error_ratio == pytest.approx(run.numbers["vjQErr"] / run.numbers["vjCErr"] - 1)
    assert run.learned_at == 4 and run.epochs == 4


def test_a_run_whose_calibration_is_noise_misses_and_the_report_says_which(analytic_table):
    good = _run(analytic_table, seed=3, own_noise=0.02)
    bad = _run(analytic_table, seed=4, own_noise=0.6, rounding="b", history=[{"epoch": 2, "own_track": 0.3}])
    assert not bad.margins.thresholds_hold and not bad.claims["s5-targets-seed"]
    assert bad.learned_at is None
    text = robustness_report([good, bad], recipe="test")
    assert "seed 3, a" in text and "seed 4, b" in text
    assert "1 of 2" in text  # threshold targets hold in one run
    assert "a run never learned" in text
    assert "| vjCTrack |" in text  # the spread of a Table 3 quantity


def test_learned_at_skips_epochs_without_validation_and_never_reached():
    history = [{"epoch": 1}, {"epoch": 2, "own_track": 0.89}, {"epoch": 3, "own_track": float("nan")}]
    assert learned_at(history) is None
    assert learned_at([*history, {"epoch": 6, "own_track": 0.9}]) == 6


def test_margins_are_negative_where_a_target_is_missed():
    m = target_margins(
        {
            "vjCTrack": 0.85,
            "vjSTrack": -0.3,
            "vjAnchOwnLtSwap": 79.0,
            "vjQErr": 0.4,
            "vjCErr": 0.5,
            "vjSelfOwnLtSwapP": 0.01,
        }
    )
    assert m.own_track < 0 and m.swap_track < 0 and m.anchored_share < 0 and m.error_ratio < 0
    assert not m.thresholds_hold


def test_the_spread_covers_every_quantity_of_table3():
    """The robustness report's list of Table 3 names (written out in the study layer) is the paper table's cells."""
    cells = {name for _label, *names in (*TABLE3_NOCALIB_ROWS, *TABLE3_CALIB_ROWS) for name in names if name}
    assert cells <= set(TABLE3)
    assert len(TABLE3) == len(set(TABLE3))
