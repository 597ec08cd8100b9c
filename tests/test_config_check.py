"""The config is checked in full before any job runs: schemas at every level, then rules across fields."""

from __future__ import annotations

import copy

import pytest
import yaml

from imply.config_check import ConfigError, check_config
from workflow_helpers import ROOT, copy_workflow, snakemake

SCHEMAS = ROOT / "workflow" / "schemas"


@pytest.fixture(scope="module")
def config() -> dict:
    return yaml.safe_load((ROOT / "config.yaml").read_text())


def _set(cfg: dict, dotted: str, value) -> dict:
    cfg = copy.deepcopy(cfg)
    *parents, last = dotted.split(".")
    node = cfg
    for key in parents:
        node = node[key]
    node[last] = value
    return cfg


def test_the_shipped_config_and_the_test_configs_pass(config):
    from snakemake.utils import update_config

    check_config(config, SCHEMAS)
    for path in sorted((ROOT / "tests" / "config").glob("*.yaml")):
        cfg = copy.deepcopy(config)
        update_config(cfg, yaml.safe_load(path.read_text()))
        check_config(cfg, SCHEMAS)


def _renamed(cfg: dict, old: str, new: str) -> dict:
    cfg = copy.deepcopy(cfg)
    cfg[new] = cfg.pop(old)
    return cfg


# (id, edit of the shipped config, expected part of the message)
BAD = [
    (
        "unknown-section",
        lambda c: {**c, "sectoin4": {"seed": 1}},
        "unknown top-level key 'sectoin4' (did you mean 'section4'?)",
    ),
    ("unknown-top-key", lambda c: {**c, "thread": 3}, "unknown top-level key 'thread' (did you mean 'threads'?)"),
    ("misspelt-section", lambda c: _renamed(c, "section4", "sectoin4"), "unknown top-level key 'sectoin4'"),
    ("missing-section", lambda c: {k: v for k, v in c.items() if k != "gap"}, "missing section 'gap'"),
    (
        "nested-unknown",
        lambda c: _set(c, "section4.selection.kk", 3),
        "section4.selection: unknown key 'kk' (did you mean 'k'?)",
    ),
    (
        "deep-unknown",
        lambda c: _set(c, "gap.benchmark.targets.top_1", 0.9),
        "gap.benchmark.targets: unknown key 'top_1'",
    ),
    ("clips-camera-unknown", lambda c: _set(c, "clips.camera.hieght", 32), "clips.camera: unknown key 'hieght'"),
    (
        "model-train-unknown",
        lambda c: _set(c, "model.train.epoch", 3),
        "model.train: unknown key 'epoch' (did you mean 'epochs'?)",
    ),
    (
        "noise-unknown",
        lambda c: _set(c, "gap.benchmark.noise.heavy_sdd", 0.3),
        "gap.benchmark.noise: unknown key 'heavy_sdd' (did you mean 'heavy_sd'?)",
    ),
    ("logs-unknown", lambda c: _set(c, "gap.benchmark.logs.nul", 3), "gap.benchmark.logs: unknown key 'nul'"),
    ("encoder-arch", lambda c: _set(c, "encoder.cpu_arch", {"depht": 2}), "encoder.cpu_arch: unknown key 'depht'"),
    ("type", lambda c: _set(c, "score.grid", "fine"), "score.grid: 'fine' is not of type 'integer'"),
    ("bound", lambda c: _set(c, "score.grid", 3), "score.grid: 3 is less than the minimum of 11"),
    (
        "masses-order",
        lambda c: _set(c, "table.masses", {"min": 2.0, "max": 0.2, "n": 25}),
        "table.masses: min 2 is greater than max 0.2",
    ),
    (
        "speeds-equal",
        lambda c: _set(c, "table.speeds", {"min": 0.5, "max": 0.5, "n": 5}),
        "table.speeds: min 0.5 is equal to max 0.5",
    ),
    (
        "query-outside",
        lambda c: _set(c, "score.query_speeds", [0.1, 0.55]),
        "score.query_speeds: 0.1 is outside the table's speed range",
    ),
    (
        "calibration-outside",
        lambda c: _set(c, "score.calibration_speeds", [0.3, 1.2]),
        "score.calibration_speeds: 1.2 is outside",
    ),
    ("query-repeated", lambda c: _set(c, "score.query_speeds", [0.25, 0.55, 0.55]), "score.query_speeds"),
    (
        "selection-speed",
        lambda c: _set(c, "section4.selection.query_speed", 0.5),
        "section4.selection.query_speed: 0.5 is not one of score.query_speeds",
    ),
    (
        "selection-k",
        lambda c: _set(c, "section4.selection.k", 6),
        "section4.selection.k: 6 candidates need section4.standins.jitter_draws >= 5",
    ),
    (
        "objects-mass",
        lambda c: _set(c, "section4.objects.mass", {"min": 0.1, "max": 2.0}),
        "section4.objects.mass: 0.1 is outside the table's mass range",
    ),
    (
        "objects-order",
        lambda c: _set(c, "section4.objects.friction", {"min": 0.5, "max": 0.2}),
        "section4.objects.friction: min 0.5 is greater than max 0.2",
    ),
    (
        "candidates",
        lambda c: _set(c, "gap.candidates", ["tlit", "viscous"]),
        "gap.candidates: unknown effect 'tlit' (did you mean 'tilt'?)",
    ),
    (
        "benchmark-ranges",
        lambda c: _set(c, "gap.benchmark.ranges", {"visocus": [0.1, 1.0]}),
        "gap.benchmark: ranges: unknown effect(s) visocus",
    ),
    ("benchmark-speeds", lambda c: _set(c, "gap.benchmark.speeds", [0.25, 2.0]), "gap.benchmark.speeds: 2 is outside"),
    ("benchmark-speed-room", lambda c: _set(c, "gap.benchmark.speeds", [0.15, 0.9]), "leave the table's speed range"),
    (
        "clips-range",
        lambda c: _set(c, "clips.train_speed", {"min": 0.9, "max": 0.2}),
        "clips.train_speed: min 0.9 is greater than max 0.2",
    ),
    ("frame-times", lambda c: _set(c, "clips.frame_times", [0.0, 0.1, 0.05]), "clips.frame_times: times must increase"),
    (
        "encoder-weights",
        lambda c: _set(c, "encoder.kind", "vjepa2_pt"),
        "encoder.weights: encoder.kind 'vjepa2_pt' needs a local path",
    ),
    (
        "query-frames",
        lambda c: _set(c, "model.variants.calib.query_frames", [0, 1, 4]),
        "model.variants.calib: query_frames [0, 1, 4] must increase and end at the clip's last frame (7)",
    ),
    (
        "token-grid",
        lambda c: _set(c, "model.token_grid", [3, 8]),
        "model.token_grid: 3 x 8 does not divide the CPU encoder's 2 x 8 patch grid",
    ),
    ("model-readout", lambda c: _set(c, "model.readout", "rollouts"), "model: unknown key 'readout'"),
    (
        "suite-split",
        lambda c: _set(c, "suite.split", "validation"),
        "suite.split: 'validation' is not one of ['heldout_calib', 'heldout_nocalib']",
    ),
    (
        "preset",
        lambda c: _set(c, "model.preset", "tiyn"),
        "model.preset: 'tiyn' is not one of model.presets (tiny, vitg-300m) (did you mean 'tiny'?)",
    ),
    ("paper-stage", lambda c: {**c, "paper": {"stages": ["sectoin4"]}}, "paper.stages: unknown stage 'sectoin4'"),
    (
        "timestep",
        lambda c: _set(c, "scene.timestep", -1),
        "scene.timestep: -1 is less than or equal to the minimum of 0",
    ),
    ("scene-option", lambda c: _set(c, "scene.option", {"gravty": "0 0 -9.81"}), "unrecognized attribute: 'gravty'"),
]


