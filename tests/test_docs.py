"""The documentation: generated reference pages that list every option, placeholders, the built site, the tutorials.

The reference pages are compared with the settings classes and the argparse parsers walked
here on their own (not with the generator's walk); the site is built as CI builds it; the
commands of the tutorials run on tiny inputs.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
import shlex
import subprocess
import sys
import typing
from pathlib import Path

import pytest

from imply import docs_pages
from imply.options import Config
from sample_inputs import EFFECT_GRID_JSON

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


# -- the settings classes and parsers, walked independently ------------------------------


def settings_keys(cls: type, prefix: str = "", instance=None) -> dict[str, dataclasses.Field]:
    """Dotted key -> field, for every field of ``cls`` and of the settings classes it nests."""
    out = {}
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        key = prefix + f.name
        out[key] = f
        hint = hints[f.name]
        value = getattr(instance, f.name, None) if instance is not None else None
        nested = [a for a in (hint, *typing.get_args(hint)) if isinstance(a, type) and issubclass(a, Config)]
        if not nested:
            continue
        if typing.get_origin(hint) is dict:
            for name, entry in (value or {}).items():
                out |= settings_keys(nested[0], f"{key}.{name}.", entry)
        else:
            out |= settings_keys(nested[0], f"{key}.", value if isinstance(value, nested[0]) else None)
    return out


def study_keys() -> dict[str, dataclasses.Field]:
    from imply.workflow_config import StudyConfig

    return settings_keys(StudyConfig, "", StudyConfig())


def parser_commands(parser: argparse.ArgumentParser, words=("imply",)) -> dict[str, list[str]]:
    """'imply sim pushes' -> the names of its arguments (option strings, positionals' metavar or dest)."""
    out = {" ".join(words): []}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out |= parser_commands(sub, (*words, name))
        elif not isinstance(action, argparse._HelpAction):
            out[" ".join(words)] += list(action.option_strings) or [action.metavar or action.dest]
    return out


def section(page: str, title: str) -> str:
    """The text of ``page`` from heading ``title`` to the next heading of any level."""
    m = re.search(rf"^#+ {re.escape(title)}\n(.*?)(?=^#+ |\Z)", page, re.M | re.S)
    assert m, f"no heading {title!r}"
    return m.group(1)


# -- the reference pages --------------------------------------------------------------------


def test_the_config_reference_lists_every_key_with_its_type_default_and_doc():
    page = docs_pages.config_reference()
    keys = study_keys()
    assert len(keys) > 300  # the whole study config, nested keys and both model presets included
    rows = {line.split("|")[1].strip().strip("`"): line for line in page.splitlines() if line.startswith("| `")}
    missing = sorted(set(keys) - set(rows))
    assert not missing, f"keys missing from the config reference: {missing}"
    assert not set(rows) - set(keys), "the reference lists keys the settings classes do not have"
    for key, f in keys.items():
        assert docs_pages.cell(f.metadata["doc"]) in rows[key], key
    # defaults are the study's values, bounds in words
    assert "| `40` |" in rows["model.train.epochs"]
    assert "≥ 1" in rows["threads"] and "one of avx2, numpy-avx2, native" in rows["kernels.pin"]
    assert "`1024`" in rows["model.presets.vitg-300m.width"]
    assert "list of 3 numbers" in rows["scene.box_half_extents"]


def test_the_cli_reference_lists_every_command_and_option():
    from imply.cli import build_parser

    page = docs_pages.cli_reference()
    commands = parser_commands(build_parser())
    assert {"imply evaluate", "imply diagnose", "imply sim pushes", "imply study paper merge"} <= set(commands)
    for name, options in commands.items():
        text = section(page, f"`{name}`")
        for option in options:
            assert f"`{option}`" in text, f"{name}: {option} missing from the CLI reference"
    # a default from a settings class, and a command's description
    assert "`101`" in section(page, "`imply score`")
    assert "object_id,role,speed,displacement" in section(page, "`imply score`")


def test_the_formats_page_holds_each_format_module_and_its_column_lists():
    page = docs_pages.formats_reference()
    from imply.diagnose.inputs import pushlog
    from imply.score_file import SCORE_COLUMNS

    for column in [*pushlog.REQUIRED, *pushlog.OPTIONAL_NUMERIC, *SCORE_COLUMNS]:
        assert f"`{column}`" in page, column
    for fmt in docs_pages.FORMATS:
        assert f"## {fmt.title}" in page and f"`{fmt.module}`" in page
    # reStructuredText made Markdown: no roles or double backticks left, literal blocks fenced
    prose = re.sub(r"```text\n.*?```", "", page, flags=re.S)
    assert ":func:" not in prose and ":class:" not in prose and "``" not in prose
    assert '```text\nformat       "imply-rollouts"' in page


def test_rst_to_markdown_handles_the_docstring_subset():
    text = """Intro line ``code`` and :func:`imply.x.y` and :class:`~imply.Z`.

    Layout, in
    two lines::

        a   b
            c

    ``term.json``
        what the term is,
        on two lines
    * item one
      continues
        - nested
    > 0 starts a line
    """
    md = docs_pages.rst_to_markdown(text)
    assert "`code`" in md and "`imply.x.y`" in md and "`imply.Z`" in md
    assert "Layout, in two lines:\n\n```text\na   b\n    c\n```" in md
    assert "`term.json`\n:   what the term is, on two lines" in md
    assert "- item one continues\n    - nested" in md
    assert "\\> 0 starts a line" in md


# -- placeholders and the status page ------------------------------------------------------


def test_placeholders_read_config_and_results_or_say_when_they_appear(tmp_path):
    (tmp_path / "config.yaml").write_text("model:\n  train: {epochs: 60}\nscore:\n  query_speeds: [0.25, 0.4]\n")
    ctx = docs_pages.Context(root=tmp_path)
    out = docs_pages.expand("{{ config model.train.epochs }} / {{ config score.query_speeds }}", "a/b.md", ctx)
    assert out == "60 / 0.25, 0.4"
    with pytest.raises(ValueError, match="unknown placeholder"):
        docs_pages.expand("{{ figur x.png }}", "a.md", ctx)
    with pytest.raises(KeyError):
        docs_pages.expand("{{ config model.nope }}", "a.md", ctx)

    page = "{{ figure results/x/fig.png | A caption }}"
    assert "appears here once it has been built" in docs_pages.expand(page, "tutorials/t.md", ctx)
    assert "appear" in docs_pages.expand("{{ stage_times }}", "t.md", ctx)
    assert "appears here once" in docs_pages.expand("{{ standins }}", "t.md", ctx)

    (tmp_path / "results" / "x").mkdir(parents=True)
    (tmp_path / "results" / "x" / "fig.png").write_bytes(b"png")
    assert "![A caption](../figures/x/fig.png)" in docs_pages.expand(page, "tutorials/t.md", ctx)
    (tmp_path / "docs" / "tutorials").mkdir(parents=True)
    (tmp_path / "docs" / "tutorials" / "t.md").write_text(page)
    assert docs_pages.figure_files(tmp_path / "docs", tmp_path) == {"figures/x/fig.png": tmp_path / "results/x/fig.png"}

    bench = tmp_path / "results" / "benchmarks" / "table"
    bench.mkdir(parents=True)
    (bench / "all.tsv").write_text("s\th:m:s\tmax_rss\tcpu_time\n42.5\t0:00:42\t300\t80.0\n")
    (tmp_path / "workflow" / "rules").mkdir(parents=True)
    (tmp_path / "workflow" / "rules" / "table.smk").write_text("rule table:\n    output: 'x'\n")
    times = docs_pages.expand("{{ stage_times }}", "t.md", ctx)
    assert "| table | table | 1 | 42 | 42 | 80 |" in times

    standins = {
        "result": {
            "n_objects": 3,
            "readout": {"name": "frame difference", "r2_check": 0.99, "error_check": 0.05},
            "standins": {
                "oracle": {
                    "model": "oracle",
                    "condition": "own",
                    "track": 0.987,
                    "error": 0.07,
                    "self": 0.03,
                    "anchored": 0.04,
                    "static_share": 0.0,
                }
            },
        }
    }
    (tmp_path / "results" / "evaluate").mkdir(parents=True)
    (tmp_path / "results" / "evaluate" / "standins.json").write_text(json.dumps(standins))
    table = docs_pages.expand("{{ standins }}", "t.md", ctx)
    assert "| oracle | 0.99 | 0.070 | 0.030 | 0.040 | n/a | n/a | 0% |" in table


def test_the_status_page_says_when_the_study_has_not_run_and_shows_the_report_when_it_has(tmp_path):
    page = docs_pages.status_page(tmp_path)
    assert "has not run in this checkout" in page
    paper = tmp_path / "results" / "paper"
    paper.mkdir(parents=True)
    (paper / "reproduction.md").write_text(
        "# Reproduction report\n\n## Summary\n\n- Claims checked: 2; hold: 1; fail: 1.\n"
    )
    (paper / "numbers.json").write_text(json.dumps({"a": 1.5, "b": None}))
    page = docs_pages.status_page(tmp_path)
    assert "has not run" not in page
    assert "### Summary" in page and "Claims checked: 2; hold: 1; fail: 1." in page
    assert "(2 numbers, 1 undefined;" in page


# -- the site, built as CI builds it -------------------------------------------------------


def test_the_site_builds_strict_with_every_key_and_option(docs_site):
    from imply.cli import build_parser

    site = docs_site
    config = (site / "reference" / "config" / "index.html").read_text()
    assert all(f"<code>{key}</code>" in config for key in study_keys())
    cli = (site / "reference" / "cli" / "index.html").read_text()
    options = {o for opts in parser_commands(build_parser()).values() for o in opts if o.startswith("-")}
    assert all(f"<code>{o}</code>" in cli for o in options)
    for page in ("tutorials/reproduce", "tutorials/evaluate", "tutorials/diagnose", "status", "reference/formats"):
        html = (site / page / "index.html").read_text()
        assert "{{" not in html, page  # every placeholder filled


# -- the README and the tutorials ----------------------------------------------------------


def test_the_readme_is_short_says_the_stand_ins_plainly_and_links_into_the_docs():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 200
    assert "real V-JEPA 2 architecture" in text and "small CPU stand-in" in text
    for target in re.findall(r"\]\(((?:docs/|CHANGELOG)[^)#]*)", text):
        assert (ROOT / target).exists(), target
    assert (ROOT / "CHANGELOG.md").is_file()


def bash_blocks(page: Path) -> list[str]:
    return re.findall(r"```bash\n(.*?)```", page.read_text(), re.S)


def test_every_workflow_target_the_docs_name_is_a_target_of_the_workflow(tmp_path, forked_imply):
    from workflow_helpers import copy_workflow, snakemake

    targets = set()
    for page in sorted(DOCS.rglob("*.md")):
        for block in bash_blocks(page):
            for line in block.splitlines():
                if line.startswith("snakemake ") and "--profile" not in line:
                    targets |= {w for w in shlex.split(line.split("#")[0]) if w.startswith("results/")}
    assert {"results/table/table.npz", "results/suite/manifest.json", "results/paper/figures/figure1.png"} <= targets
    work = copy_workflow(tmp_path / "work")
    snakemake(work, "-n", *sorted(targets))


@pytest.mark.slow
def test_the_diagnose_tutorial_runs_as_written_and_finds_the_slope(
    tmp_path, tiny_table_path, effect_cache, forked_imply
):
    """Every command of the diagnose tutorial, in order, on the tiny table (the diagnosis on three candidate effects and
    a coarse effect grid, so that it takes seconds), each ``imply`` in a fork of the worker's fork server."""
    (tmp_path / "results" / "table").mkdir(parents=True)
    (tmp_path / "results" / "table" / "table.npz").symlink_to(tiny_table_path)
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    fast = [
        "--effects",
        "tilt,speed_gain,viscous",
        "--effect-grid-json",
        EFFECT_GRID_JSON,
        "--cache-dir",
        str(effect_cache),
        "--threads",
        "2",
    ]
    one_refit_iteration = ["--options-json", '{"refit_iterations": 1}']
    prelude = (
        f"set -euo pipefail\nPY={shlex.quote(sys.executable)}\n"
        "snakemake() { test -e results/table/table.npz; }\n"  # the table is there: the tiny one
        'python() { "$PY" "$@"; }\n'
        # the refit in one Levenberg-Marquardt iteration from the tables' estimate (a third of the default's time)
        f'imply() {{ local refit=(); case " $* " in *" --refit "*) refit=({shlex.join(one_refit_iteration)});; esac; '
        f'if [ "$1" = diagnose ]; then command imply "$@" {shlex.join(fast)} "${{refit[@]}}"; '
        'else command imply "$@"; fi; }\n'
    )
    blocks = bash_blocks(DOCS / "tutorials" / "diagnose.md")
    assert len(blocks) == 8
    proc = subprocess.run(["bash", "-c", prelude + "\n".join(blocks)], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((tmp_path / "gap-report" / "summary.json").read_text())
    assert summary["verdict"]["effects"] == ["tilt"], summary["verdict"]
    tilt = next(e for e in summary["effects"] if e["effect"] == "tilt")
    assert (
        abs(abs(tilt["magnitude"]) - 0.0255) < 0.006
    )  # atan(0.25 / 9.81), the slope simulated (one direction: signed)
    again = json.loads((tmp_path / "gap-report-2" / "summary.json").read_text())
    assert again["verdict"]["effects"] == ["tilt"]
    n_first = sum(1 for _ in open(tmp_path / "pushlog.csv"))
    assert sum(1 for _ in open(tmp_path / "pushlog2.csv")) > n_first
    filmed = json.loads((tmp_path / "gap-report-filmed" / "summary.json").read_text())
    assert (tmp_path / "filmed.track.csv").is_file()
    assert filmed["observables"][-3:] == ["crossing_25", "crossing_50", "crossing_75"], filmed["observables"]
    assert filmed["verdict"]["effects"] == ["tilt"], filmed["verdict"]
    probes = (tmp_path / "probed.probes.csv").read_text().splitlines()
    assert {line.split(",")[0] for line in probes[1:]} == {"free_stroke", "friction", "added_mass"}
    probed = json.loads((tmp_path / "gap-report-probed" / "summary.json").read_text())
    assert "calibration probes" in probed["observables_note"]
    # against the reference session, the slope is what changed, beside the soft pusher's standing gap
    since = json.loads((tmp_path / "gap-report-since" / "summary.json").read_text())
    assert since["verdict"]["effects"] == ["tilt"], since["sentence"]
    assert since["reference"]["pushes_matched"] == since["n_pushes"]
    assert since["reference"]["standing"]["adequacy"] != "no_gap"
    assert (tmp_path / "gap-report-since" / "report.md").read_text().count("Since the reference, the gap") == 1
    # against the reference, the corrected scene holds what changed and the standing gap's stated causes
    sources = {c["cause"]: c["source"] for c in since["simulator"]["causes"]}
    assert sources["tilt"] == "stated"
    standing = set(since["reference"]["standing"]["effects"]) - {"tilt"}
    assert {sources.get(e) for e in standing} <= {"standing"} and set(sources) == standing | {"tilt"}
    assert (tmp_path / "gap-report-since" / "corrected.xml").is_file()
    # the slope in the simulator: corrected.xml's gravity, re-simulated and refitted; the pushes re-run there
    refit = json.loads((tmp_path / "gap-report-refit" / "summary.json").read_text())["simulator"]
    assert refit["causes"][0]["cause"] == "tilt" and refit["refit"]["excludes_zero"]
    assert refit["share_closed"] > 0.8 and not refit["simulator_contradicts"]
    again_log = (tmp_path / "again.csv").read_text().splitlines()
    assert len(again_log) == n_first
