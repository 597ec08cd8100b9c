"""The registry of every reported number: ``imply/paper/registry.csv``.

One row per number the study reports, and per number the paper prints that the study
does not produce. Columns:

``name``
    The LaTeX macro name (letters only): the paper's own where its preamble has one,
    otherwise a new name. The same string is the key in ``numbers.json``, the macro in
    ``macros.tex`` and the row of the reproduction report, so grepping it leads here.
``section``
    The paper section that reports it (``3``, ``4``, ``5``), or ``gap`` for the
    diagnostic's benchmark, which the paper does not have.
``stage``
    The workflow stage whose result part reports it (``section4``, ``clips``,
    ``section5``, ``gap``); empty for a paper number the study does not produce.
``source``
    The dotted name of the function that computes it: the value is read from that
    function's result document (written with :func:`imply.paper.results.write_result`).
``path``
    Where in that result: keys and list indices joined by dots (``standins.blind.auroc_anchored``,
    ``levels.-1.sd``). A list index past the end means "not produced" (a config with fewer
    noise levels or one data seed); a missing key is an error.
``format``
    The Python format spec of the macro (the paper's rounding); NaN prints as ``--``.
``paper``
    The value exactly as the paper prints it (its decimals are the paper's precision), or
    empty.
``label``
    What the number is, in words.

Anything that reads or writes a number by name goes through :class:`Registry` (parts,
macros, tables, claims, the reproduction report), so a name that is not registered fails
loudly (:class:`UnknownNumberError`) instead of printing a blank.
"""

from __future__ import annotations

import csv
import difflib
import functools
import math
import os
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

COLUMNS = ["name", "section", "stage", "source", "path", "format", "paper", "label"]
STAGES = ("section4", "clips", "section5", "gap")
_NAME = re.compile(r"^[A-Za-z]+$")


class UnknownNumberError(KeyError):
    """A number name that the registry does not list."""

    def __str__(self) -> str:
        return str(self.args[0])


class NotProducedError(KeyError):
    """A registered number that the results at hand do not hold."""

    def __str__(self) -> str:
        return str(self.args[0])


class _Missing:
    def __repr__(self) -> str:
        return "NOT_PRODUCED"


NOT_PRODUCED = _Missing()


@dataclass(frozen=True)
class Entry:
    """One registered number (see the module docstring for the fields)."""

    name: str
    section: str
    stage: str
    source: str
    path: str
    format: str
    paper: str
    label: str

    @property
    def produced(self) -> bool:
        """Whether a stage of the study computes it."""
        return bool(self.stage)

    @property
    def paper_value(self) -> float | None:
        return float(self.paper) if self.paper else None

    @property
    def paper_decimals(self) -> int:
        """Decimals the paper prints (0 for integers)."""
        return len(self.paper.split(".")[1]) if "." in self.paper else 0

    def resolve(self, results: Mapping[str, Any]) -> Any:
        """The value in ``results`` (source -> result document), or :data:`NOT_PRODUCED`.

        A list index past the end is "not produced"; a missing key is an error, since the
        result's shape is fixed by its function.
        """
        if self.source not in results:
            raise KeyError(f"{self.name}: no result of {self.source} was given")
        node: Any = results[self.source]
        for part in self.path.split("."):
            if isinstance(node, list):
                index = int(part)
                if not -len(node) <= index < len(node):
                    return NOT_PRODUCED
                node = node[index]
            elif isinstance(node, dict) and part in node:
                node = node[part]
            else:
                raise KeyError(f"{self.name}: {self.source} has no {self.path!r} (no {part!r})")
        if node is None:
            return float("nan")
        if isinstance(node, bool) or not isinstance(node, int | float):
            raise TypeError(f"{self.name}: {self.source} {self.path!r} is not a number: {node!r}")
        return node

    def text(self, value: float | int) -> str:
        """The value as the macro prints it: this entry's format, NaN as ``--``."""
        return format_value(value, self.format)


def format_value(value: float | int, spec: str) -> str:
    """A number as the paper prints it; integer specs round, NaN prints as ``--``."""
    v = float(value)
    if not math.isfinite(v):
        return "--"
    if spec.endswith("d"):
        return format(int(round(v)), spec)
    return format(v, spec)


