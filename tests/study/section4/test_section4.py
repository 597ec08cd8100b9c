"""The controlled validation's steps: stand-ins, objects and truth, scoring, selection, claims."""

from __future__ import annotations

import numpy as np
import pytest

from imply.paper.parts import build_part, write_part
from imply.paper.registry import load_registry
from imply.paper.results import producer_name
from imply.score import ScoreConfig
from imply.study.section4 import objects as objects_step
from imply.study.section4 import standins
from imply.study.section4.claims import (
    NOISY_BLIND_ANCHORED_AUROC_MIN,
    NOISY_BLIND_SELF_AUROC_MAX,
    section4_claims,
)
from imply.study.section4.config import NoiseConfig, ObjectsConfig, SelectionConfig, StandinsConfig
from imply.study.section4.scoring import noise_sweep, score_rollouts, smallest_nonzero_level, standin_metrics
from imply.study.section4.selection import selection_study

SEED = 7
OBJECTS = ObjectsConfig.from_dict({"n": 8, "n_train": 4})
STANDINS = StandinsConfig.from_dict({"jitter_sd": 0.25, "jitter_draws": 3})
NOISE = NoiseConfig.from_dict({"sds": [0.0, 0.1, 0.2]})
SELECTION = SelectionConfig.from_dict({"k": 4, "noise_sd": 0.03, "query_speed": 0.55, "within_mm": 10})
SCORE = ScoreConfig.from_dict({"grid": 41})


def test_standins_without_simulation():
    train = np.array([[0.01, 0.04], [0.04, 0.01]])
    typ = standins.typical_displacement(train)
    np.testing.assert_allclose(typ, [0.02, 0.02])  # geometric mean
    blind = standins.object_blind(3, typ)
    assert blind.shape == (3, 2) and np.all(blind == typ)
    col = standins.collapse(3, 2, 1e-4)
    assert np.all(col == 1e-4)
    np.testing.assert_allclose(standins.add_readout_noise([1.0, 2.0], 0.1, [0.0, 1.0]), [1.0, 2 * np.exp(0.1)])
    m, mu = standins.jitter_physics(
        [1.0, 0.21],
        [0.3, 0.59],
        k=5,
        draws=3,
        sd=0.25,
        rng=np.random.default_rng(0),
        mass_range=(0.2, 2.0),
        friction_range=(0.1, 0.6),
    )
    assert m.shape == mu.shape == (2, 3, 5)
    assert m.min() >= 0.2 and mu.max() <= 0.6  # clipped to the table's range
    assert np.std(np.log(m[0])) == pytest.approx(0.25, rel=0.5)  # log-normal spread around the truth
    with pytest.raises(ValueError):
        standins.typical_displacement(np.array([[0.0, 0.1]]))


def test_jitter_simulates_in_one_batch(scene, monkeypatch):
    calls = []
    real = objects_step.simulate_pushes

    def spy(*args, **kwargs):
        calls.append(np.size(args[0]))
        return real(*args, **kwargs)

    monkeypatch.setattr(objects_step, "simulate_pushes", spy)
    he = np.array([[0.05, 0.05, 0.03], [0.052, 0.049, 0.031]])
    disp, ok, m, mu = standins.jitter(
        [0.3, 0.8],
        [0.5, 1.0],
        [0.3, 0.2],
        he,
        sd=0.25,
        draws=2,
        rng=np.random.default_rng(1),
        mass_range=(0.2, 2.0),
        friction_range=(0.1, 0.6),
        scene=scene,
        nthread=2,
    )
    assert calls == [8]  # 2 objects x 2 draws x 2 speeds, one call
    assert disp.shape == (2, 2, 2) and ok.all()
    assert np.all(disp[..., 1] > disp[..., 0])  # faster pushes slide further


