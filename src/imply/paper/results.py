"""Result documents: what a study step computed, labelled with the function that computed it.

A step writes its result (a frozen dataclass of the study, or a JSON-able mapping) with
:func:`write_result`; a dataclass is written as its fields, nested dataclasses as objects::

    {"produced_by": "imply.study.section4.scoring.standin_metrics", "result": {...}}

and the paper part of its stage reads every registered number from these documents by
the registry's ``source`` and ``path`` (:mod:`imply.paper.registry`), so a number's
name leads to the function that computed it.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from imply.io import write_json


def producer_name(function: Callable[..., Any]) -> str:
    """The dotted name a registry's ``source`` column uses for ``function``."""
    return f"{function.__module__}.{function.__qualname__}"


def write_result(path: str | os.PathLike, function: Callable[..., Any], result: Any) -> None:
    """Write ``result`` (a dataclass instance or a mapping), computed by ``function``, as a result
    document (atomically)."""
    if dataclasses.is_dataclass(result) and not isinstance(result, type):
        result = dataclasses.asdict(result)
    if not isinstance(result, Mapping):
        raise TypeError(f"a result is a dataclass instance or a mapping, not {type(result).__name__}")
    write_json(path, {"produced_by": producer_name(function), "result": result})


def read_result(path: str | os.PathLike) -> tuple[str, dict[str, Any]]:
    """(producer's dotted name, result) of a result document."""
    with open(Path(path)) as fh:
        doc = json.load(fh)
    if not isinstance(doc, dict) or "produced_by" not in doc or "result" not in doc:
        raise ValueError(f"{path}: not a result document (needs 'produced_by' and 'result')")
    return doc["produced_by"], doc["result"]


def read_results(paths: Iterable[str | os.PathLike]) -> dict[str, dict[str, Any]]:
    """Producer -> result of several result documents; two from one producer is an error."""
    out: dict[str, dict[str, Any]] = {}
    for path in paths:
        producer, result = read_result(path)
        if producer in out:
            raise ValueError(f"{path}: a second result of {producer}")
        out[producer] = result
    return out