@pytest.mark.parametrize("edit, expected", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_config_is_refused_in_one_line_naming_the_key(config, edit, expected):
    with pytest.raises(ConfigError) as err:
        check_config(edit(config), SCHEMAS)
    message = str(err.value)
    assert expected in message
    assert "\n" not in message


@pytest.fixture(scope="module")
def workflow_copy(tmp_path_factory):
    return copy_workflow(tmp_path_factory.mktemp("wf"))


@pytest.mark.parametrize(
    "override, expected",
    [
        ("sectoin4:\n  seed: 1\n", "config error: unknown top-level key 'sectoin4' (did you mean 'section4'?)"),
        ("thread: 3\n", "config error: unknown top-level key 'thread' (did you mean 'threads'?)"),
        ("table:\n  masses: {min: 2.0, max: 0.2}\n", "config error: table.masses: min 2 is greater than max 0.2"),
        ("score:\n  query_speeds: [0.1, 0.55]\n", "config error: score.query_speeds: 0.1 is outside"),
        ("section4:\n  selection: {query_speed: 0.5}\n", "config error: section4.selection.query_speed: 0.5"),
    ],
    ids=["unknown-section", "unknown-key", "ranges", "query-speed", "selection-speed"],
)
def test_snakemake_dry_run_refuses_a_bad_configfile(workflow_copy, tmp_path, override, expected, forked_imply):
    bad = tmp_path / "bad.yaml"
    bad.write_text(override)
    proc = snakemake(workflow_copy, "-n", "--configfile", str(bad), check=False)
    assert proc.returncode != 0
    lines = [ln for ln in (proc.stdout + proc.stderr).splitlines() if "config error" in ln]
    assert lines == [expected] or (len(lines) == 1 and lines[0].startswith(expected)), proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and "KeyError" not in proc.stderr


def test_snakemake_dry_run_names_a_typo_in_config_yaml(tmp_path, forked_imply):
    work = copy_workflow(tmp_path / "wf")
    text = (work / "config.yaml").read_text()
    (work / "config.yaml").write_text(text.replace("\nsection4:", "\nsectoin4:"))
    proc = snakemake(work, "-n", check=False)
    assert proc.returncode != 0
    assert "config error: unknown top-level key 'sectoin4' (did you mean 'section4'?)" in proc.stderr
    assert "KeyError" not in proc.stderr