@pytest.fixture(scope="module")
def study(tiny_table, scene):
    """Objects, truth and stand-ins on the tiny table (a few seconds of simulation)."""
    objects = objects_step.draw_objects(OBJECTS, scene=scene, seed=SEED, table=tiny_table)
    truth = objects_step.simulate_truth(
        objects, query_speeds=SCORE.query_speeds, calibration_speeds=SCORE.calibration_speeds, scene=scene, nthread=2
    )
    rollouts = standins.standin_rollouts(
        objects,
        truth,
        settings=STANDINS,
        seed=SEED,
        table=tiny_table,
        query_speeds=SCORE.query_speeds,
        calibration_speeds=SCORE.calibration_speeds,
        floor=1e-4,
        scene=scene,
        nthread=2,
    )
    return objects, truth, rollouts


def run_study(tiny_table, objects, truth, rollouts):
    scores = score_rollouts(tiny_table, objects, truth, rollouts, score=SCORE)
    metrics = standin_metrics(scores, tiny_table, jitter_sd=0.25, k_speeds=5)
    noise = noise_sweep(tiny_table, truth, rollouts, settings=NOISE, seed=SEED, score=SCORE)
    sel, choices = selection_study(tiny_table, truth, rollouts, settings=SELECTION, seed=SEED, score=SCORE)
    results = {
        producer_name(standin_metrics): metrics,
        producer_name(noise_sweep): noise,
        producer_name(selection_study): sel,
    }
    return scores, results, choices


def test_objects_and_truth(study, tiny_table):
    objects, truth, rollouts = study
    assert (objects["population"] == "eval").sum() == 8 and (objects["population"] == "train").sum() == 4
    assert objects["mass"].between(0.2, 2.0).all() and objects["friction"].between(0.1, 0.6).all()
    assert objects["size_x"].nunique() == len(objects)  # geometry varies per object
    t = objects_step.truth_arrays(truth, query_speeds=SCORE.query_speeds, calibration_speeds=SCORE.calibration_speeds)
    assert t["calib"].shape == (8, 2) and t["query"].shape == (8, 5) and t["train"].shape == (4, 5)
    assert np.all(np.diff(t["query"], axis=1) > 0)
    r = standins.rollout_arrays(rollouts, t["ids"], SCORE.query_speeds)
    np.testing.assert_array_equal(r["oracle"][:, 0], t["query"])  # the oracle's rollouts are the truth
    assert r["jitter"].shape == (8, 3, 5)
    assert np.all(r["blind"][:, 0] == r["blind"][0, 0])  # same typical slide for every object
    assert np.all(r["collapse"] == 1e-4)
    wide = OBJECTS.replace(mass=OBJECTS.mass.replace(min=0.1))
    with pytest.raises(ValueError, match="range"):
        objects_step.draw_objects(wide, scene=None, seed=1, table=tiny_table)


