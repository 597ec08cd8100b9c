"""Section 4 building blocks: metrics, selection rules, stand-ins, the study steps, the paper merge."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from imply import metrics as M
from imply import section4 as s4
from imply import standins as S
from imply.paper.macros import format_value, macros_tex, merge_parts, numbers_json
from imply.paper.parts import Claim, Number, read_part, write_part
from imply.paper.report import number_status, reproduction_frame, reproduction_md
from imply.paper.tables import table1_tex, table2_tex
from imply.paper.values import PaperValue, load_paper_values

SMALL_CFG = {
    "seed": 7,
    "objects": {"n": 8, "n_train": 4, "mass": {"min": 0.2, "max": 2.0}, "friction": {"min": 0.1, "max": 0.6},
                "size_log_sd": 0.05},
    "standins": {"jitter_sd": 0.25, "jitter_draws": 3},
    "noise": {"sds": [0.0, 0.1, 0.2]},
    "selection": {"k": 4, "noise_sd": 0.03, "query_speed": 0.55, "within_mm": 10},
}  # fmt: skip
SCORE_CFG = {
    "grid": 41,
    "readout_floor": 1e-4,
    "query_speeds": [0.25, 0.4, 0.55, 0.7, 0.85],
    "calibration_speeds": [0.3, 0.8],
}


# -- metrics ----------------------------------------------------------------------------


def test_auroc_known_values():
    assert M.auroc([0, 1, 2], [3, 4]) == 1.0
    assert M.auroc([3, 4], [0, 1]) == 0.0
    assert M.auroc([1, 1], [1, 1]) == 0.5  # ties count one half
    assert M.auroc([0, 2], [1, 3]) == 0.75
    with pytest.raises(ValueError):
        M.auroc([], [1.0])
    with pytest.raises(ValueError):
        M.auroc([np.nan], [1.0])


def test_pearson_r2_and_log_error():
    x = np.arange(10.0)
    assert M.pearson(x, 2 * x + 1) == pytest.approx(1.0)
    assert M.pearson(x, -x) == pytest.approx(-1.0)
    assert math.isnan(M.pearson(x, np.zeros(10)))  # constant side: undefined, not 0
    assert M.r_squared(x, x) == 1.0
    assert M.r_squared(x, np.full(10, x.mean())) == pytest.approx(0.0)
    # a biased prediction has a lower R^2 than its correlation would suggest (identity line)
    assert M.r_squared(x, x + 3) < 0.5
    true = np.array([[0.1, 0.2]])
    assert M.log_error(true, true, 1e-4)[0] == 0.0
    assert M.log_error(true * np.e, true, 1e-4)[0] == pytest.approx(1.0)
    # below the floor, predictions are clamped like the score clamps them
    assert M.log_error(np.zeros((1, 2)), np.full((1, 2), 1e-3), 1e-4)[0] == pytest.approx(np.log(10))


def test_selection_rules():
    # 2 objects x 3 candidates x 2 speeds
    c = np.array(
        [
            [[0.10, 0.20], [0.11, 0.21], [0.50, 0.90]],
            [[0.01, 0.01], [0.30, 0.40], [0.31, 0.41]],
        ]
    )
    np.testing.assert_array_equal(M.select_first(2), [0, 0])
    np.testing.assert_array_equal(M.select_lowest([[3, 1, 2], [0, 5, 5]]), [1, 0])
    np.testing.assert_allclose(M.consensus(c), [[0.11, 0.21], [0.30, 0.40]])
    # the medoid sits among the agreeing pair, not on the outlier
    med = M.select_medoid(c, 1e-4)
    assert med[0] in (0, 1) and med[1] in (1, 2)
    np.testing.assert_allclose(M.take(c, [2, 0]), [[0.50, 0.90], [0.01, 0.01]])
    miss = M.miss_mm([0.105, 0.2], [0.1, 0.1])
    np.testing.assert_allclose(miss, [5.0, 100.0])
    assert M.share_within(miss, 10) == 0.5


# -- stand-ins -------------------------------------------------------------------------


def test_standins_without_simulation():
    train = np.array([[0.01, 0.04], [0.04, 0.01]])
    typ = S.typical_displacement(train)
    np.testing.assert_allclose(typ, [0.02, 0.02])  # geometric mean
    blind = S.object_blind(3, typ)
    assert blind.shape == (3, 2) and np.all(blind == typ)
    col = S.collapse(3, 2, 1e-4)
    assert np.all(col == 1e-4)
    np.testing.assert_allclose(S.add_readout_noise([1.0, 2.0], 0.1, [0.0, 1.0]), [1.0, 2 * np.exp(0.1)])
    m, mu = S.jitter_physics([1.0, 0.21], [0.3, 0.59], 5, 3, 0.25, np.random.default_rng(0), (0.2, 2.0), (0.1, 0.6))
    assert m.shape == mu.shape == (2, 3, 5)
    assert m.min() >= 0.2 and mu.max() <= 0.6  # clipped to the table's range
    assert np.std(np.log(m[0])) == pytest.approx(0.25, rel=0.5)  # log-normal spread around the truth
    with pytest.raises(ValueError):
        S.typical_displacement(np.array([[0.0, 0.1]]))


def test_jitter_simulates_in_one_batch(scene, monkeypatch):
    calls = []
    real = S.simulate_pushes

    def spy(*args, **kwargs):
        calls.append(np.size(args[0]))
        return real(*args, **kwargs)

    monkeypatch.setattr(S, "simulate_pushes", spy)
    he = np.array([[0.05, 0.05, 0.03], [0.052, 0.049, 0.031]])
    disp, ok, m, mu = S.jitter(
        [0.3, 0.8], [0.5, 1.0], [0.3, 0.2], he, sd=0.25, draws=2, rng=np.random.default_rng(1),
        mass_range=(0.2, 2.0), friction_range=(0.1, 0.6), scene=scene, nthread=2,
    )  # fmt: skip
    assert calls == [8]  # 2 objects x 2 draws x 2 speeds, one call
    assert disp.shape == (2, 2, 2) and ok.all()
    assert np.all(disp[..., 1] > disp[..., 0])  # faster pushes slide further


# -- the study on the tiny table ---------------------------------------------------------


@pytest.fixture(scope="module")
def study(tiny_table, scene):
    """Objects, truth and stand-ins on the tiny table (a few seconds of simulation)."""
    q, c = SCORE_CFG["query_speeds"], SCORE_CFG["calibration_speeds"]
    objects = s4.draw_objects(SMALL_CFG["objects"], scene, SMALL_CFG["seed"], tiny_table)
    truth = s4.simulate_truth(objects, q, c, scene, nthread=2)
    rollouts = s4.make_standins(
        objects, truth, SMALL_CFG["standins"], SMALL_CFG["seed"], tiny_table, q, c, 1e-4, scene, nthread=2
    )
    return objects, truth, rollouts


def run_study(tiny_table, objects, truth, rollouts):
    scores = s4.score_rollouts(tiny_table, objects, truth, rollouts, SCORE_CFG)
    metrics = s4.table1_metrics(scores, tiny_table, 0.25, 5)
    noise = s4.noise_sweep(tiny_table, truth, rollouts, SMALL_CFG["noise"], SMALL_CFG["seed"], SCORE_CFG)
    sel, choices = s4.selection_study(tiny_table, truth, rollouts, SMALL_CFG["selection"], SMALL_CFG["seed"], SCORE_CFG)
    return scores, metrics, noise, sel, choices


def test_objects_and_truth(study, tiny_table):
    objects, truth, rollouts = study
    assert (objects["population"] == "eval").sum() == 8 and (objects["population"] == "train").sum() == 4
    assert objects["mass"].between(0.2, 2.0).all() and objects["friction"].between(0.1, 0.6).all()
    assert objects["size_x"].nunique() == len(objects)  # geometry varies per object
    t = s4.truth_arrays(truth, SCORE_CFG["query_speeds"], SCORE_CFG["calibration_speeds"])
    assert t["calib"].shape == (8, 2) and t["query"].shape == (8, 5) and t["train"].shape == (4, 5)
    assert np.all(np.diff(t["query"], axis=1) > 0)
    r = s4.rollout_arrays(rollouts, t["ids"], SCORE_CFG["query_speeds"])
    np.testing.assert_array_equal(r["oracle"][:, 0], t["query"])  # the oracle's rollouts are the truth
    assert r["jitter"].shape == (8, 3, 5)
    assert np.all(r["blind"][:, 0] == r["blind"][0, 0])  # same typical slide for every object
    assert np.all(r["collapse"] == 1e-4)
    with pytest.raises(ValueError, match="range"):
        s4.draw_objects({**SMALL_CFG["objects"], "mass": {"min": 0.1, "max": 2.0}}, None, 1, tiny_table)


def test_study_metrics_by_construction(study, tiny_table):
    scores, metrics, noise, sel, choices = run_study(tiny_table, *study)
    st = metrics["standins"]
    assert st["oracle"]["log_error"] == 0.0
    assert st["collapse"]["self"] > 1.0 and st["collapse"]["anchored"] > 1.0
    assert st["collapse"]["auroc_self"] == 1.0
    assert st["oracle"]["self"] < st["collapse"]["self"] / 20
    assert metrics["table_shape"] == [7, 6, 6]
    assert list(noise["sd"].unique()) == [0.0, 0.1, 0.2]
    # noise level 0 reproduces the clean scores exactly
    clean = noise[(noise["sd"] == 0) & (noise["standin"] == "blind")].iloc[0]
    assert clean["mean_anchored"] == pytest.approx(st["blind"]["anchored"])
    assert set(sel["rule"]) == {"first", "consensus", "anchored", "oracle", "self", "medoid"}
    orc = sel.set_index("rule").loc["oracle"]
    assert orc["picked_oracle"] == 1.0
    assert len(choices) == 8 and all(c.count("oracle") == 1 for c in choices["candidates"])
    numbers, claims = s4.section4_part(metrics, noise, sel, SMALL_CFG)
    for name in ("nObjects", "kSpeeds", "jitterSd", "OrSelf", "JitCorr", "BlSelf", "BlAnch", "BlErr", "BlAurocSelf",
                 "BlAurocAnch", "BlCorr", "orMassR", "orFricR", "selFirstMiss", "selConsMiss", "selAnchMiss",
                 "selPickedOracle", "selK", "noiseMax", "noiseMaxAurocBlind"):  # fmt: skip
        assert name in numbers
    assert numbers["noiseCSd"].value == 0.2 and numbers["noiseMax"].value == 0.2
    assert {c.id for c in claims} >= {"s4-oracle-near-zero", "s4-sel-consensus-no-better"}
    assert all(c.section == "4" and c.detail for c in claims)


def test_study_is_deterministic(study, tiny_table, scene, tmp_path):
    """Same seeds -> byte-identical part files (simulation included)."""
    objects, truth, rollouts = study
    q, c = SCORE_CFG["query_speeds"], SCORE_CFG["calibration_speeds"]
    truth2 = s4.simulate_truth(objects, q, c, scene, nthread=2)
    rollouts2 = s4.make_standins(
        objects, truth2, SMALL_CFG["standins"], SMALL_CFG["seed"], tiny_table, q, c, 1e-4, scene, nthread=2
    )
    paths = []
    for i, (t, r) in enumerate(((truth, rollouts), (truth2, rollouts2))):
        _, metrics, noise, sel, _ = run_study(tiny_table, objects, t, r)
        numbers, claims = s4.section4_part(metrics, noise, sel, SMALL_CFG)
        paths.append(tmp_path / f"part{i}.json")
        write_part(paths[-1], "section4", numbers, claims)
    assert paths[0].read_bytes() == paths[1].read_bytes()


def test_selection_config_errors(study, tiny_table):
    _, truth, rollouts = study
    bad = {**SMALL_CFG["selection"], "query_speed": 0.5}
    with pytest.raises(ValueError, match="query_speed"):
        s4.selection_study(tiny_table, truth, rollouts, bad, 1, SCORE_CFG)
    with pytest.raises(ValueError, match="jitter_draws"):
        s4.selection_study(tiny_table, truth, rollouts, {**SMALL_CFG["selection"], "k": 6}, 1, SCORE_CFG)


# -- claims ------------------------------------------------------------------------------


def _values(**over):
    v = {
        "OrSelf": 0.005, "orMassR": 0.98, "orFricR": 0.97, "JitAurocSelf": 1.0, "ColAurocSelf": 1.0, "BlSelf": 0.006,
        "BlAurocSelf": 0.7, "BlAurocAnch": 1.0, "BlErr": 0.37, "JitErr": 0.37, "BlAnch": 0.165, "JitCorr": 0.96,
        "BlCorr": 1.0, "ColSelf": 4.7, "ColAnch": 4.1, "noiseASd": 0.0, "noiseAOracle": 0.006, "noiseAJitter": 1.0,
        "noiseACollapse": 1.0, "noiseBSd": 0.2, "noiseBOracle": 0.147, "noiseBJitter": 0.91, "noiseBCollapse": 1.0,
        "noiseMax": 0.2, "noiseMaxAurocBlind": 0.78, "selPickedOracle": 98, "selAnchMiss": 1.5, "selFirstMiss": 7.1,
        "selConsMiss": 8.6, "selOracMiss": 1.6,
    }  # fmt: skip
    v.update(over)
    return {c.id: c.holds for c in s4.section4_claims(v)}


def test_claims_follow_the_results():
    assert all(_values().values())  # the paper's own numbers satisfy every check
    assert not _values(BlAurocSelf=0.95)["s4-blind-self-auroc-far-below-anchored"]
    assert not _values(selConsMiss=5.0)["s4-sel-consensus-no-better"]
    assert not _values(selPickedOracle=40)["s4-sel-anchored-picks-oracle"]
    assert not _values(noiseBOracle=0.001)["s4-noise-oracle-rises"]
    assert not _values(OrSelf=0.05)["s4-oracle-near-zero"]


# -- paper outputs -----------------------------------------------------------------------


def test_paper_values_file():
    values = {v.name: v for v in load_paper_values()}
    # every macro of the paper's preamble is there, as printed (spot checks across sections)
    assert values["BlAurocSelf"].text == "0.70" and values["BlAurocSelf"].decimals == 2
    assert values["selPickedOracle"].text == "98" and values["vjSOneSCorrAnch"].text == "0.99"
    assert values["vjCQTrack"].text == "-0.00" and values["ColSelf"].value == 4.715
    assert {v.section for v in values.values()} == {"3", "4", "5"}
    assert len(values) >= 55


def test_paper_values_errors(tmp_path):
    bad = tmp_path / "v.csv"
    bad.write_text("name,value,section\nOr1Self,0.1,4\n")
    with pytest.raises(ValueError, match="letters only"):
        load_paper_values(bad)
    bad.write_text("name,value,section\nOrSelf,abc,4\n")
    with pytest.raises(ValueError, match="not a number"):
        load_paper_values(bad)


def test_number_status():
    pv = PaperValue("x", "0.70", "4")
    assert number_status(pv, 0.704)[0] == "matches"
    assert number_status(pv, 0.75)[0] == "close"
    assert number_status(pv, 0.9)[0] == "differs"
    assert number_status(pv, None) == ("not produced", "not produced")
    assert format_value(200, "d") == "200" and format_value(float("nan"), ".2f") == "--"


def test_merge_and_report(tmp_path):
    a, b = tmp_path / "section4.json", tmp_path / "gap.json"
    write_part(a, "section4", {"OrSelf": Number(0.0051234, ".3f"), "newThing": Number(3, "d")},
               [Claim("c1", "4", "oracle small", True, "0.005")])  # fmt: skip
    write_part(b, "gap", {"BlCorr": Number(float("nan"), ".2f")}, [Claim("c2", "gap", "x fails", False, "d")])
    merged = merge_parts([b, a])
    assert merged.stages == ["gap", "section4"]
    tex = macros_tex(merged)
    assert "\\newcommand{\\OrSelf}{0.005}" in tex and "\\newcommand{\\BlCorr}{--}" in tex
    nums = numbers_json(merged)
    assert nums["OrSelf"] == 0.0051234 and nums["BlCorr"] is None and nums["newThing"] == 3
    values = [PaperValue("OrSelf", "0.005", "4"), PaperValue("vjCTrack", "0.91", "5")]
    frame = reproduction_frame(values, merged)
    assert list(frame["status"]) == ["matches", "not produced"]
    md = reproduction_md(values, merged, frame)
    assert "oracle small" in md and "FAILS" in md and "newThing" in md
    assert "produced: 1" in md and "hold: 1; fail: 1" in md
    write_part(tmp_path / "dup.json", "other", {"OrSelf": Number(0.1)}, [])
    with pytest.raises(ValueError, match="both"):
        merge_parts([a, tmp_path / "dup.json"])


def test_tables_from_numbers(tmp_path):
    numbers = {
        "OrSelf": {"value": 0.0049, "format": ".3f"}, "BlAurocSelf": {"value": 0.7012, "format": ".2f"},
        "noiseASd": {"value": 0.0, "format": "g"}, "noiseAOracle": {"value": 0.006, "format": ".3f"},
        "selAnchMiss": {"value": 1.46, "format": ".1f"}, "selPickedOracle": {"value": 97.5, "format": ".0f"},
    }  # fmt: skip
    t1 = table1_tex(numbers)
    assert "\\toprule" in t1 and "Oracle (true physics) & 0.005 & --" in t1 and "& 0.70 &" in t1
    t2 = table2_tex(numbers)
    assert "0 & 0.006" in t2 and "Lowest anchored disagreement & 1.5 & -- & 98\\%" in t2
    assert "noiseBSd" not in t2 and t2.count("\\toprule") == 2


def test_cli_errors(tmp_path, tiny_table_path):
    from imply.cli import main

    out = tmp_path / "objects.csv"
    cfg = json.dumps({"seed": 1, "objects": {**SMALL_CFG["objects"], "mass": {"min": 0.05, "max": 2.0}}})
    code = main(["section4", "objects", "--table", str(tiny_table_path), "--section4-json", cfg, "--scene-json", "{}",
                 "-o", str(out)])  # fmt: skip
    assert code == 2 and not out.exists()
    code = main(["section4", "objects", "--table", str(tiny_table_path), "--section4-json", '{"seed": 1}',
                 "--scene-json", "{}", "-o", str(out)])  # fmt: skip
    assert code == 2 and not out.exists()
    part = tmp_path / "p.json"
    part.write_text('{"stage": "x"}')
    code = main(["paper", "merge", str(part), "--macros", str(tmp_path / "m.tex"), "--numbers", str(tmp_path / "n.json"),
                 "--report-md", str(tmp_path / "r.md"), "--report-csv", str(tmp_path / "r.csv")])  # fmt: skip
    assert code == 2 and not (tmp_path / "m.tex").exists()


def test_read_part_round_trip(tmp_path):
    p = tmp_path / "s.json"
    write_part(p, "section4", {"A": Number(1.5, ".1f")}, [])
    assert read_part(p)["numbers"]["A"] == {"value": 1.5, "format": ".1f"}
    assert isinstance(pd.read_json(p, typ="series")["stage"], str)
