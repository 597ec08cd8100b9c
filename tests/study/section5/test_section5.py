"""Section 5 scoring on synthetic rollout tables: typed results whose registry paths name model and context."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from imply.models.object_blind import TypicalSlide
from imply.paper.parts import stage_numbers
from imply.paper.registry import load_registry
from imply.paper.results import producer_name
from imply.score import ScoreConfig
from imply.study.section5.rollouts import read_evaluations
from imply.study.section5.scoring import Section5Result, nocalib_vs_blind, own_lt_swap, section5_results
from section5_helpers import rollout_table


@pytest.fixture(scope="module")
def tables() -> dict[tuple[str, int], pd.DataFrame]:
    rng = np.random.default_rng(3)
    out = {}
    for seed in (0, 1):
        mu = rng.uniform(0.15, 0.5, 30)
        own = mu * np.exp(rng.normal(0, 0.05, mu.size))  # tracks the object
        swap = np.roll(own, 1)  # another object's calibration
        none = np.full(mu.size, 0.3)  # the typical object
        out[("calib", seed)] = rollout_table(mu, {"own": own, "swap": swap, "none": none})
        out[("nocalib", seed)] = rollout_table(mu, {"none": none})
    return out


def test_section5_result_is_typed_and_every_registered_path_names_model_and_context(analytic_table, tables):
    scorer = ScoreConfig().scorer(analytic_table)
    typical = TypicalSlide(np.array([2.0, np.log(0.05 / 0.3)]))
    result, per_object = section5_results(tables, scorer, seeds=[0, 1], selection_seed=12, typical=typical)
    assert isinstance(result, Section5Result) and [s.seed for s in result.seeds] == [0, 1]
    first = result.seeds[0]
    assert set(first.calib) == {"own", "swap", "none"} and set(first.nocalib) == {"none"}
    assert set(first.blind) == {"calib_objects", "nocalib_objects"}
    # own calibration tracks the object, another's does not; the typical object does not at all
    assert first.calib["own"].track > 0.9 > first.calib["swap"].track
    assert np.isnan(first.nocalib["none"].track)
    assert first.calib["own"].error < first.calib["swap"].error
    assert first.selection.n == 30 and first.selection.consensus.own is None
    assert first.selection.anchored_minus_oracle == pytest.approx(
        first.selection.lowest_anchored.error - first.selection.oracle.error
    )

    document = {producer_name(section5_results): dataclasses.asdict(result)}
    registry = load_registry()
    numbers = stage_numbers("section5", document, registry)
    assert set(numbers) == {e.name for e in registry.of_stage("section5")}
    assert numbers["vjCTrack"] == first.calib["own"].track
    assert numbers["vjSTrack"] == first.calib["swap"].track
    assert numbers["vjQErr"] == first.nocalib["none"].error
    assert numbers["vjBQErr"] == first.blind["nocalib_objects"].error
    assert numbers["vjSOneCTrack"] == result.seeds[1].calib["own"].track
    assert numbers["vjSelAnchOwn"] == first.selection.lowest_anchored.own
    for entry in registry.of_stage("section5"):
        assert ".rows." not in entry.path, entry.name

    assert set(per_object["model"]) == {"calib", "nocalib", "blind", "blind_nocalib_objects"}
    assert len(per_object) == 2 * (3 + 1 + 2) * 30


def test_evaluations_need_a_report_a_suite_and_both_models(tmp_path, tiny_suite):
    with pytest.raises(ValueError, match="MODEL:SEED:FOLDER"):
        read_evaluations([f"calib:{tmp_path}"], {"calib": tiny_suite})
    with pytest.raises(ValueError, match="no suite given"):
        read_evaluations([f"calib:0:{tmp_path}"], {})
    with pytest.raises(ValueError, match="not an imply evaluate report"):
        read_evaluations([f"calib:0:{tmp_path}"], {"calib": tiny_suite})


def _per_object(ids, **columns) -> pd.DataFrame:
    return pd.DataFrame({"object_id": ids, **{k: np.asarray(v, dtype=float) for k, v in columns.items()}})


def test_own_lt_swap_counts_ties_as_not_lower_and_tests_each_share():
    ids = [f"o{i}" for i in range(6)]
    own = _per_object(ids, self_disagreement=[1, 1, 1, 2, 2, 2], anchored_disagreement=[0, 0, 0, 0, 0, 1])
    swap = _per_object(ids, self_disagreement=[2, 2, 1, 1, 1, 2], anchored_disagreement=[1, 1, 1, 1, 1, 1])
    s = own_lt_swap(own, swap)
    assert (s.n, s.self_count, s.anchored_count) == (6, 2, 5)  # the ties (objects 2, 5) are not lower
    assert s.self_disagreement == pytest.approx(100 * 2 / 6) and s.anchored_disagreement == pytest.approx(100 * 5 / 6)
    # two-sided for self: P(X <= 2) + P(X >= 4) of Binomial(6, 1/2); one-sided for anchored: P(X >= 5)
    assert s.self_p == pytest.approx((1 + 6 + 15 + 15 + 6 + 1) / 64)
    assert s.anchored_p == pytest.approx((6 + 1) / 64)
    assert s.self_low < s.self_disagreement < s.self_high and s.anchored_low < s.anchored_disagreement <= 100
    with pytest.raises(ValueError, match="different objects"):
        own_lt_swap(own, swap.iloc[::-1])


def test_nocalib_vs_blind_needs_the_same_objects_in_the_same_order():
    rng = np.random.default_rng(1)
    ids = [f"o{i}" for i in range(50)]
    blind = _per_object(ids, log_error=rng.uniform(0.2, 0.6, 50))
    model = _per_object(ids, log_error=blind["log_error"] + rng.normal(0.1, 0.05, 50))
    d = nocalib_vs_blind(model, blind, resamples=300, seed=0)
    assert d.diff == pytest.approx((model["log_error"] - blind["log_error"]).mean())
    assert d.low < d.diff < d.high
    with pytest.raises(ValueError, match="different objects"):
        nocalib_vs_blind(model.iloc[::-1], blind, resamples=300, seed=0)


def test_section5_results_report_the_tests_and_the_bootstrap_deterministically(analytic_table, tables):
    scorer = ScoreConfig().scorer(analytic_table)
    typical = TypicalSlide(np.array([2.0, np.log(0.05 / 0.3)]))
    kwargs = dict(seeds=[0, 1], selection_seed=12, typical=typical)
    result, per_object = section5_results(tables, scorer, **kwargs, bootstrap=200, bootstrap_seed=3)
    again, _ = section5_results(tables, scorer, **kwargs, bootstrap=200, bootstrap_seed=3)
    other, _ = section5_results(tables, scorer, **kwargs, bootstrap=200, bootstrap_seed=4)
    first = result.seeds[0]
    assert first.nocalib_vs_blind == again.seeds[0].nocalib_vs_blind != other.seeds[0].nocalib_vs_blind
    f = per_object[per_object["seed"] == 0].set_index("model")
    diff = f.loc["nocalib", "log_error"].to_numpy() - f.loc["blind_nocalib_objects", "log_error"].to_numpy()
    assert first.nocalib_vs_blind.diff == pytest.approx(diff.mean())
    assert first.nocalib_vs_blind.diff == pytest.approx(
        first.nocalib["none"].error - first.blind["nocalib_objects"].error
    )
    assert first.nocalib_vs_blind.low <= first.nocalib_vs_blind.diff <= first.nocalib_vs_blind.high
    s = first.own_lt_swap
    assert s.n == 30 and s.anchored_disagreement == pytest.approx(100 * s.anchored_count / 30)
    numbers = stage_numbers("section5", {producer_name(section5_results): dataclasses.asdict(result)}, load_registry())
    assert numbers["vjOwnLtSwapN"] == 30 and numbers["vjSelfOwnLtSwapP"] == s.self_p
    assert (
        numbers["vjAnchOwnLtSwapHigh"] == s.anchored_high and numbers["vjQBlindDiffLow"] == first.nocalib_vs_blind.low
    )
    assert numbers["vjSOneSelfOwnLtSwapP"] == result.seeds[1].own_lt_swap.self_p


# hand-made Section 5 numbers for which every claim below holds (roughly the seed-0 figures,
# self-disagreement made uncorrelated with error); each test moves one number
GOOD = dict(
    vjQTrack=-0.02,
    vjQErr=0.484,
    vjBQErr=0.380,
    vjQBlindDiff=0.104,
    vjQBlindDiffLow=0.08,
    vjQBlindDiffHigh=0.13,
    vjCTrack=0.955,
    vjSTrack=-0.02,
    vjCErr=0.177,
    vjSErr=0.543,
    vjOwnLtSwapN=300,
    vjSelfOwnLtSwap=52.0,
    vjSelfOwnLtSwapCount=156,
    vjSelfOwnLtSwapP=0.53,
    vjSelfOwnLtSwapLow=46.2,
    vjSelfOwnLtSwapHigh=57.8,
    vjAnchOwnLtSwap=88.7,
    vjAnchOwnLtSwapCount=266,
    vjAnchOwnLtSwapP=1e-43,
    vjAnchOwnLtSwapLow=84.5,
    vjAnchOwnLtSwapHigh=92.1,
    vjCCorrSelf=0.2,
    vjSCorrSelf=-0.1,
    vjCCorrAnch=0.9,
    vjSCorrAnch=0.95,
    vjSOneCTrack=0.966,
    vjSOneSTrack=0.05,
    vjSOneCErr=0.18,
    vjSOneQErr=0.49,
    vjSOneAnchOwnLtSwap=88.0,
    vjSOneOwnLtSwapN=300,
    vjSOneSelfOwnLtSwap=49.0,
    vjSOneSelfOwnLtSwapCount=147,
    vjSOneSelfOwnLtSwapP=0.77,
    vjSOneSelfOwnLtSwapLow=43.2,
    vjSOneSelfOwnLtSwapHigh=54.8,
    vjSOneCCorrAnch=0.9,
    vjSOneSCorrAnch=0.9,
)


def _claims(**changes) -> dict:
    from imply.study.section5.claims import section5_claims

    registry = load_registry()
    numbers = {e.name: 0.5 for e in registry.of_stage("section5")} | GOOD | changes
    numbers = {k: x for k, x in numbers.items() if x is not None}
    return {c.id: c for c in section5_claims(registry.values(numbers))}


def test_claims_hold_on_good_numbers_and_name_the_seeds_present():
    claims = _claims()
    for cid in (
        "s5-self-chance",
        "s5-self-no-error-track",
        "s5-anchored-prefers-own",
        "s5-nocalib-blind",
        "s5-anchored-tracks-error",
        "s5-targets-seed0",
        "s5-targets-seed1",
        "s5-second-seed",
    ):
        assert claims[cid].holds is True, (cid, claims[cid].detail)
    assert "156 of 300" in claims["s5-self-chance"].detail and "46.2-57.8%" in claims["s5-self-chance"].detail
    assert "All reached" in claims["s5-targets-seed0"].detail
    no_second = _claims(**{name: None for name in GOOD if name.startswith("vjSOne")})
    assert "s5-targets-seed0" in no_second and not {"s5-targets-seed1", "s5-second-seed"} & set(no_second)


def test_self_chance_is_a_two_sided_test():
    # 169 of 300 (56.3%): within 10 points of 50%, but the two-sided p is 0.03
    claim = _claims(vjSelfOwnLtSwap=56.3, vjSelfOwnLtSwapCount=169, vjSelfOwnLtSwapP=0.0325)["s5-self-chance"]
    assert claim.holds is False and "p = 0.033" in claim.detail
    assert _claims(vjSOneSelfOwnLtSwapP=0.0325)["s5-second-seed"].holds is False


@pytest.mark.parametrize(
    "changes",
    [dict(vjCCorrSelf=0.69), dict(vjSCorrSelf=-0.45), dict(vjCCorrSelf=0.35, vjCCorrAnch=0.3)],
)
def test_self_no_error_track_bounds_self_and_compares_it_to_anchored(changes):
    assert _claims(**changes)["s5-self-no-error-track"].holds is False


def test_anchored_tracks_error_no_longer_asks_about_self():
    assert _claims(vjCCorrSelf=0.95)["s5-anchored-tracks-error"].holds is True  # self above anchored
    assert _claims(vjSCorrAnch=0.45)["s5-anchored-tracks-error"].holds is False


@pytest.mark.parametrize("changes", [dict(vjAnchOwnLtSwapP=0.07), dict(vjAnchOwnLtSwap=51.0)])
def test_anchored_prefers_own_is_a_one_sided_test_above_self(changes):
    assert _claims(**changes)["s5-anchored-prefers-own"].holds is False


def test_nocalib_blind_reports_the_baseline_without_claiming_to_match_it():
    claim = _claims()["s5-nocalib-blind"]
    assert claim.holds is True  # its error (0.484) is above the baseline's (0.380)
    assert "+0.104" in claim.detail and "+0.080 to +0.130" in claim.detail and "0.380" in claim.detail
    assert _claims(vjQTrack=0.25)["s5-nocalib-blind"].holds is False


@pytest.mark.parametrize(
    ("changes", "missed"),
    [
        (dict(vjCTrack=0.89), "own-calibration r"),
        (dict(vjSTrack=-0.21), "another object's |r|"),
        (dict(vjAnchOwnLtSwap=79.9), "anchored prefers own"),
        (dict(vjCErr=0.49), "error with own calibration"),
        (dict(vjSelfOwnLtSwapP=0.049), "self's preference"),
        (dict(vjCTrack=float("nan")), "own-calibration r"),
    ],
)
def test_targets_name_what_is_not_reached(changes, missed):
    claims = _claims(**changes)
    claim = claims["s5-targets-seed0"]
    assert claim.holds is False
    assert missed in claim.detail.split("Not reached:")[1] and claim.detail.count(";") >= 4
    assert claims["s5-targets-seed1"].holds is True
    seed1 = {k.replace("vj", "vjSOne", 1): x for k, x in changes.items()}
    assert _claims(**seed1)["s5-targets-seed1"].holds is False