def test_study_results_by_construction(study, tiny_table):
    scores, results, choices = run_study(tiny_table, *study)
    st = results[producer_name(standin_metrics)]["standins"]
    assert st["oracle"]["log_error"] == 0.0
    assert st["collapse"]["self"] > 1.0 and st["collapse"]["anchored"] > 1.0
    assert st["collapse"]["auroc_self"] == 1.0
    assert st["oracle"]["self"] < st["collapse"]["self"] / 20
    assert results[producer_name(standin_metrics)]["table_shape"] == [7, 6, 6]
    levels = results[producer_name(noise_sweep)]["levels"]
    assert [lv["sd"] for lv in levels] == [0.0, 0.1, 0.2]
    # noise level 0 reproduces the clean scores exactly
    assert levels[0]["standins"]["blind"]["mean_anchored"] == pytest.approx(st["blind"]["anchored"])
    assert levels[0]["standins"]["blind"]["auroc_self"] == pytest.approx(st["blind"]["auroc_self"])
    # self AUROC beside anchored: jitter is plain to see by itself without noise; under noise the
    # object-blind model's constant rollouts look as self-consistent as the oracle's, anchoring still sees it
    assert levels[0]["standins"]["jitter"]["auroc_self"] >= 0.9
    assert levels[0]["standins"]["oracle"]["auroc_self"] is None
    for lv in levels[1:]:
        assert lv["standins"]["blind"]["auroc_self"] < lv["standins"]["blind"]["auroc_anchored"]
    assert results[producer_name(noise_sweep)]["smallest_nonzero"] == {
        "level": 1,
        "sd": 0.1,
        "blind_auroc_self": levels[1]["standins"]["blind"]["auroc_self"],
        "blind_auroc_anchored": levels[1]["standins"]["blind"]["auroc_anchored"],
    }
    sel = results[producer_name(selection_study)]
    assert set(sel["rules"]) == {"first", "consensus", "anchored", "oracle", "self", "medoid"}
    assert sel["rules"]["oracle"]["picked_oracle"] == 1.0 and sel["rules"]["consensus"]["picked_oracle"] is None
    assert len(choices) == 8 and all(c.count("oracle") == 1 for c in choices["candidates"])
    numbers, claims = build_part("section4", results, claims=section4_claims)
    # every registered section4 number is read from these results, except the noise
    # levels this config does not have (three of five)
    registered = {e.name for e in load_registry().of_stage("section4")}
    assert registered - set(numbers) == {
        f"noise{L}{k}"
        for L in "DE"
        for k in ("Sd", "Oracle", "Jitter", "Blind", "Collapse", "JitterSelf", "BlindSelf", "CollapseSelf")
    }
    assert numbers["noiseCSd"] == 0.2 and numbers["noiseMax"] == 0.2 and numbers["noiseMinSd"] == 0.1
    assert numbers["noiseBBlindSelf"] == levels[1]["standins"]["blind"]["auroc_self"] == numbers["noiseMinBlindSelf"]
    assert numbers["selPickedOracle"] == 100.0 * sel["rules"]["anchored"]["picked_oracle"]
    assert {c.id for c in claims} >= {"s4-oracle-near-zero", "s4-sel-consensus-no-better"}
    assert all(c.section == "4" and c.detail for c in claims)


def test_study_is_deterministic(study, tiny_table, scene, tmp_path):
    """Same seeds -> byte-identical part files (simulation included)."""
    objects, truth, rollouts = study
    truth2 = objects_step.simulate_truth(
        objects, query_speeds=SCORE.query_speeds, calibration_speeds=SCORE.calibration_speeds, scene=scene, nthread=2
    )
    rollouts2 = standins.standin_rollouts(
        objects,
        truth2,
        settings=STANDINS,
        seed=SEED,
        table=tiny_table,
        query_speeds=SCORE.query_speeds,
        calibration_speeds=SCORE.calibration_speeds,
        floor=1e-4,
        scene=scene,
        nthread=2,
    )
    paths = []
    for i, (t, r) in enumerate(((truth, rollouts), (truth2, rollouts2))):
        _, results, _ = run_study(tiny_table, objects, t, r)
        numbers, claims = build_part("section4", results, claims=section4_claims)
        paths.append(tmp_path / f"part{i}.json")
        write_part(paths[-1], stage="section4", numbers=numbers, claims=claims)
    assert paths[0].read_bytes() == paths[1].read_bytes()


def test_selection_config_errors(study, tiny_table):
    _, truth, rollouts = study
    with pytest.raises(ValueError, match="query_speed"):
        selection_study(tiny_table, truth, rollouts, settings=SELECTION.replace(query_speed=0.5), seed=1, score=SCORE)
    with pytest.raises(ValueError, match="jitter_draws"):
        selection_study(tiny_table, truth, rollouts, settings=SELECTION.replace(k=6), seed=1, score=SCORE)
    with pytest.raises(ValueError, match="k must be at least 2"):
        SELECTION.replace(k=1)


