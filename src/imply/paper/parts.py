"""Per-stage result parts that the paper rule merges into macros, numbers and the report.

Each study stage has one part, ``results/paper/parts/<stage>.json``, built by
:func:`build_part` from the stage's result documents (:mod:`imply.paper.results`)::

    {"stage": "section4",
     "numbers": {"BlAurocSelf": 0.7012, ...},
     "claims": [{"id": "s4-blind-self-auroc", "section": "4",
                 "statement": "...", "holds": true, "detail": "self 0.70 vs anchored 1.00"}]}

Every registered number of the stage (:mod:`imply.paper.registry`) is read from the
result of its ``source`` function at its ``path``, unrounded; the stage's claims are
checked on those values by the stage's claims function, which the caller passes in
(``imply study paper part`` takes it from :func:`imply.cli.paper.stage_claims`), so this module
imports no study code.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

from imply.io import write_json
from imply.paper.registry import STAGES, load_registry
from imply.results import NOT_PRODUCED, Claim, Registry, Values

# a stage's claims: checked on the stage's values, with its result documents (producer -> result) at hand
ClaimsFunction = Callable[[Values, Mapping[str, Any]], list[Claim]]


def stage_numbers(stage: str, results: Mapping[str, Any], registry: Registry | None = None) -> dict[str, Any]:
    """Every registered number of ``stage`` read from ``results`` (source -> result); name -> value."""
    registry = registry or load_registry()
    numbers: dict[str, Any] = {}
    for entry in registry.of_stage(stage):
        value = entry.resolve(results)
        if value is not NOT_PRODUCED:
            numbers[entry.name] = value
    return numbers


def build_part(
    stage: str, results: Mapping[str, Any], *, claims: ClaimsFunction, registry: Registry | None = None
) -> tuple[dict[str, Any], list[Claim]]:
    """The numbers and checked claims of a stage's part; ``claims`` is the stage's claims function."""
    if stage not in STAGES:
        raise ValueError(f"unknown stage {stage!r} (one of {', '.join(STAGES)})")
    registry = registry or load_registry()
    numbers = stage_numbers(stage, results, registry)
    return numbers, claims(registry.values(numbers), results)


def write_part(
    path: str | os.PathLike,
    *,
    stage: str,
    numbers: Mapping[str, Any],
    claims: list[Claim],
    registry: Registry | None = None,
    read_by: str | None = None,
) -> None:
    """Write a stage's part file; every name must be registered to that stage.

    ``read_by``: which instrument read the rollouts behind the stage's numbers (Section 5:
    the readout of each ``imply evaluate`` report), shown beside each of them in the report.
    """
    registry = registry or load_registry()
    for name, value in numbers.items():
        entry = registry[name]
        if entry.stage != stage:
            raise ValueError(f"number {name!r} is registered to stage {entry.stage!r}, not {stage!r}")
        if not isinstance(value, int | float) or isinstance(value, bool):
            raise TypeError(f"number {name!r} is not a number: {value!r}")
        if isinstance(value, float) and not math.isfinite(value):
            # a NaN is a result too (e.g. an undefined correlation): it stays visible as null
            pass
    payload: dict[str, Any] = {
        "stage": stage,
        "numbers": dict(sorted(numbers.items())),
        "claims": [asdict(c) for c in claims],
    }
    if read_by:
        payload["read_by"] = read_by
    write_json(path, payload)


def read_part(path: str | os.PathLike) -> dict[str, Any]:
    with open(Path(path)) as fh:
        part = json.load(fh)
    for key in ("stage", "numbers", "claims"):
        if key not in part:
            raise ValueError(f"{path}: not a result part (missing {key!r})")
    return part
