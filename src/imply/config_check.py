"""Checking the study's configuration in full before any job runs, and CLI settings.

The workflow calls :func:`validate_workflow_config` (:func:`check_config`, ending
Snakemake with one line on error) once, when Snakemake reads the Snakefile, so
``snakemake -n`` refuses a bad config with one line naming the key at fault instead of
a rule failing minutes into the run. Two layers:

* the JSON schema ``workflow/schemas/config.schema.yaml`` (types, bounds, and no unknown
  key at any level), written from the settings classes (:mod:`imply.workflow_config`), each
  error turned into one line with a suggestion for a misspelt key;
* rules across fields that a schema cannot state: ranges ordered, speeds inside the
  table, the selection's query speed among the query speeds, candidate effects known,
  the preset named in ``model.presets``, and the scene compiled once by MuJoCo.

:func:`check_scene` and :func:`table_grid` check the ``scene`` and ``table`` settings
that ``imply table build`` and ``imply sim`` take as JSON, without the schemas.
"""

from __future__ import annotations

import difflib
import math
import os
from pathlib import Path
from typing import Any

# the schema of the whole config, written from imply.workflow_config.StudyConfig (the settings
# classes) and held to it by a test: reading it needs none of the modules that declare them
SCHEMA_FILE = "config.schema.yaml"

# stages whose result parts the paper merge knows (config paper.stages)
# (the one list: the registry and the workflow read it here)
PAPER_STAGES = ("section4", "clips", "section5", "gap", "evaluate", "pixel")

# relative slack for "inside the table": config speeds are written in decimal
TOL = 1e-9


class ConfigError(ValueError):
    """A config value or combination the study cannot run with; the message names the key."""


