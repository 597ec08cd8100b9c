"""One source per option: the settings classes against config.yaml, the schema file, the CLI flags and the comments."""

from __future__ import annotations

import argparse
import importlib
import re
from typing import ClassVar

import pytest
import yaml

from imply.options import Config, default_of, json_schema, option
from imply.workflow_config import StudyConfig, schema_text
from workflow_helpers import ROOT

# keys config.yaml leaves out: the workflow passes no value, so the class's default acts
LEFT_TO_THE_DEFAULT = {
    "encoder.pretrain.min_lr",
    "gap.benchmark.ranges",
    "gap.benchmark.stepping",
    "gap.benchmark.stribeck_speed",
    "gap.contact_benchmark.double_range",
    "gap.contact_benchmark.ranges",
    "gap.contact_benchmark.stepping",
    "gap.contact_benchmark.stribeck_speed",
    "gap.diagnose.model_floor",
    "gap.lab_benchmark.accuracy",
    "gap.lab_benchmark.double_range",
    "gap.lab_benchmark.ranges",
    "gap.lab_benchmark.sapien",
    "gap.lab_benchmark.stepping",
    "gap.lab_benchmark.stribeck_speed",
    "gap.lab_benchmark.targets",
    "gap.diagnose.noise_sd",
    "gap.diagnose.pusher_speed_noise_sd",
    "gap.diagnose.track_noise_sd",
    "gap.diagnose.scan",
    "gap.diagnose.stop_time_floor",
    "gap.diagnose.stop_time_noise_sd",
    "gap.diagnose.use_measured",
    "gap.effect_grid.floor_pushes",
    "model.presets.tiny.rope_theta",
    "model.presets.vitg-300m.rope_theta",
    "model.train.beta1",
    "model.train.beta2",
    "model.variants.calib.n_frames",
    "model.variants.nocalib.calib_frames",
    "model.variants.nocalib.n_frames",
    "paper",
    "scene.friction",
    "scene.mass",
    "scene.option",
}
# keys config.yaml sets in another place on purpose, with the reason
SET_ELSEWHERE = {
    "model.variants.calib.rest_state": "one value for every variant: model.rest_state, which the rules pass in",
    "model.variants.nocalib.rest_state": "one value for every variant: model.rest_state, which the rules pass in",
}


def _differences(study: object, defaults: object, path: str = "") -> list[str]:
    if isinstance(study, dict) and isinstance(defaults, dict):
        out = []
        for key in sorted(set(study) | set(defaults)):
            where = f"{path}{key}"
            if key not in study:
                if where not in LEFT_TO_THE_DEFAULT and where not in SET_ELSEWHERE:
                    out.append(f"{where}: config.yaml lacks it (class default {defaults[key]!r})")
            elif key not in defaults:
                out.append(f"{where}: no field of that name")
            else:
                out += _differences(study[key], defaults[key], f"{where}.")
        return out
    return [] if study == defaults else [f"{path.rstrip('.')}: config.yaml {study!r}, class default {defaults!r}"]


def test_every_section_of_config_yaml_equals_its_classes_defaults():
    study = yaml.safe_load((ROOT / "config.yaml").read_text())
    assert _differences(study, StudyConfig().to_dict()) == []


def test_config_yaml_builds_the_study_settings():
    study = yaml.safe_load((ROOT / "config.yaml").read_text())
    assert StudyConfig.from_dict(study) == StudyConfig()


def test_the_schema_file_is_the_one_written_from_the_classes():
    """Regenerate with `python -m imply.workflow_config workflow/schemas/config.schema.yaml`."""
    assert (ROOT / "workflow" / "schemas" / "config.schema.yaml").read_text() == schema_text()
    assert sorted(p.name for p in (ROOT / "workflow" / "schemas").iterdir()) == ["config.schema.yaml"]


def test_cli_flags_default_to_the_study_values():
    from imply.cli import build_parser
    from imply.models.config import ModelConfig
    from imply.score import ScoreConfig

    parser = build_parser()

    def defaults(*command: str) -> dict:
        sub = parser
        for name in command:
            sub = next(a for a in sub._actions if isinstance(a, argparse._SubParsersAction))._name_parser_map[name]
        return {a.dest: a.default for a in sub._actions}

    model = ModelConfig()
    assert defaults("study", "model", "rollout")["derangement_seed"] == model.derangement_seed == 11
    assert defaults("study", "model", "rollout")["batch_size"] == model.rollout_batch
    assert defaults("study", "model", "train")["rest_state"] == model.rest_state
    assert defaults("study", "model", "train")["device"] == model.device
    assert defaults("study", "section5")["selection_seed"] == model.selection_seed == 12
    score = defaults("score")
    assert (score["grid"], score["floor"]) == (ScoreConfig().grid, ScoreConfig().readout_floor)


# dotted names of the package, e.g. imply.diagnose.physics.candidates.CANDIDATES
DOTTED = re.compile(r"\bimply(?:\.[A-Za-z_][A-Za-z0-9_]*)+")


def _resolves(dotted: str) -> bool:
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


@pytest.mark.parametrize("path", ["config.yaml", "workflow/schemas/config.schema.yaml"])
def test_every_name_the_config_and_schema_mention_exists(path):
    names = sorted(set(DOTTED.findall((ROOT / path).read_text())))
    assert names, path
    assert [n for n in names if not _resolves(n)] == []


def test_every_field_has_a_doc_line():
    schema = json_schema(StudyConfig)

    def undocumented(node: dict, where: str) -> list[str]:
        out = []
        for name, prop in node.get("properties", {}).items():
            if "description" not in prop and node.get("additionalProperties") is False and "$ref" not in prop:
                out.append(f"{where}.{name}")
        return out

    missing = undocumented(schema, "config")
    for name, node in schema["$defs"].items():
        missing += undocumented(node, name)
    assert missing == []


def test_bounds_are_checked_by_the_class_and_stated_in_the_schema():
    from dataclasses import dataclass

    @dataclass(frozen=True, kw_only=True)
    class Example(Config):
        config_key: ClassVar[str] = "example"

        n: int = option(3, doc="points", minimum=2)
        sizes: tuple[float, ...] = option((1.0,), doc="sizes", items={"exclusive_minimum": 0})
        kind: str = option("a", doc="which", choices=("a", "b"))

    assert Example.from_dict({"n": 2}).n == 2
    for bad, message in [
        ({"n": 1}, "example.n: 1 is less than the minimum of 2"),
        ({"sizes": [1.0, 0.0]}, "example.sizes: 0 is less than or equal to the minimum of 0"),
        ({"kind": "c"}, "example.kind: 'c' is not one of ['a', 'b']"),
    ]:
        with pytest.raises(ValueError, match=re.escape(message)):
            Example.from_dict(bad)
    props = json_schema(Example)["properties"]
    assert props["n"] == {"description": "points", "type": "integer", "minimum": 2}
    assert props["sizes"]["items"] == {"type": "number", "exclusiveMinimum": 0}
    assert props["kind"]["enum"] == ["a", "b"]
    assert default_of(Example, "sizes") == (1.0,)
