"""The one way configuration reaches code: frozen, keyword-only dataclasses built from config.

Every settings object of the package (a config section, or part of one) is a
``@dataclass(frozen=True, kw_only=True)`` subclass of :class:`Config`. Its
:meth:`Config.from_dict` takes the section as read from ``config.yaml`` (or from the
JSON a workflow rule passes) and:

* refuses keys the class does not declare, naming all of them (:func:`known_options`);
* converts values by the fields' type hints: nested settings from mappings, tuples from
  lists, ``dict[str, X]`` entry by entry, numbers to ``float``/``int``;
* checks each value against the bounds its field declares (:func:`option`);
* leaves checks across fields to the class's ``__post_init__``.

So a function receives one typed object, never a raw dict, and a misspelt key is an
error wherever it comes from. :meth:`Config.to_dict` gives the mapping back (JSON-able),
which is what digests and saved models record.

The dataclass is the one source of an option: its type (the hint), its default (the
study's value, or none: the key is required), its bounds and one line of doc, declared
with :func:`option`. :func:`json_schema` turns a class into the JSON schema the workflow
validates ``config.yaml`` against (``workflow/schemas/config.schema.yaml`` is written
by ``python -m imply.workflow_config`` and held to it by a test), and the CLI takes its
flags' defaults from the fields (:func:`default_of`).
"""

from __future__ import annotations

import copy
import dataclasses
import math
import types
import typing
from dataclasses import dataclass, fields
from typing import Any, ClassVar, TypeVar

C = TypeVar("C", bound="Config")

# option()'s bound keywords and their JSON-schema spelling
_BOUNDS = {
    "minimum": "minimum",
    "maximum": "maximum",
    "exclusive_minimum": "exclusiveMinimum",
    "exclusive_maximum": "exclusiveMaximum",
    "choices": "enum",
    "min_items": "minItems",
    "max_items": "maxItems",
    "unique": "uniqueItems",
    "pattern": "pattern",
}


