"""The registry of every reported number: ``imply/paper/registry.csv``.

One row per number the study reports, and per number the paper prints that the study
does not produce. Columns:

``name``
    The LaTeX macro name (letters only): the paper's own where its preamble has one,
    otherwise a new name. The same string is the key in ``numbers.json``, the macro in
    ``macros.tex`` and the row of the reproduction report, so grepping it leads here.
``section``
    The paper section that reports it (``3``, ``4``, ``5``), or ``gap`` for the
    diagnostic's benchmark, ``evaluate`` for the stand-ins measured through
    ``imply evaluate`` and ``beyond`` for the pixel-space world model, which the paper
    does not have (the reproduction report gives ``beyond`` a section of its own).
``stage``
    The workflow stage whose result part reports it (``section4``, ``clips``,
    ``section5``, ``gap``, ``evaluate``, ``pixel``); empty for a paper number the study does not produce.
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

Anything that reads or writes a number by name goes through :class:`imply.results.Registry`
(parts, macros, tables, claims, the reproduction report), so a name that is not registered
fails loudly (:class:`imply.results.UnknownNumberError`) instead of printing a blank. This
module reads the file; the types live in :mod:`imply.results`.
"""

from __future__ import annotations

import csv
import functools
import os
import re
from importlib import resources
from pathlib import Path

from imply.config_check import PAPER_STAGES
from imply.results import Entry, Registry

COLUMNS = ["name", "section", "stage", "source", "path", "format", "paper", "label"]
STAGES = PAPER_STAGES
_NAME = re.compile(r"^[A-Za-z]+$")


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
