"""Stage parts from result documents, the merge into macros and numbers, the report, the tables."""

from __future__ import annotations

import json

import pytest

from imply.paper.latex_tables import table1_tex, table2_tex
from imply.paper.macros import macros_tex, merge_parts, numbers_json
from imply.paper.parts import build_part, read_part, stage_numbers, write_part
from imply.paper.registry import load_registry
from imply.paper.report import reproduction_frame, reproduction_html, reproduction_md
from imply.paper.results import read_results, write_result
from imply.realworld.benchmark_report import benchmark_claims
from imply.results import NOT_PRODUCED, Claim, UnknownNumberError
from imply.study.section4.scoring import standin_metrics
from registry_helpers import fake_results


def test_result_documents_name_their_producer(tmp_path):
    path = tmp_path / "m.json"
    write_result(path, standin_metrics, {"n_objects": 3})
    assert read_results([path]) == {"imply.study.section4.scoring.standin_metrics": {"n_objects": 3}}
    with pytest.raises(ValueError, match="second result"):
        read_results([path, path])
    (tmp_path / "x.json").write_text('{"n_objects": 3}')
    with pytest.raises(ValueError, match="not a result document"):
        read_results([tmp_path / "x.json"])


def test_paths_resolve_and_missing_levels_are_not_produced():
    reg = load_registry()
    noise = {
        "imply.study.section4.scoring.noise_sweep": {
            "levels": [
                {"sd": 0.0, "standins": {"oracle": {"mean_anchored": 0.01}, "blind": {"auroc_anchored": 0.9}}},
                {"sd": 0.2, "standins": {"oracle": {"mean_anchored": 0.1}, "blind": {"auroc_anchored": 0.7}}},
            ]
        }
    }
    assert reg["noiseBSd"].resolve(noise) == 0.2
    assert reg["noiseMax"].resolve(noise) == 0.2 and reg["noiseMaxAurocBlind"].resolve(noise) == 0.7
    assert reg["noiseCSd"].resolve(noise) is NOT_PRODUCED
    broken = {"imply.study.section4.scoring.noise_sweep": {"levels": [{"sd": 0.0}]}}
    with pytest.raises(KeyError, match="noiseAOracle"):
        reg["noiseAOracle"].resolve(broken)
    with pytest.raises(KeyError, match="no result"):
        stage_numbers("section4", noise)
    assert reg["BlCorr"].resolve({reg["BlCorr"].source: {"standins": {"blind": {"corr_anchored_error": None}}}}) != 0


def test_merge_and_report(tmp_path):
    a, b = tmp_path / "section4.json", tmp_path / "gap.json"
    write_part(
        a,
        stage="section4",
        numbers={"OrSelf": 0.0051234, "selK": 4},
        claims=[Claim("c1", "4", "oracle small", True, "0.005")],
    )
    write_part(
        b,
        stage="gap",
        numbers={"gapFalseAlarm": float("nan")},
        claims=[Claim("c2", "gap", "x fails", False, "d", count=9, n=12)],
    )
    merged = merge_parts([b, a])
    assert merged.stages == ["gap", "section4"]
    tex = macros_tex(merged)
    assert "\\newcommand{\\OrSelf}{0.005}" in tex and "\\newcommand{\\gapFalseAlarm}{--}" in tex
    nums = numbers_json(merged)
    assert nums["OrSelf"] == 0.0051234 and nums["gapFalseAlarm"] is None and nums["selK"] == 4
    reg = load_registry()
    frame = reproduction_frame(reg, merged)
    status = dict(zip(frame["name"], frame["status"], strict=True))
    assert status["OrSelf"] == "matches" and status["vjCTrack"] == "not produced"
    md = reproduction_md(reg, merged, frame)
    assert "oracle small" in md and "FAILS" in md and "gapFalseAlarm" in md
    # the paper's claims and this project's targets counted apart, each over its own denominator
    assert "The paper's claims checked: 1; hold: 1; fail: 0." in md
    assert "This project's own targets" in md and "checked: 1; hold: 0; fail: 1." in md
    assert md.index("### The paper's claims") < md.index("oracle small") < md.index("### This project's targets")
    assert md.index("### This project's targets") < md.index("x fails")
    # a claim on a share of logs says its count and its exact 95% interval (9 of 12: 0.43 to 0.95)
    assert "(d; 9 of 12; 95% interval 0.43-0.95)" in md
    page = reproduction_html(reg, merged, frame)  # the same report, as the page the Snakemake report shows
    assert "checked: 1; hold: 0; fail: 1." in page and "<span class='fails'>FAILS</span> [gap / c2] x fails" in page
    assert (
        "<td>OrSelf</td>" in page and page.count("<tr>") == md.count("\n| ") - 2
    )  # every data row; md also has 2 header rows
    with pytest.raises(ValueError, match="registered to stage 'section4'"):
        write_part(tmp_path / "dup.json", stage="gap", numbers={"OrSelf": 0.1}, claims=[])
    (tmp_path / "dup.json").write_text(json.dumps({"stage": "gap", "numbers": {"OrSelf": 0.1}, "claims": []}))
    with pytest.raises(ValueError, match="registered to stage"):
        merge_parts([a, tmp_path / "dup.json"])
    (tmp_path / "unknown.json").write_text(json.dumps({"stage": "gap", "numbers": {"gapNewThing": 1}, "claims": []}))
    with pytest.raises(UnknownNumberError, match="gapNewThing"):
        merge_parts([tmp_path / "unknown.json"])
    with pytest.raises(UnknownNumberError):
        write_part(tmp_path / "u.json", stage="gap", numbers={"gapNewThing": 1}, claims=[])


