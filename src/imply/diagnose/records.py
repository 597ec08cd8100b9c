"""Typed results of the diagnosis and their JSON form: one frozen dataclass per record, read by attribute.

A record's fields become the keys of its JSON object (``summary.json``), in the same
names, except where a field says otherwise: :func:`json_field` gives the key a field is
written under (``class`` is a Python keyword) and whether it is left out when it is None
(an effect without an azimuth has no ``azimuth_deg`` key, not a null one).
:meth:`Record.to_dict` writes a record as plain JSON values; :meth:`Record.from_dict`
reads one back (nested records, lists and maps of records, settings objects with their
own ``from_dict``), so what is written is exactly what is read.
"""

from __future__ import annotations

import dataclasses
import enum
import types
import typing
from typing import Any, TypeVar

R = TypeVar("R", bound="Record")


def json_field(
    *,
    key: str | None = None,
    omit_none: bool = False,
    default: Any = dataclasses.MISSING,
    default_factory: Any = dataclasses.MISSING,
) -> Any:
    """A record field written under ``key`` (default: its name), left out when None if ``omit_none``.

    A field with a default (or ``default_factory``) may be missing from what is read: summaries written before
    it existed read back with the default."""
    metadata = {"key": key, "omit_none": omit_none}
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=metadata)
    if default is dataclasses.MISSING:
        return dataclasses.field(metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def _has_default(f: dataclasses.Field) -> bool:
    return f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING


def _key(f: dataclasses.Field) -> str:
    return f.metadata.get("key") or f.name


def _plain(value: Any) -> Any:
    if hasattr(value, "to_dict"):
        return value.to_dict()
    if isinstance(value, list | tuple):
        return [_plain(x) for x in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def _read(tp: Any, value: Any) -> Any:
    """``value`` (plain JSON) as type ``tp``."""
    if value is None:
        return None
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        inner = [a for a in args if a is not type(None)]
        return _read(inner[0], value) if len(inner) == 1 else value
    if origin is list:
        return [_read(args[0], x) for x in value]
    if origin is tuple:
        return tuple(_read(args[0], x) for x in value)
    if origin is dict:
        return {k: _read(args[1], v) for k, v in value.items()}
    if isinstance(tp, type) and hasattr(tp, "from_dict"):
        return tp.from_dict(value)
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return tp(value)
    return value


class Record:
    """Mixin of the diagnosis' frozen dataclasses: JSON out (:meth:`to_dict`) and back (:meth:`from_dict`)."""

    def to_dict(self) -> dict[str, Any]:
        out = {}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            if value is None and f.metadata.get("omit_none"):
                continue
            out[_key(f)] = _plain(value)
        return out

    @classmethod
    def from_dict(cls: type[R], values: dict[str, Any]) -> R:
        hints = typing.get_type_hints(cls)
        kwargs = {}
        for f in dataclasses.fields(cls):  # type: ignore[arg-type]
            if _key(f) in values:
                kwargs[f.name] = _read(hints[f.name], values[_key(f)])
            elif not f.metadata.get("omit_none") and not _has_default(f):
                raise KeyError(f"{cls.__name__}: no {_key(f)!r}")
        return cls(**kwargs)