class Registry:
    """The registered numbers by name, in file order."""

    def __init__(self, entries: list[Entry], path: str = "<registry>") -> None:
        self.path = path
        self.entries: dict[str, Entry] = {}
        for e in entries:
            if e.name in self.entries:
                raise ValueError(f"{path}: number {e.name!r} is registered twice")
            self.entries[e.name] = e

    def __getitem__(self, name: str) -> Entry:
        try:
            return self.entries[name]
        except KeyError:
            close = difflib.get_close_matches(name, list(self.entries), n=1, cutoff=0.75)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise UnknownNumberError(
                f"number {name!r} is not in the registry {self.path}{hint}; register it there (name, stage, "
                "source, path, format, paper, label) before reporting or using it"
            ) from None

    def __contains__(self, name: object) -> bool:
        return name in self.entries

    def __iter__(self) -> Iterator[Entry]:
        return iter(self.entries.values())

    def __len__(self) -> int:
        return len(self.entries)

    def of_stage(self, stage: str) -> list[Entry]:
        """The entries a stage reports, in registry order."""
        return [e for e in self.entries.values() if e.stage == stage]

    def in_paper(self) -> list[Entry]:
        """The entries the paper prints, in registry order."""
        return [e for e in self.entries.values() if e.paper]

    def values(self, numbers: Mapping[str, Any]) -> Values:
        """A :class:`Values` over ``numbers`` (name -> value), every name checked now."""
        return Values(self, numbers)


def default_path() -> Path:
    """Where the package keeps the registry."""
    return Path(str(resources.files("imply") / "paper" / "registry.csv"))


def read_registry(path: str | os.PathLike) -> Registry:
    """Read and check a registry file (columns, letters-only unique names, known stages, paper values)."""
    path = Path(path)
    entries = []
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        if reader.fieldnames != COLUMNS:
            raise ValueError(f"{path}: header must be {','.join(COLUMNS)}, got {reader.fieldnames}")
        for line, row in enumerate(reader, start=2):
            e = Entry(**{k: (row[k] or "").strip() for k in COLUMNS})
            where = f"{path}:{line}"
            if not _NAME.match(e.name):
                raise ValueError(f"{where}: column name: {e.name!r} is not letters only (a LaTeX command name)")
            if e.stage and e.stage not in STAGES:
                raise ValueError(f"{where}: column stage: {e.stage!r} is not one of {', '.join(STAGES)}")
            if bool(e.stage) != bool(e.source) or bool(e.stage) != bool(e.path):
                raise ValueError(f"{where}: stage, source and path are given together or not at all")
            if not e.stage and not e.paper:
                raise ValueError(f"{where}: a number no stage produces must be one the paper prints")
            if e.paper:
                try:
                    float(e.paper)
                except ValueError:
                    raise ValueError(f"{where}: column paper: {e.paper!r} is not a number") from None
            try:
                format(1.0 if not e.format.endswith("d") else 1, e.format)
            except ValueError:
                raise ValueError(f"{where}: column format: {e.format!r} is not a format spec") from None
            entries.append(e)
    return Registry(entries, str(path))


@functools.cache
def load_registry() -> Registry:
    """The package's registry (read once per process)."""
    return read_registry(default_path())


class Values(Mapping[str, Any]):
    """Registered numbers and their unrounded values, as claims and tables read them.

    ``values[name]`` raises :class:`UnknownNumberError` for a name the registry does not
    list and :class:`NotProducedError` for a registered one without a value here;
    ``name in values`` is True for produced numbers only, and asking it about an
    unregistered name is an error too.
    """

    def __init__(self, registry: Registry, numbers: Mapping[str, Any]) -> None:
        for name in numbers:
            registry[name]
        self.registry = registry
        self._numbers = dict(numbers)

    def __getitem__(self, name: str) -> Any:
        self.registry[name]
        if name not in self._numbers:
            raise NotProducedError(f"number {name!r} is registered but was not produced by these results")
        return self._numbers[name]

    def __contains__(self, name: object) -> bool:
        self.registry[name]  # type: ignore[index]
        return name in self._numbers

    def __iter__(self) -> Iterator[str]:
        return iter(self._numbers)

    def __len__(self) -> int:
        return len(self._numbers)

    def text(self, name: str) -> str:
        """The value of ``name`` as its macro prints it."""
        return self.registry[name].text(self[name])
