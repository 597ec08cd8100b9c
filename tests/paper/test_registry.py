"""The registry of reported numbers: every name traceable, every use of an unregistered name loud."""

from __future__ import annotations

import importlib
import inspect
import re
from pathlib import Path

import pytest

from imply.cli.common import UserError
from imply.cli.paper import stage_claims
from imply.paper import latex_tables
from imply.paper.registry import COLUMNS, STAGES, default_path, load_registry, read_registry
from imply.paper.report import number_status
from imply.results import NotProducedError, Registry, UnknownNumberError, format_value
from registry_helpers import fake_results

SRC = Path(__file__).resolve().parents[2] / "src" / "imply"


def _function(dotted: str):
    module, _, name = dotted.rpartition(".")
    return getattr(importlib.import_module(module), name)


def test_every_source_is_a_function_and_every_paper_macro_is_registered():
    reg = load_registry()
    for e in reg:
        if e.produced:
            assert inspect.isfunction(_function(e.source)), e.name
            assert e.path and e.format
    assert reg["BlAurocSelf"].paper == "0.70" and reg["BlAurocSelf"].paper_decimals == 2
    assert reg["vjCQTrack"].paper == "-0.00" and reg["ColSelf"].paper_value == 4.715
    assert not reg["cosmosSlideMm"].produced


def test_every_macro_of_the_paper_is_registered_with_its_printed_value():
    papers = sorted((Path(__file__).resolve().parents[3] / "shared" / "seeds").glob("*.txt"))
    if not papers:
        pytest.skip("the paper's source (../shared/seeds) is not beside this checkout")
    reg = load_registry()
    macros = re.findall(r"\\newcommand\{\\([A-Za-z]+)\}\{([-0-9.]+)\}", papers[0].read_text())
    assert len(macros) > 50
    for name, value in macros:
        assert reg[name].paper == value, name


def test_unknown_names_fail_loudly():
    reg = load_registry()
    with pytest.raises(UnknownNumberError, match="did you mean 'BlAurocAnch'"):
        reg["BlAurocAnc"]
    values = reg.values({"OrSelf": 0.004})
    assert values.text("OrSelf") == "0.004"
    with pytest.raises(UnknownNumberError):
        values["orSelf"]
    with pytest.raises(UnknownNumberError):
        "orSelf" in values  # noqa: B015 - asking about an unregistered name is itself an error
    assert "BlSelf" not in values
    with pytest.raises(NotProducedError):
        values["BlSelf"]
    with pytest.raises(UnknownNumberError):
        reg.values({"notANumber": 1.0})


def test_renaming_a_macro_without_the_registry_fails(monkeypatch):
    """A name used by a table or a claim but missing from the registry cannot go unnoticed."""
    reg = load_registry()
    renamed = Registry(
        [e if e.name != "BlAurocSelf" else type(e)(**{**e.__dict__, "name": "BlAurocSelfRenamed"}) for e in reg]
    )
    numbers = {e.name: 1.0 for e in renamed if e.stage == "section4"}
    values = renamed.values(numbers)
    with pytest.raises(UnknownNumberError, match="BlAurocSelf"):
        latex_tables.table1_tex(values)
    with pytest.raises(UnknownNumberError, match="BlAurocSelf"):
        stage_claims("section4")(values, {})


def test_every_name_used_by_tables_and_claims_is_registered():
    """Parts, tables and claims run on a full set of registered values without an unknown name."""
    from imply.paper.parts import build_part

    reg = load_registry()
    for stage in STAGES:
        numbers, claims = build_part(stage, fake_results(reg, stage), claims=stage_claims(stage))
        assert set(numbers) == {e.name for e in reg.of_stage(stage)} and claims
    s4 = reg.values({e.name: 0.5 for e in reg.of_stage("section4")})
    assert "\\toprule" in latex_tables.table1_tex(s4) and "\\toprule" in latex_tables.table2_tex(s4)
    assert "\\toprule" in latex_tables.table3_tex(reg.values({e.name: 0.5 for e in reg.of_stage("section5")}))


def test_literal_names_are_greppable():
    """The names the code uses are written out in full: no macro name is assembled from pieces."""
    assembled = re.compile(r"""f["'](?:noise|sel|vj|gap|Or|Jit|Bl|Col)\{""")
    offenders = [
        f"{p.relative_to(SRC)}:{i}"
        for p in SRC.rglob("*.py")
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if assembled.search(line)
    ]
    assert offenders == []


def test_registry_file_errors(tmp_path):
    bad = tmp_path / "r.csv"
    header = ",".join(COLUMNS) + "\n"
    bad.write_text(header + "Or1Self,4,section4,a.b,x,.3f,,label\n")
    with pytest.raises(ValueError, match="letters only"):
        read_registry(bad)
    bad.write_text(header + "OrSelf,4,section4,a.b,x,.3f,abc,label\n")
    with pytest.raises(ValueError, match="not a number"):
        read_registry(bad)
    bad.write_text(header + "OrSelf,4,sectionX,a.b,x,.3f,,label\n")
    with pytest.raises(ValueError, match="stage"):
        read_registry(bad)
    bad.write_text(header + "OrSelf,4,section4,a.b,x,.3f,,l\nOrSelf,4,section4,a.b,y,.3f,,l\n")
    with pytest.raises(ValueError, match="twice"):
        read_registry(bad)
    bad.write_text("name,value,section\nOrSelf,0.1,4\n")
    with pytest.raises(ValueError, match="header"):
        read_registry(bad)
    assert read_registry(default_path()).entries.keys() == load_registry().entries.keys()


def test_number_status_and_format():
    e = load_registry()["BlAurocSelf"]  # the paper prints 0.70
    assert number_status(e, 0.704)[0] == "matches"
    assert number_status(e, 0.75)[0] == "close"
    assert number_status(e, 0.9)[0] == "differs"
    assert number_status(e, None) == ("not produced", "not produced")
    assert format_value(200, "d") == "200" and format_value(float("nan"), ".2f") == "--"


def test_every_stage_has_a_claims_function():
    for stage in STAGES:
        assert inspect.isfunction(stage_claims(stage)), stage
    with pytest.raises(UserError, match="unknown stage"):
        stage_claims("section6")
