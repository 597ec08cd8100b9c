"""The contact benchmark's worlds (imply.realworld.contact): contact models of their own, another engine, four directions."""

from __future__ import annotations

import json
import sys
import types

import mujoco
import numpy as np
import pytest

from imply.cli import main
from imply.realworld import cases as C
from imply.realworld.contact import BULLET_EFFECTS, CONTACT_KINDS, CONTACT_PARAMETERS, apply_contact
from imply.realworld.world import PARAMETERS, WorldPushes, WorldResult, simulate_world

# the world's pushes before the contact parameters existed (commit 3327312, MuJoCo 4.0.0), as float.hex:
# a plain push, a fast heavy one, one under Stribeck friction, one with viscous friction on a tilted table
BEFORE_MUJOCO = "4.0.0"
BEFORE_DISPLACEMENT = ["0x1.b85c724367829p-6", "0x1.371ad525d6713p-4", "0x1.0a5d88721dbc2p-4", "0x1.4832b31afc689p-5"]
BEFORE_STOP_TIME = ["0x1.9251e620031e1p-3", "0x1.b1cb67567bf78p-3", "0x1.e2acf4ca08c19p-3", "0x1.2b825add958f3p-3"]


@pytest.mark.skipif(mujoco.__version__ != BEFORE_MUJOCO, reason="the recorded bytes are MuJoCo 4.0.0's")
def test_nominal_contact_reproduces_the_world_before_it_bit_for_bit(scene):
    p = WorldPushes.nominal(
        [0.2, 0.9, 0.5, 0.6], [0.3, 1.2, 0.5, 1.0], [0.15, 0.4, 0.25, 0.5], [0.0, 1.0, 2.0, 3.0], scene
    )
    p.params["stribeck"][2] = 0.5
    p.params["viscous"][3] = 0.4
    p.params["tilt"][3] = 0.01
    res = simulate_world(p, scene, nthread=1)
    assert [float(x).hex() for x in res.displacement] == BEFORE_DISPLACEMENT
    assert [float(x).hex() for x in res.stop_time] == BEFORE_STOP_TIME


SPEEDS = np.array([0.2, 0.9, 0.2, 0.9])
MASSES = np.array([0.5, 0.5, 1.5, 1.5])
FRICTIONS = np.array([0.5, 0.5, 0.3, 0.3])
SLOW, FAST = SPEEDS < 0.5, SPEEDS > 0.5


def _log_ratio(scene, base, **params) -> tuple[np.ndarray, WorldResult]:
    p = WorldPushes.nominal(SPEEDS, MASSES, FRICTIONS, 0.3, scene)
    apply_contact(p, {"parameters": params})
    res = simulate_world(p, scene, nthread=2)
    assert res.ok.all(), params
    return np.log(res.displacement / base.displacement), res


def test_each_contact_parameter_changes_the_push_its_own_way(scene):
    base = simulate_world(WorldPushes.nominal(SPEEDS, MASSES, FRICTIONS, 0.3, scene), scene, nthread=2)
    # friction rising with speed (k > 0) shortens fast slides more than slow ones; falling (k < 0) lengthens them
    up, _ = _log_ratio(scene, base, friction_slope=0.8)
    down, _ = _log_ratio(scene, base, friction_slope=-0.5)
    assert np.all(up < 0) and up[FAST].mean() < up[SLOW].mean() - 0.05, up
    assert np.all(down > 0) and down[FAST].mean() > down[SLOW].mean() + 0.05, down
    # regularised friction is weaker near zero slip: every slide is longer, and the slow ones by more
    reg, res = _log_ratio(scene, base, friction_regularisation=0.15, friction_rest_share=0.4)
    assert np.all(reg > 0.01) and reg[SLOW].mean() > reg[FAST].mean(), reg
    assert np.all(res.stop_time > base.stop_time)
    # a softer table contact lets the box slide further; a stiffer one changes it far less
    soft, _ = _log_ratio(scene, base, table_timeconst=5.0)
    stiff, _ = _log_ratio(scene, base, table_timeconst=0.25)
    assert soft.mean() > 0.03 and np.abs(stiff).mean() < soft.mean(), (soft, stiff)
    # an underdamped table contact: the box bounces as it is pushed, the slide changes
    bouncy, _ = _log_ratio(scene, base, table_dampratio=0.3)
    assert np.abs(bouncy).max() > 0.02, bouncy
    # a pusher that sinks further into the box (lower impedance) hands over less of a fast push
    sink, _ = _log_ratio(scene, base, pusher_impedance=0.3)
    assert np.all(sink < 0) and sink[FAST].mean() < sink[SLOW].mean() - 0.05, sink
    # friction on the pusher's face: the box can no longer slip along it as it rocks
    grip, _ = _log_ratio(scene, base, pusher_friction=0.8)
    assert np.abs(grip).max() > 0.02, grip