def _values(**over):
    v = {
        "OrSelf": 0.005,
        "orMassR": 0.98,
        "orFricR": 0.97,
        "JitAurocSelf": 1.0,
        "ColAurocSelf": 1.0,
        "BlSelf": 0.006,
        "BlAurocSelf": 0.7,
        "BlAurocAnch": 1.0,
        "BlErr": 0.37,
        "JitErr": 0.37,
        "BlAnch": 0.165,
        "JitCorr": 0.96,
        "BlCorr": 1.0,
        "ColSelf": 4.7,
        "ColAnch": 4.1,
        "noiseASd": 0.0,
        "noiseAOracle": 0.006,
        "noiseAJitter": 1.0,
        "noiseACollapse": 1.0,
        "noiseBSd": 0.2,
        "noiseBOracle": 0.147,
        "noiseBJitter": 0.91,
        "noiseBCollapse": 1.0,
        "noiseMax": 0.2,
        "noiseMaxAurocBlind": 0.78,
        "selPickedOracle": 98,
        "selAnchMiss": 1.5,
        "selFirstMiss": 7.1,
        "selConsMiss": 8.6,
        "selOracMiss": 1.6,
        "noiseMinSd": 0.03,
        "noiseMinBlindSelf": 0.54,
        "noiseMinBlindAnch": 0.99,
    }
    v.update(over)
    return v


def _claims(**over):
    return {c.id: c.holds for c in section4_claims(load_registry().values(_values(**over)))}


def test_claims_follow_the_results():
    assert all(_claims().values())  # the paper's own numbers satisfy every check
    assert not _claims(BlAurocSelf=0.95)["s4-blind-self-auroc-far-below-anchored"]
    assert not _claims(selConsMiss=5.0)["s4-sel-consensus-no-better"]
    assert not _claims(selPickedOracle=40)["s4-sel-anchored-picks-oracle"]
    assert not _claims(noiseBOracle=0.001)["s4-noise-oracle-rises"]
    assert not _claims(OrSelf=0.05)["s4-oracle-near-zero"]


def test_smallest_nonzero_level_is_found_not_assumed():
    def level(sd, auroc_self, auroc_anchored):
        return {"sd": sd, "standins": {"blind": {"auroc_self": auroc_self, "auroc_anchored": auroc_anchored}}}

    # two zero levels first, and out of order: the lowest sd above zero is picked, wherever it sits
    found = smallest_nonzero_level(
        [level(0.0, 0.99, 1.0), level(0.0, 0.98, 1.0), level(0.2, 0.5, 0.8), level(0.05, 0.6, 0.95)]
    )
    assert found == {"level": 3, "sd": 0.05, "blind_auroc_self": 0.6, "blind_auroc_anchored": 0.95}
    assert smallest_nonzero_level([level(0.0, 0.99, 1.0)])["sd"] is None


def test_claim_self_misses_blind_under_noise():
    cid = "s4-noise-self-misses-blind"
    assert _claims()[cid]
    assert _claims(noiseMinBlindSelf=NOISY_BLIND_SELF_AUROC_MAX)[cid]  # the bounds are inclusive
    assert _claims(noiseMinBlindAnch=NOISY_BLIND_ANCHORED_AUROC_MIN)[cid]
    assert not _claims(noiseMinBlindSelf=NOISY_BLIND_SELF_AUROC_MAX + 0.01)[cid]  # self sees it after all
    assert not _claims(noiseMinBlindAnch=NOISY_BLIND_ANCHORED_AUROC_MIN - 0.01)[cid]  # nor does anchoring
    # a sweep with no nonzero level (the result's fields are None, read as NaN) cannot support the claim
    assert not _claims(noiseMinSd=float("nan"), noiseMinBlindSelf=float("nan"), noiseMinBlindAnch=float("nan"))[cid]
    # the zero-noise self AUROC is reported, not claimed: a high one does not fail the claim
    assert _claims(noiseABlindSelf=0.995)[cid]
    text = {c.id: c for c in section4_claims(load_registry().values(_values()))}[cid].statement
    assert "sd 0.03" in text and "at most 0.75" in text and "at least 0.9" in text
