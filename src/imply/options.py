"""Checking config sections against the dataclasses that hold them."""

from __future__ import annotations

from dataclasses import fields
from typing import Any


def known_options(cls: type, values: dict[str, Any] | None, what: str) -> dict[str, Any]:
    """A copy of ``values`` (None: empty), refused if it names a field the dataclass lacks.

    The error names every unknown key: "unknown <what> option(s): a, b".
    """
    values = dict(values or {})
    unknown = sorted(set(values) - {f.name for f in fields(cls)})
    if unknown:
        raise ValueError(f"unknown {what} option(s): {', '.join(unknown)}")
    return values
