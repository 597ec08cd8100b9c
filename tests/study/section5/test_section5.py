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
from imply.study.section5.rollouts import read_rollout_tables
from imply.study.section5.scoring import Section5Result, section5_results

QUERY = np.array([0.3, 0.5, 0.7, 0.9])
CALIB = np.array([0.4, 0.8])


def _rollout_table(true_mu: np.ndarray, contexts: dict[str, np.ndarray]) -> pd.DataFrame:
    """A rollout table: per context, predictions from that context's friction per object."""

    def slide(v, mu):
        return 0.05 * v**2 / mu

    rows = []
    for ctx, pred_mu in contexts.items():
        for i, (mu, pmu) in enumerate(zip(true_mu, pred_mu, strict=True)):
            oid = f"o{i:03d}"
            for k, v in enumerate(QUERY):
                rows.append(dict(object_id=oid, context=ctx, role="rollout", speed_index=k, speed=v,
                                 displacement=slide(v, pmu), true_displacement=slide(v, mu)))  # fmt: skip
            for k, v in enumerate(CALIB):
                rows.append(dict(object_id=oid, context=ctx, role="calibration", speed_index=k, speed=v,
                                 displacement=slide(v, mu), true_displacement=slide(v, mu)))  # fmt: skip
    return pd.DataFrame(rows)


@pytest.fixture(scope="module")
def tables() -> dict[tuple[str, int], pd.DataFrame]:
    rng = np.random.default_rng(3)
    out = {}
    for seed in (0, 1):
        mu = rng.uniform(0.15, 0.5, 30)
        own = mu * np.exp(rng.normal(0, 0.05, mu.size))  # tracks the object
        swap = np.roll(own, 1)  # another object's calibration
        none = np.full(mu.size, 0.3)  # the typical object
        out[("calib", seed)] = _rollout_table(mu, {"own": own, "swap": swap, "none": none})
        out[("nocalib", seed)] = _rollout_table(mu, {"none": none})
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


def test_rollout_tables_need_both_models_of_a_seed(tmp_path, tables):
    path = tmp_path / "calib.csv"
    tables[("calib", 0)].to_csv(path, index=False)
    with pytest.raises(ValueError, match="lacks the nocalib model"):
        read_rollout_tables([f"calib:0:{path}"])
    with pytest.raises(ValueError, match="MODEL:SEED:PATH"):
        read_rollout_tables([f"calib:{path}"])
