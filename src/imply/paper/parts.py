"""Per-stage result parts that the paper rule merges into macros, numbers and the report.

Each study stage writes one part, ``results/paper/parts/<stage>.json``::

    {"stage": "section4",
     "numbers": {"BlAurocSelf": {"value": 0.7012, "format": ".2f"}, ...},
     "claims": [{"id": "s4-blind-self-auroc", "section": "4",
                 "statement": "...", "holds": true, "detail": "self 0.70 vs anchored 1.00"}]}

``value`` is unrounded; ``format`` is a Python format spec used for the LaTeX macro
(the paper's own rounding). Macro names are the paper's where it has one.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from imply.io import write_json

_NAME = re.compile(r"^[A-Za-z]+$")


@dataclass(frozen=True)
class Claim:
    """A qualitative claim of the paper, checked on the reproduced results."""

    id: str
    section: str
    statement: str
    holds: bool
    detail: str = ""


@dataclass(frozen=True)
class Number:
    value: float | int
    format: str = ".3f"


def write_part(path: str | os.PathLike, stage: str, numbers: dict[str, Number], claims: list[Claim]) -> None:
    """Write a stage's part file (validated: LaTeX-safe names, finite values)."""
    for name, num in numbers.items():
        if not _NAME.match(name):
            raise ValueError(f"macro name {name!r} must be letters only (LaTeX command names)")
        if isinstance(num.value, float) and not math.isfinite(num.value):
            # a NaN is a result too (e.g. an undefined correlation); keep it visible
            pass
        format(num.value if math.isfinite(float(num.value)) else 0.0, num.format)
    payload: dict[str, Any] = {
        "stage": stage,
        "numbers": {k: {"value": v.value, "format": v.format} for k, v in sorted(numbers.items())},
        "claims": [asdict(c) for c in claims],
    }
    write_json(path, payload)


def read_part(path: str | os.PathLike) -> dict[str, Any]:
    with open(Path(path)) as fh:
        part = json.load(fh)
    for key in ("stage", "numbers", "claims"):
        if key not in part:
            raise ValueError(f"{path}: not a result part (missing {key!r})")
    return part