def option(
    default: Any = dataclasses.MISSING,
    *,
    doc: str,
    required: bool = False,
    items: dict[str, Any] | None = None,
    keys: tuple[str, ...] | None = None,
    **bounds: Any,
) -> Any:
    """A settings field: its default (none: the key is required), one line of doc and its bounds.

    ``bounds`` are ``minimum``, ``maximum``, ``exclusive_minimum``, ``exclusive_maximum``,
    ``choices``, ``min_items``, ``max_items``, ``unique`` and ``pattern``; ``items``
    holds the same bounds for each element of a list (or each value of a mapping), and
    ``keys`` the only keys a mapping may have.
    ``required`` asks the workflow's config to spell the key out although the class has a
    default (the workflow reads it directly). A list, dict or settings default is copied
    for each instance.
    """
    unknown = sorted(set(bounds) - set(_BOUNDS))
    if unknown or set(items or {}) - set(_BOUNDS):
        raise TypeError(f"option(): unknown bound(s) {', '.join(unknown or sorted(set(items or {}) - set(_BOUNDS)))}")
    metadata = {"doc": doc, "bounds": bounds, "items": items or {}, "required": required, "keys": keys}
    if isinstance(default, list | dict | Config):
        value = default
        return dataclasses.field(default_factory=lambda: copy.deepcopy(value), metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def default_of(cls: type, name: str) -> Any:
    """The default of field ``name`` of settings class ``cls`` (for a CLI flag's default)."""
    f = {f.name: f for f in fields(cls)}[name]
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    if f.default is dataclasses.MISSING:
        raise ValueError(f"{cls.__name__}.{name} has no default")
    return f.default


def doc_of(cls: type, name: str) -> str:
    """The one line of doc of field ``name`` of ``cls``."""
    return {f.name: f for f in fields(cls)}[name].metadata.get("doc", "")


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
        declared = {f.name: f for f in fields(cls)}
        for name, value in converted.items():
            _check_bounds(declared[name].metadata, value, f"{where}.{name}")
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

    min: float = option(doc="lower end", exclusive_minimum=0)
    max: float = option(doc="upper end", exclusive_minimum=0)

    def __post_init__(self) -> None:
        if not 0 < self.min <= self.max:
            raise ValueError(f"range needs 0 < min <= max, not min {self.min:g}, max {self.max:g}")

    def as_tuple(self) -> tuple[float, float]:
        return (self.min, self.max)


@dataclass(frozen=True, kw_only=True)
class Axis(Config):
    """A grid axis ``{min, max, n}``: n points from min to max (positive numbers)."""

    min: float = option(doc="first point", exclusive_minimum=0)
    max: float = option(doc="last point", exclusive_minimum=0)
    n: int = option(doc="points", minimum=4)


# -- bounds -----------------------------------------------------------------------


def _out_of_bounds(bounds: dict[str, Any], value: Any) -> str | None:
    """Why ``value`` breaks ``bounds`` (None: it keeps them); lists are checked as a whole."""
    if isinstance(value, bool | dict | Config) or value is None:
        return None
    if isinstance(value, int | float):
        if not math.isfinite(value):
            return f"{value!r} is not a finite number"
        for key, fails, word in (
            ("minimum", lambda b: value < b, "less than the minimum of"),
            ("maximum", lambda b: value > b, "greater than the maximum of"),
            ("exclusive_minimum", lambda b: value <= b, "less than or equal to the minimum of"),
            ("exclusive_maximum", lambda b: value >= b, "greater than or equal to the maximum of"),
        ):
            if key in bounds and fails(bounds[key]):
                return f"{value:g} is {word} {bounds[key]:g}"
    if "choices" in bounds and value not in bounds["choices"]:
        return f"{value!r} is not one of {list(bounds['choices'])}"
    if isinstance(value, tuple | list):
        if "min_items" in bounds and len(value) < bounds["min_items"]:
            return f"{list(value)!r} has fewer than {bounds['min_items']} items"
        if "max_items" in bounds and len(value) > bounds["max_items"]:
            return f"{list(value)!r} has more than {bounds['max_items']} items"
        if bounds.get("unique") and len(set(value)) != len(value):
            return f"{list(value)!r} has repeated items"
    return None


def _check_bounds(metadata: Any, value: Any, where: str) -> None:
    if not metadata:
        return
    problem = _out_of_bounds(metadata.get("bounds", {}), value)
    if problem is None and metadata.get("keys") is not None and isinstance(value, dict):
        unknown = sorted(set(value) - set(metadata["keys"]))
        problem = f"unknown key(s) {', '.join(unknown)} (known: {', '.join(metadata['keys'])})" if unknown else None
    if problem is None and metadata.get("items"):
        elements = value.values() if isinstance(value, dict) else value if isinstance(value, tuple | list) else ()
        problem = next((p for p in (_out_of_bounds(metadata["items"], v) for v in elements) if p), None)
    if problem:
        raise ValueError(f"{where}: {problem}")


# -- the JSON schema of a settings class ------------------------------------------


def _schema_bounds(bounds: dict[str, Any]) -> dict[str, Any]:
    return {_BOUNDS[k]: (list(v) if k == "choices" else v) for k, v in bounds.items()}


def _type_schema(hint: Any, defs: dict[str, Any]) -> dict[str, Any]:
    """The JSON schema of a value of type ``hint`` (settings classes go to ``defs``, once each)."""
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        options = [_type_schema(a, defs) for a in args]
        return {"anyOf": options}
    if hint is type(None):
        return {"type": "null"}
    if isinstance(hint, type) and issubclass(hint, Config):
        if hint.__name__ not in defs:
            defs[hint.__name__] = {}  # placeholder against recursion
            defs[hint.__name__] = _class_schema(hint, defs)
        return {"$ref": f"#/$defs/{hint.__name__}"}
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return {"type": "array", "items": _type_schema(args[0], defs)}
        item = _type_schema(args[0], defs) if len(set(args)) == 1 else {}
        return {"type": "array", "items": item, "minItems": len(args), "maxItems": len(args)}
    if origin is dict:
        value = _type_schema(args[1], defs) if args and args[1] is not Any else {}
        return {"type": "object", "additionalProperties": value} if value else {"type": "object"}
    if hint is Any:
        return {}
    simple = {bool: "boolean", int: "integer", float: "number", str: "string"}
    if hint in simple:
        return {"type": simple[hint]}
    raise TypeError(f"no JSON schema for type {hint!r}")


def _with_bounds(schema: dict[str, Any], metadata: Any) -> dict[str, Any]:
    """``schema`` with a field's bounds on the value and its items (through anyOf branches)."""
    bounds = dict(metadata.get("bounds", {})) if metadata else {}
    items = dict(metadata.get("items", {})) if metadata else {}
    if not bounds and not items and not (metadata and metadata.get("keys") is not None):
        return schema
    if "anyOf" in schema:
        # the bounds hold for the plain values; a branch of settings (or null) has its own schema
        return {"anyOf": [b if b.get("type") in ("null", None) else _with_bounds(b, metadata) for b in schema["anyOf"]]}
    schema = {**schema, **_schema_bounds(bounds)}
    if items:
        key = "items" if schema.get("type") == "array" else "additionalProperties"
        schema[key] = {**schema.get(key, {}), **_schema_bounds(items)}
    if metadata and metadata.get("keys") is not None:
        value = schema.pop("additionalProperties", {})
        schema["properties"] = {k: value for k in metadata["keys"]}
        schema["additionalProperties"] = False
    return schema


def _class_schema(cls: type, defs: dict[str, Any]) -> dict[str, Any]:
    hints = typing.get_type_hints(cls)
    properties: dict[str, Any] = {}
    required = []
    for f in fields(cls):
        schema = _with_bounds(_type_schema(hints[f.name], defs), f.metadata)
        doc = f.metadata.get("doc") if f.metadata else None
        properties[f.name] = {"description": doc, **schema} if doc else schema
        if _required(f) or (f.metadata and f.metadata.get("required")):
            required.append(f.name)
    out: dict[str, Any] = {"type": "object"}
    if cls.__doc__:
        out["description"] = " ".join(cls.__doc__.strip().split("\n\n")[0].split())
    if required:
        out["required"] = required
    out["additionalProperties"] = False
    out["properties"] = properties
    return out


def json_schema(cls: type, *, title: str | None = None) -> dict[str, Any]:
    """The JSON schema (draft 2020-12) of settings class ``cls``: types, bounds, docs, required keys.

    Every object refuses keys the class does not declare; nested settings classes are
    described once each under ``$defs``.
    """
    defs: dict[str, Any] = {}
    body = _class_schema(cls, defs)
    schema = {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": title or cls.__name__, **body}
    if defs:
        schema["$defs"] = dict(sorted(defs.items()))
    return schema
