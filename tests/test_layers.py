"""The package's layers only point down, and no two modules import each other, however indirectly.

Imports are read from the source with :mod:`ast` (those inside functions too, since the
command-line modules import on demand), so the test runs without importing anything.

Layers, bottom up: the neutral modules (:mod:`imply.stats`, :mod:`imply.results`) import
nothing of :mod:`imply`; the models, the study, the diagnostic and the paper import the
neutral modules and the foundations (tables, scoring, simulation, io) but no layer beside
or above them: the study and the paper never import each other (the command line ties a
stage to its claims); only :mod:`imply.cli` imports everything.
"""

from __future__ import annotations

import ast
import functools
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

NEUTRAL = ("imply.stats", "imply.results", "imply.extras")
DIAGNOSE_STAGES = ("inputs", "physics", "inference", "conclusion")
DIAGNOSE_TOP = ("analysis", "reference", "report", "run")
# package -> the packages it must not import
FORBIDDEN = {
    "imply.stats": ("imply",),
    "imply.results": ("imply",),
    "imply.extras": ("imply",),
    "imply.models": ("imply.study", "imply.paper", "imply.diagnose", "imply.cli"),
    "imply.study": ("imply.paper", "imply.diagnose", "imply.cli"),
    # the tool a user runs does not hold the study's benchmark (imply.realworld scores it)
    "imply.diagnose": ("imply.study", "imply.paper", "imply.cli", "imply.realworld"),
    "imply.paper": ("imply.study", "imply.models", "imply.diagnose", "imply.cli"),
    # the diagnostic's stages, in the order a reader follows them: each imports only the stages before it, and none
    # the pipeline above them
    **{
        f"imply.diagnose.{stage}": tuple(f"imply.diagnose.{s}" for s in DIAGNOSE_STAGES[k + 1 :] + DIAGNOSE_TOP)
        for k, stage in enumerate(DIAGNOSE_STAGES)
    },
}


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports_of(source: str, module: str, is_package: bool, known: set[str]) -> set[str]:
    """The :mod:`imply` modules a module's source imports (a name imported from a package counts
    as its submodule when there is one)."""
    package = module if is_package else module.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                out.add(sub if sub in known else target)
    return {name for name in out if name == "imply" or name.startswith("imply.")}


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the :mod:`imply` modules it imports, for every module under ``root/imply``."""
    files = {module_name(p, root): p for p in sorted((root / "imply").rglob("*.py"))}
    known = set(files)
    return {
        name: imports_of(path.read_text(), name, path.name == "__init__.py", known) - {name}
        for name, path in files.items()
    }


def _inside(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    out = []
    for module, targets in sorted(graph.items()):
        for package, banned in FORBIDDEN.items():
            if not _inside(module, package):
                continue
            for target in sorted(targets):
                if any(_inside(target, b) for b in banned):
                    out.append(f"{module} imports {target}")
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


@functools.cache
def package_graph() -> dict[str, set[str]]:
    return import_graph(SRC)


def test_layers_only_point_down():
    graph = package_graph()
    assert {"imply.stats", "imply.results", "imply.study.section5.scoring"} <= set(graph)
    assert layer_violations(graph) == []


def test_no_import_cycles():
    assert cycles(package_graph()) == []


def test_the_checks_see_a_violation(tmp_path):
    """The same checks on a copy of the package with one upward import and one cycle added."""
    copy = tmp_path / "src"
    for path in (SRC / "imply").rglob("*.py"):
        target = copy / path.relative_to(SRC)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(path.read_text())
    stats = copy / "imply" / "stats.py"
    stats.write_text(stats.read_text() + "\nfrom imply.study.section5 import scoring  # noqa\n")
    selection = copy / "imply" / "study" / "section5" / "selection.py"
    selection.write_text(selection.read_text() + "\nfrom imply.study.section5.scoring import ContextScores  # noqa\n")
    graph = import_graph(copy)
    assert "imply.stats imports imply.study.section5.scoring" in layer_violations(graph)
    assert any({"imply.study.section5.scoring", "imply.study.section5.selection"} <= set(c) for c in cycles(graph))


def test_the_diagnostic_is_four_stages_and_a_pipeline():
    """Every module of imply.diagnose sits in a stage or is one of the few above or beside them."""
    graph = package_graph()
    loose = {
        m.removeprefix("imply.diagnose.")
        for m in graph
        if m.startswith("imply.diagnose.") and m.count(".") == 2 and m.rpartition(".")[2] not in DIAGNOSE_STAGES
    }
    assert loose == {*DIAGNOSE_TOP, "records", "tails"}
    for stage in DIAGNOSE_STAGES:
        assert sum(m.startswith(f"imply.diagnose.{stage}.") for m in graph) >= 4, stage


@pytest.mark.parametrize("module", NEUTRAL)
def test_neutral_modules_import_nothing_of_imply(module):
    assert package_graph()[module] == set()


@pytest.mark.parametrize(
    ("module", "heavy"),
    [
        # the readouts' and the statistics' helpers: scikit-learn and scipy.stats only where a fit or a test runs
        ("imply.readout", ("sklearn",)),
        ("imply.stats", ("sklearn", "scipy.stats")),
        # the pixel model's scores read reports and settings, never the network
        ("imply.study.pixel_model", ("torch", "sklearn")),
    ],
)
def test_modules_that_many_commands_import_leave_the_heavy_libraries_for_their_use(module, heavy):
    code = f"import sys, {module}; print(','.join(m for m in {heavy!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"importing {module} imports {out}"