def test_tables_print_registered_formats_and_refuse_missing_cells():
    reg = load_registry()
    numbers = {e.name: 0.5 for e in reg.of_stage("section4")}
    numbers.update(
        OrSelf=0.0049, BlAurocSelf=0.7012, noiseASd=0.0, noiseAOracle=0.006, selAnchMiss=1.46, selPickedOracle=97.5
    )
    t1 = table1_tex(reg.values(numbers))
    assert "\\toprule" in t1 and "Oracle (true physics) & 0.005 & 0.500 & 0.500 & --" in t1 and "& 0.70 &" in t1
    t2 = table2_tex(reg.values(numbers))
    assert "0 & 0.006" in t2 and "Lowest anchored disagreement & 1.5 & 0\\% & 98\\%" in t2

    def noise_rows(tex: str) -> int:
        top = tex.split("\\bottomrule")[0]
        return top.count("\\\\\n") - 1  # the header row ends in \\ too

    assert noise_rows(t2) == 5
    del numbers["noiseDSd"], numbers["noiseESd"]
    assert noise_rows(table2_tex(reg.values(numbers))) == 3
    del numbers["OrErr"]
    with pytest.raises(KeyError, match="OrErr"):
        table1_tex(reg.values(numbers))


def test_build_part_reads_every_number_of_a_stage(tmp_path):
    numbers, claims = build_part("gap", fake_results(load_registry(), "gap", value=13), claims=benchmark_claims)
    assert set(numbers) == {e.name for e in load_registry().of_stage("gap")}
    assert numbers["gapTopOneN"] == 13 and {c.id for c in claims} >= {"gap-null", "gap-top1", "gap-both"}
    write_part(tmp_path / "g.json", stage="gap", numbers=numbers, claims=claims)
    assert read_part(tmp_path / "g.json")["numbers"]["gapTopOneN"] == 13


def test_the_report_gives_each_seed_s_value_and_the_range():
    from imply.paper.macros import Merged, MergedNumber
    from imply.paper.report import per_seed_rows

    reg = load_registry()
    numbers = {
        "vjCTrack": MergedNumber("vjCTrack", 0.95, ".2f", "section5"),
        "vjSOneCTrack": MergedNumber("vjSOneCTrack", 0.91, ".2f", "section5"),
        "vjCErr": MergedNumber("vjCErr", 0.2, ".3f", "section5"),  # no second seed: not a row
    }
    rows = per_seed_rows(reg, Merged(numbers=numbers, claims=[], stages=["section5"]))
    assert [(values, spread) for _, values, spread in rows] == [(["0.95", "0.91"], "0.04")]
    assert "vjCTrack" in rows[0][0]