def test_contact_parameters_are_world_parameters(scene):
    assert set(CONTACT_PARAMETERS) <= set(PARAMETERS)
    assert {p for kind in CONTACT_KINDS.values() for p in kind} == set(CONTACT_PARAMETERS)
    with pytest.raises(KeyError, match="unknown contact parameter"):
        apply_contact(WorldPushes.nominal(0.5, 0.5, 0.3, 0.0, scene), {"parameters": {"tilt": 0.1}})


DESIGN = {
    "seed": 5,
    "logs": {
        "null_contact": 3,
        "single_contact": 3,
        "outside_contact": 2,
        "null_engine": 1,
        "single_engine": 2,
        "outside_engine": 1,
    },
    "n_objects": 3,
    "speeds": [0.3, 0.6, 0.9],
    "four_share": 0.5,
}


def test_contact_cases_are_drawn_reproducibly_from_the_configured_ranges():
    design = C.ContactBenchmarkConfig.from_dict(DESIGN)
    a, b = C.draw_cases(design), C.draw_cases(design)
    assert a == b
    assert C.draw_cases(C.ContactBenchmarkConfig.from_dict({**DESIGN, "seed": 6})) != a
    assert [c["id"] for c in a] == C.case_ids(design)
    groups = sorted(c["group"] for c in a)
    assert groups == sorted(g for g, n in DESIGN["logs"].items() for _ in range(n))
    draw = design.contact
    for c in a:
        assert (c["engine"] == "bullet") == c["group"].endswith("_engine")
        assert len(c["effects"]) == (0 if c["group"].startswith("null") else 1)
        if c["engine"] == "bullet":
            assert c["contact"] == {"kinds": [], "parameters": {}}
            assert all(e["name"] in BULLET_EFFECTS for e in c["effects"])
            continue
        lo, hi = draw.per_log
        assert lo <= len(c["contact"]["kinds"]) <= hi
        assert set(c["contact"]["parameters"]) == {p for k in c["contact"]["kinds"] for p in CONTACT_KINDS[k]}
        for name, x in c["contact"]["parameters"].items():
            a_, b_ = draw.ranges[name]
            x = abs(x)
            assert a_ <= x <= b_ or (name == "table_timeconst" and a_ <= 1 / x <= b_), (name, x)
        for e in c["effects"]:
            top = design.range_of(e["name"])[1]
            assert design.effect_range[0] * top <= abs(e["magnitude"]) <= design.effect_range[1] * top
    assert {c["design"] for c in a} == {"four", "random"}


def test_four_directions_are_90_degrees_apart_for_every_object_and_speed():
    design = C.ContactBenchmarkConfig.from_dict({**DESIGN, "four_share": 1.0})
    for case in C.draw_cases(design):
        obj, v = C.push_layout(case, design)
        phi = np.asarray(case["direction"])
        assert phi.size == obj.size == 3 * 3 * 4
        rotations = set()
        for i in range(3):
            for s in design.speeds:
                mine = np.sort(phi[(obj == i) & (v == s)])
                assert mine.size == 4
                np.testing.assert_allclose(np.diff(mine), np.pi / 2, atol=1e-9)
                rotations.add(round(float(mine[0] % (np.pi / 2)), 9))
        assert len(rotations) == 1  # one rotation per log
    random = C.ContactBenchmarkConfig.from_dict({**DESIGN, "four_share": 0.0})
    assert all(len(c["direction"]) == 9 and c["design"] == "random" for c in C.draw_cases(random))


