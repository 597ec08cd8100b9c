"""What the study reports, as types every layer can import: registered numbers, their values, claims.

* :class:`Entry` and :class:`Registry`: the registered numbers (one row of
  ``imply/paper/registry.csv`` each; the file and its columns: :mod:`imply.paper.registry`).
  An entry names the function that computes its number (``source``) and where in that
  function's result document the number sits (``path``, e.g. ``seeds.0.calib.own.track``).
* :class:`Values`: registered numbers by name with their unrounded values, as the claims
  and tables read them.
* :class:`Claim`: a qualitative claim of the paper, checked on those values.

The study (its claims), the diagnostic's benchmark report and the paper all import these
from here, so none of them imports another for a type. This module imports nothing of
:mod:`imply`.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any


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


@dataclass(frozen=True)
class Claim:
    """A qualitative claim, checked on the reproduced results: the paper's own (its stage is one of
    :data:`PAPER_CLAIM_STAGES`) or a target of this project's (the gap benchmarks', the evaluate checks, the pixel
    model's). A claim on a share of logs or objects carries its ``count`` of ``n``, so that a report can say what
    a threshold on that many can tell (:func:`binomial_interval`)."""

    id: str
    section: str
    statement: str
    holds: bool
    detail: str = ""
    count: int | None = None
    n: int | None = None


# the stages whose claims are the paper's; the other stages' claims are this project's own targets
PAPER_CLAIM_STAGES = ("section4", "clips", "section5")
CLAIM_KINDS = {"paper": "the paper's claims", "project": "this project's targets"}


# claims of the paper's stages that are this project's bar, not the paper's: the per-seed targets of the Section 5
# stand-in (own-calibration r >= 0.9, anchored >= 80%, ...), which the paper's own model does not reach (0.91, 73%)
PROJECT_TARGET_PREFIXES = ("s5-targets-seed",)


def claim_kind(stage: str, claim_id: str = "") -> str:
    """``paper`` for a claim of the paper's stages, ``project`` for one of this project's targets (another stage's
    claims, and those of :data:`PROJECT_TARGET_PREFIXES`)."""
    if stage not in PAPER_CLAIM_STAGES or claim_id.startswith(PROJECT_TARGET_PREFIXES):
        return "project"
    return "paper"


def claim_tally(claims: Iterable[tuple[str, Claim | Mapping]]) -> dict[str, dict[str, int]]:
    """``{kind: {"checked": n, "hold": k}}`` over (stage, claim) pairs, for both kinds of :data:`CLAIM_KINDS` (a
    claim as a :class:`Claim` or as its JSON mapping)."""
    out = {kind: {"checked": 0, "hold": 0} for kind in CLAIM_KINDS}
    for stage, c in claims:
        holds = c.holds if isinstance(c, Claim) else bool(c.get("holds"))
        row = out[claim_kind(stage, c.id if isinstance(c, Claim) else str(c.get("id", "")))]
        row["checked"] += 1
        row["hold"] += int(holds)
    return out


def tally(share: float | None, n: int | None) -> dict[str, int]:
    """``{"count", "n"}`` of a share of ``n`` logs (keyword arguments of :class:`Claim`); empty where the share is
    missing or not finite."""
    if share is None or n is None or not math.isfinite(float(share)) or int(n) <= 0:
        return {}
    return {"count": int(round(float(share) * int(n))), "n": int(n)}


def binomial_interval(count: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """The exact (Clopper-Pearson) ``level`` interval of a share observed as ``count`` of ``n``."""
    from scipy.stats import beta

    tail = (1.0 - level) / 2.0
    lo = 0.0 if count <= 0 else float(beta.ppf(tail, count, n - count + 1))
    hi = 1.0 if count >= n else float(beta.ppf(1.0 - tail, count + 1, n - count))
    return lo, hi