def _suggest(key: str, known: list[str]) -> str:
    close = difflib.get_close_matches(key, known, n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def unknown_keys(values: dict[str, Any], known: list[str], where: str) -> None:
    """Refuse keys of ``values`` outside ``known``, naming each and the nearest known key."""
    unknown = [k for k in values if k not in known]
    if unknown:
        parts = [f"{k!r}{_suggest(str(k), known)}" for k in unknown]
        what = f"key{'s' if len(unknown) > 1 else ''} {', '.join(parts)}"
        raise ConfigError(f"{where}: unknown {what}" if where else f"unknown top-level {what}")


# -- the JSON schemas --------------------------------------------------------------


def _path(prefix: str, parts) -> str:
    if prefix.startswith("-") and parts:
        # a CLI option: "--grid-json: speeds.n"
        return f"{prefix}: {_path('', parts)}"
    out = prefix
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


def _describe(error, prefix: str) -> str:
    """One line for a jsonschema error, naming the key at fault."""
    from jsonschema.exceptions import best_match

    if error.validator in ("anyOf", "oneOf") and error.context:
        # the branch that fits the value's kind says more than "is not of type" or "not one of"
        telling = [e for e in error.context if e.validator not in ("type", "enum")]
        return _describe(best_match(telling or error.context), prefix)
    where = _path(prefix, error.absolute_path)
    if error.validator == "additionalProperties" and isinstance(error.instance, dict):
        known = list(error.schema.get("properties", {}))
        try:
            unknown_keys(error.instance, known, where)
        except ConfigError as exc:
            return str(exc)
    if error.validator == "required":
        missing = error.message.split("'")[1] if "'" in error.message else error.message
        return f"{where}: missing key {missing!r}" if where else f"missing section {missing!r}"
    message = error.message
    if len(message) > 160:
        message = message[:157] + "..."
    return f"{where or 'config'}: {message}"


# a misspelt key is both unknown and (the right one) missing: name the misspelling first
_FIRST = {"additionalProperties": 0, "required": 1}


def _first(errors: list) -> Any:
    return min(errors, key=lambda e: (len(e.absolute_path), _FIRST.get(e.validator, 2)))


def check_schemas(config: dict[str, Any], schema_dir: str | os.PathLike) -> None:
    """Validate ``config`` against ``schema_dir/config.schema.yaml``; the first error as one line."""
    import yaml

    path = Path(schema_dir) / SCHEMA_FILE
    if not path.is_file():
        raise ConfigError(f"no {SCHEMA_FILE} in {schema_dir}: cannot check the config")
    with open(path) as fh:
        # libyaml's loader where present: the schema is long, and this runs at every `snakemake -n`
        schema = yaml.load(fh, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    check_against(schema, config, "")


def check_against(schema: dict[str, Any], instance: Any, prefix: str) -> None:
    """Validate ``instance`` against a JSON ``schema``; the first error as one :class:`ConfigError` line."""
    import jsonschema

    validator = jsonschema.validators.validator_for(schema)(schema)
    errors = list(validator.iter_errors(instance))
    if errors:
        more = f" (and {len(errors) - 1} more problem{'s' if len(errors) > 2 else ''})" if len(errors) > 1 else ""
        raise ConfigError(_describe(_first(errors), prefix) + more)


# -- rules across fields --------------------------------------------------------


def _ordered(rng: dict[str, Any] | list, where: str, strict: bool = True) -> tuple[float, float]:
    lo, hi = (rng["min"], rng["max"]) if isinstance(rng, dict) else (rng[0], rng[1])
    if lo > hi or (strict and lo == hi):
        raise ConfigError(f"{where}: min {lo:g} is {'greater than' if lo > hi else 'equal to'} max {hi:g}")
    return float(lo), float(hi)


def _inside(values, lo: float, hi: float, where: str, what: str) -> None:
    for v in values if isinstance(values, list | tuple) else [values]:
        if not lo * (1 - TOL) <= v <= hi * (1 + TOL):
            raise ConfigError(f"{where}: {v:g} is outside the table's {what} range [{lo:g}, {hi:g}] (config table)")


def check_rules(config: dict[str, Any]) -> None:
    """Rules across fields; assumes the config passed :func:`check_schemas`."""
    table = config["table"]
    speeds = _ordered(table["speeds"], "table.speeds")
    masses = _ordered(table["masses"], "table.masses")
    frictions = _ordered(table["frictions"], "table.frictions")

    score = config["score"]
    for key in ("query_speeds", "calibration_speeds"):
        _inside(score[key], *speeds, f"score.{key}", "speed")
    if len(score["calibration_speeds"]) != 2:
        raise ConfigError(
            f"score.calibration_speeds: {len(score['calibration_speeds'])} speeds given; the study's anchored "
            "score and clips use exactly 2 calibration pushes"
        )

    s4 = config.get("section4")
    if s4 is not None:
        _inside(
            list(_ordered(s4["objects"]["mass"], "section4.objects.mass")), *masses, "section4.objects.mass", "mass"
        )
        _inside(
            list(_ordered(s4["objects"]["friction"], "section4.objects.friction")),
            *frictions,
            "section4.objects.friction",
            "friction",
        )
        sel = s4["selection"]
        if not any(math.isclose(sel["query_speed"], q, rel_tol=TOL) for q in score["query_speeds"]):
            listed = ", ".join(f"{q:g}" for q in score["query_speeds"])
            raise ConfigError(
                f"section4.selection.query_speed: {sel['query_speed']:g} is not one of score.query_speeds ({listed})"
            )
        if s4["standins"]["jitter_draws"] < sel["k"] - 1:
            raise ConfigError(
                f"section4.selection.k: {sel['k']} candidates need section4.standins.jitter_draws >= {sel['k'] - 1}, "
                f"not {s4['standins']['jitter_draws']}"
            )

    gap = config.get("gap")
    if gap is not None:
        from imply.diagnose.physics.candidates import ALIASES, CANDIDATES
        from imply.realworld.cases import BenchmarkConfig

        known = list(CANDIDATES)
        for name in gap.get("candidates") or []:
            if name not in CANDIDATES and name not in ALIASES:
                raise ConfigError(
                    f"gap.candidates: unknown effect {name!r}{_suggest(name, known)}; known: {', '.join(known)}"
                )
        bench = gap["benchmark"]
        try:
            design = BenchmarkConfig.from_dict(bench)
        except (TypeError, ValueError) as exc:
            raise ConfigError(str(exc)) from None
        _inside(list(design.speeds), *speeds, "gap.benchmark.speeds", "speed")
        _inside(
            list(_ordered(list(design.masses), "gap.benchmark.masses", strict=False)),
            *masses,
            "gap.benchmark.masses",
            "mass",
        )
        _inside(
            list(_ordered(list(design.frictions), "gap.benchmark.frictions", strict=False)),
            *frictions,
            "gap.benchmark.frictions",
            "friction",
        )
        gain = design.range_of("speed_gain")[1]
        offset = design.range_of("speed_offset")[1]
        lo, hi = min(design.speeds), max(design.speeds)
        if (
            lo * (1 - gain) < speeds[0] * (1 - TOL)
            or hi * (1 + gain) > speeds[1] * (1 + TOL)
            or lo - offset < speeds[0] * (1 - TOL)
            or hi + offset > speeds[1] * (1 + TOL)
        ):
            raise ConfigError(
                f"gap.benchmark.speeds: speeds {lo:g} to {hi:g} m/s with speed errors up to {gain:g} (gain) and "
                f"{offset:g} m/s (offset) leave the table's speed range [{speeds[0]:g}, {speeds[1]:g}]"
            )

    clips = config.get("clips")
    if clips is not None:
        for key in ("train_speed", "masses", "frictions", "size_scale"):
            if key in clips:
                _ordered(clips[key], f"clips.{key}", strict=False)
        if "train_speed" in clips:
            _inside([clips["train_speed"]["min"], clips["train_speed"]["max"]], *speeds, "clips.train_speed", "speed")
        times = clips["frame_times"]
        if any(b <= a for a, b in zip(times, times[1:], strict=False)):
            raise ConfigError("clips.frame_times: times must increase")
        cam = clips["camera"]
        if "x_min" in cam and "x_max" in cam and cam["x_min"] >= cam["x_max"]:
            raise ConfigError(f"clips.camera: x_min {cam['x_min']:g} is not below x_max {cam['x_max']:g}")
    enc = config.get("encoder")
    if enc is not None and enc["kind"] != "cpu" and not enc.get("weights"):
        raise ConfigError(f"encoder.weights: encoder.kind {enc['kind']!r} needs a local path to the weights")
    readout = config.get("readout")
    if readout is not None and "log10_alpha_min" in readout and "log10_alpha_max" in readout:
        if readout["log10_alpha_min"] > readout["log10_alpha_max"]:
            raise ConfigError("readout: log10_alpha_min is greater than log10_alpha_max")

    model = config.get("model")
    if model is not None and model["preset"] not in model["presets"]:
        raise ConfigError(
            f"model.preset: {model['preset']!r} is not one of model.presets ({', '.join(model['presets'])})"
            f"{_suggest(model['preset'], list(model['presets']))}"
        )
    if model is not None:
        _check_model_inputs(model, config.get("clips"), enc)
    paper = config.get("paper")
    if paper is not None:
        for stage in paper.get("stages", []):
            if stage not in PAPER_STAGES:
                raise ConfigError(
                    f"paper.stages: unknown stage {stage!r}{_suggest(stage, list(PAPER_STAGES))}; "
                    f"known: {', '.join(PAPER_STAGES)}"
                )
    check_scene(config["scene"], compile_model=True, where="scene")


def _check_model_inputs(model: dict[str, Any], clips: dict[str, Any] | None, enc: dict[str, Any] | None) -> None:
    """The predictor's sequence layouts, and its token grid against the CPU encoder's patch grid."""
    from imply.models.config import Layout

    for name, variant in model["variants"].items():
        try:
            Layout.from_dict(variant, f"model.variants.{name}")
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
    grid = model.get("token_grid")
    if grid and clips is not None and enc is not None and enc["kind"] == "cpu" and not enc.get("pool_grid"):
        from imply.models.config import PRESETS, ViTConfig

        arch = enc.get("cpu_arch")
        patch = (
            arch.get("patch_size", ViTConfig.patch_size)
            if isinstance(arch, dict)
            else (PRESETS[arch].patch_size if arch in PRESETS else None)
        )
        cam = clips.get("camera", {})
        if patch and "height" in cam and "width" in cam:
            rows, cols = cam["height"] // patch, cam["width"] // patch
            if rows % grid[0] or cols % grid[1]:
                raise ConfigError(
                    f"model.token_grid: {grid[0]} x {grid[1]} does not divide the CPU encoder's {rows} x {cols}"
                    f" patch grid (clips.camera {cam['height']} x {cam['width']} px, {patch} px patches)"
                )


def check_config(config: dict[str, Any], schema_dir: str | os.PathLike) -> None:
    """The whole study config: schemas, the rules across fields, then released weights. Raises :class:`ConfigError`."""
    if not isinstance(config, dict):
        raise ConfigError("config: expected a mapping of sections")
    check_schemas(config, schema_dir)
    check_rules(config)
    check_weights(config)


def check_weights(config: dict[str, Any]) -> None:
    """Released encoder weights (``encoder.weights``) present and a checkpoint of ``encoder.kind``."""
    from imply.models.weights import check_encoder_weights  # imports torch only for released weights

    try:
        check_encoder_weights(config["encoder"])
    except ValueError as exc:
        raise ConfigError(" ".join(str(exc).split())) from None


def validate_workflow_config(config: dict[str, Any], schema_dir: str | os.PathLike) -> None:
    """:func:`check_config` for the Snakefile: a bad config ends Snakemake with one line."""
    try:
        check_config(config, schema_dir)
    except ConfigError as exc:
        raise SystemExit(f"config error: {exc}") from None


# -- CLI settings -------------------------------------------------------------------


def check_scene(cfg: Any, compile_model: bool = False, where: str = "--scene-json"):
    """A :class:`imply.sim.SceneConfig` from settings, refused with one line if any is bad.

    The dataclass checks its own values; this adds the names of unknown keys with a
    suggestion, and refuses a timestep that is not a positive number up front (a zero
    or negative one makes a push that never ends). ``compile_model`` also builds the
    scene once, which catches ``option`` attributes MuJoCo does not know.
    """
    from dataclasses import fields

    from imply.sim.scene import SceneConfig, build_model

    if cfg is None:
        cfg = {}
    if not isinstance(cfg, dict):
        raise ConfigError(f"{where}: expected a JSON object of scene settings, not {type(cfg).__name__}")
    unknown_keys(cfg, [f.name for f in fields(SceneConfig)], where)
    if "timestep" in cfg and not (_number(cfg["timestep"]) and cfg["timestep"] > 0):
        raise ConfigError(f"{where}: timestep must be a positive number of seconds, not {cfg['timestep']!r}")
    try:
        scene = SceneConfig.from_dict(cfg)
        if compile_model:
            build_model(scene)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where}: {' '.join(str(exc).split())}") from exc
    return scene


def _number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def table_grid(cfg: Any, where: str = "--grid-json"):
    """A :class:`imply.table.TableGrid` from the ``table`` settings, refused with one line if bad.

    Types, bounds and keys come from :class:`imply.table.TableConfig`'s schema; this adds
    the rule the schema cannot state (each axis's min below its max).
    """
    from imply.options import json_schema
    from imply.table import TableConfig

    if not isinstance(cfg, dict):
        raise ConfigError(f"{where}: expected a JSON object with speeds, masses and frictions")
    check_against(json_schema(TableConfig), cfg, where)
    for axis in ("speeds", "masses", "frictions"):
        _ordered(cfg[axis], f"{where}: {axis}")
    return TableConfig.from_dict(cfg, where).grid()