def test_an_engine_case_runs_in_the_bullet_world(scene, monkeypatch):
    calls = []

    def simulate_bullet(pushes, scene_, stepping=None, *, progress=False, track_times=None):
        calls.append(pushes)
        n = pushes.n
        # a world that slides the box as far as it is pushed fast: distinguishable from MuJoCo's
        return WorldResult(
            0.05 * pushes.speed,
            np.zeros(n),
            np.full(n, 0.3),
            np.ones(n, bool),
            np.ones(n, np.int64),
            0.01 / pushes.speed,
        )

    monkeypatch.setitem(sys.modules, "imply.realworld.bullet", types.SimpleNamespace(simulate_bullet=simulate_bullet))
    design = C.ContactBenchmarkConfig.from_dict(DESIGN)
    case = next(c for c in C.draw_cases(design) if c["group"] == "single_engine")
    sims = C.simulate_cases([case], design, scene)
    assert len(calls) == 1 and calls[0].n == 2 * len(C.push_layout(case, design)[0])  # with the effect and without
    assert set(sims[case["id"]]) == {"all", "contact"}
    obj, v = C.push_layout(case, design)
    if case["effects"][0]["name"] not in ("speed_gain", "speed_offset"):
        np.testing.assert_allclose(sims[case["id"]]["all"]["displacement"], 0.05 * v)
    np.testing.assert_allclose(sims[case["id"]]["contact"]["displacement"], 0.05 * v)
    frame, label = C.make_log(case, sims[case["id"]], design, scene)
    assert label["engine"] == "bullet" and label["design"] == case["design"]
    assert set(label["noise_free"]) == {"all", "contact"}
    assert len(frame) == 2 * v.size


def test_generate_writes_contact_logs_with_their_labels(tmp_path, tiny_table_path):
    design = {
        "seed": 1,
        "logs": {"null_contact": 1, "outside_contact": 1},
        "n_objects": 2,
        "speeds": [0.4, 0.8],
        "four_share": 0.0,
        "accuracy": {"pushes": 1, "nominal": 1},
    }
    args = [
        "study",
        "gap",
        "generate",
        "--table",
        str(tiny_table_path),
        "--contact-bench-json",
        json.dumps(design),
        "--logs",
        str(tmp_path / "logs"),
        "--sealed",
        str(tmp_path / "s.json"),
        "--accuracy",
        str(tmp_path / "a.json"),
    ]
    assert main(args) == 0
    labels = json.loads((tmp_path / "s.json").read_text())
    assert sorted(labels) == ["log-000", "log-001"] and sorted(p.name for p in (tmp_path / "logs").iterdir()) == [
        "log-000.csv",
        "log-000.track.csv",
        "log-001.csv",
        "log-001.track.csv",
    ]
    for label in labels.values():
        assert label["engine"] == "mujoco" and label["contact"]["kinds"] and label["design"] == "random"
        assert set(label["noise_free"]) == ({"all"} if label["group"] == "null_contact" else {"all", "contact"})
    finer = json.loads((tmp_path / "a.json").read_text())["against_finer"]
    assert finer["log_d"]["n"] >= 1
    # the push behind the largest difference is named, with what sets it apart from the nominal world
    assert abs(finer["worst"]["log_d_difference"]) == finer["log_d"]["max_abs"] and "parameters" in finer["worst"]


@pytest.mark.parametrize(
    "edit, message",
    [
        ({"logs": {"null": 3}}, "gap.contact_benchmark.logs: unknown key(s) null"),
        ({"contact": {"per_log": [3, 9]}}, "per_log must be [low, high]"),
        ({"contact": {"kinds": ["sticky"]}}, "sticky"),
        ({"targets": {"top1": 0.9}}, "gap.contact_benchmark.targets: unknown key(s) top1"),
    ],
)
def test_bad_contact_design_is_one_line(tmp_path, tiny_table_path, capsys, edit, message):
    args = [
        "study",
        "gap",
        "generate",
        "--table",
        str(tiny_table_path),
        "--contact-bench-json",
        json.dumps({**DESIGN, **edit}),
        "--logs",
        str(tmp_path / "logs"),
        "--sealed",
        str(tmp_path / "s.json"),
        "--accuracy",
        str(tmp_path / "a.json"),
    ]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "logs").exists()
