"""The paper's reported numbers, kept as data: ``imply/data/paper_values.csv``.

Columns ``name,value,section``: ``name`` is the paper's LaTeX macro where it has one
(every macro of its preamble, all sections) and a new letters-only name for a number
it prints literally (table cells, the table's grid size, a few text values); ``value``
is the text exactly as printed, so its number of decimals is the paper's precision;
``section`` is the paper section that reports it. Facts only, no prose.
"""

from __future__ import annotations

import csv
import os
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

_NAME = re.compile(r"^[A-Za-z]+$")


@dataclass(frozen=True)
class PaperValue:
    name: str
    text: str
    section: str

    @property
    def value(self) -> float:
        return float(self.text)

    @property
    def decimals(self) -> int:
        """Decimals the paper prints (0 for integers)."""
        return len(self.text.split(".")[1]) if "." in self.text else 0


def default_path() -> Path:
    """Where the package keeps the paper's values."""
    return Path(str(resources.files("imply") / "data" / "paper_values.csv"))


def load_paper_values(path: str | os.PathLike | None = None) -> list[PaperValue]:
    """Read and check the paper's values (names letters-only and unique, values numbers)."""
    path = Path(path) if path is not None else default_path()
    out: list[PaperValue] = []
    seen: set[str] = set()
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        if reader.fieldnames != ["name", "value", "section"]:
            raise ValueError(f"{path}: header must be name,value,section, got {reader.fieldnames}")
        for i, row in enumerate(reader, start=2):
            name, text, section = row["name"].strip(), row["value"].strip(), row["section"].strip()
            if not _NAME.match(name):
                raise ValueError(f"{path}:{i}: column name: {name!r} is not letters only")
            if name in seen:
                raise ValueError(f"{path}:{i}: column name: {name!r} appears twice")
            try:
                float(text)
            except ValueError:
                raise ValueError(f"{path}:{i}: column value: {text!r} is not a number") from None
            seen.add(name)
            out.append(PaperValue(name, text, section))
    return out
