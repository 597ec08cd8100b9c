"""The one way configuration reaches code: frozen, keyword-only dataclasses built from config.

Every settings object of the package (a config section, or part of one) is a
``@dataclass(frozen=True, kw_only=True)`` subclass of :class:`Config`. Its
:meth:`Config.from_dict` takes the section as read from ``config.yaml`` (or from the
JSON a workflow rule passes) and:

* refuses keys the class does not declare, naming all of them (:func:`known_options`);
* converts values by the fields' type hints: nested settings from mappings, tuples from
  lists, ``dict[str, X]`` entry by entry, numbers to ``float``/``int``;
* leaves checks of values to the class's ``__post_init__``.

So a function receives one typed object, never a raw dict, and a misspelt key is an
error wherever it comes from. :meth:`Config.to_dict` gives the mapping back (JSON-able),
which is what digests and saved models record.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass, fields
from typing import Any, ClassVar, TypeVar

C = TypeVar("C", bound="Config")


def known_options(cls: type, values: dict[str, Any] | None, what: str) -> dict[str, Any]:
    """A copy of ``values`` (None: empty), refused if it names a field the dataclass lacks.

    The error names every unknown key: "unknown <what> option(s): a, b".
    """
    if values is not None and not isinstance(values, dict):
        raise ValueError(f"{what}: expected a mapping of options, not {type(values).__name__}")
    values = dict(values or {})
    unknown = sorted(set(values) - {f.name for f in fields(cls)})
    if unknown:
        raise ValueError(f"unknown {what} option(s): {', '.join(unknown)}")
    return values


def _convert(hint: Any, value: Any, where: str) -> Any:
    """``value`` converted to the type ``hint`` (the subset of typing the settings use)."""
    if value is None:
        return None
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        options = [a for a in args if a is not type(None)]
        if len(options) == 1:
            return _convert(options[0], value, where)
        return value
    if isinstance(hint, type) and issubclass(hint, Config):
        return value if isinstance(value, hint) else hint.from_dict(value, where)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ValueError(f"{where}: expected a list, not {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if args and len(args) != len(value):
            raise ValueError(f"{where}: expected {len(args)} values, not {len(value)}")
        return tuple(_convert(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=False)))
    if origin is dict:
        if not isinstance(value, dict):
            raise ValueError(f"{where}: expected a mapping, not {value!r}")
        return {k: _convert(args[1], v, f"{where}.{k}") for k, v in value.items()} if args else dict(value)
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"{where}: expected a number, not {value!r}")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{where}: expected an integer, not {value!r}")
        return int(value)
    if hint is bool:
        if not isinstance(value, bool):
            raise ValueError(f"{where}: expected true or false, not {value!r}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ValueError(f"{where}: expected text, not {value!r}")
        return value
    return value


@dataclass(frozen=True, kw_only=True)
class Config:
    """Base of every settings dataclass (see the module docstring)."""

    # where the section lives in config.yaml, for messages ("scene", "gap.diagnose")
    config_key: ClassVar[str] = "config"

    @classmethod
    def from_dict(cls: type[C], values: dict[str, Any] | None = None, where: str | None = None) -> C:
        """Config from a config mapping (None: every default); unknown keys and bad types refused."""
        where = where or getattr(cls, "config_key", cls.__name__)
        values = known_options(cls, values, where)
        hints = typing.get_type_hints(cls)
        converted = {name: _convert(hints[name], value, f"{where}.{name}") for name, value in values.items()}
        missing = [f.name for f in fields(cls) if f.name not in converted and _required(f)]
        if missing:
            raise ValueError(f"{where}: missing key(s) {', '.join(missing)}")
        try:
            return cls(**converted)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None

    def to_dict(self) -> dict[str, Any]:
        """The settings as a JSON-able mapping (tuples as lists)."""
        return _plain(dataclasses.asdict(self))

    def replace(self: C, **changes: Any) -> C:
        """A copy with some fields changed (checked again by ``__post_init__``)."""
        return dataclasses.replace(self, **changes)


def _required(f: dataclasses.Field) -> bool:
    return f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING


def _plain(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    return obj


@dataclass(frozen=True, kw_only=True)
class Range(Config):
    """A closed interval ``{min, max}`` of positive numbers in a config."""

    min: float
    max: float

    def __post_init__(self) -> None:
        if not 0 < self.min <= self.max:
            raise ValueError(f"range needs 0 < min <= max, not min {self.min:g}, max {self.max:g}")

    def as_tuple(self) -> tuple[float, float]:
        return (self.min, self.max)
