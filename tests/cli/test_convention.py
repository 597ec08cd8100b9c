"""One command-line convention, checked on every parser: help everywhere, -o/--output, one error prefix."""

from __future__ import annotations

import argparse

import pytest

from imply.cli import build_parser


def _commands(parser: argparse.ArgumentParser, words: tuple[str, ...] = ("imply",)):
    """(words, parser, help) of every command, depth first."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help for choice in action._choices_actions}
            for name, sub in action.choices.items():
                yield (*words, name), sub, helps.get(name)
                yield from _commands(sub, (*words, name))


COMMANDS = list(_commands(build_parser()))


def test_every_command_option_and_positional_has_help():
    missing = []
    for words, parser, help_ in COMMANDS:
        if not help_ or not parser.description:
            missing.append(" ".join(words))
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
                continue
            if not action.help:
                missing.append(f"{' '.join(words)} {action.option_strings or action.dest}")
    assert missing == []


def test_every_output_option_is_dash_o_output():
    """An option that names a file or folder the command writes is -o/--output (a second output is its own
    named option, e.g. --markdown, never --out)."""
    for words, parser, _ in COMMANDS:
        for action in parser._actions:
            strings = set(action.option_strings)
            assert not strings & {"--out", "--out-npz", "--out-csv", "--outdir"}, words
            if "-o" in strings:
                assert strings == {"-o", "--output"}, words


def _refusal(argv: list[str], capsys) -> tuple[int, str]:
    """Run ``imply ARGV`` in this process: its exit status and what it printed on stderr."""
    from imply.cli import main

    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's usage errors exit through the parser
        code = exc.code
    return code, capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "prefix"),
    [
        ([], "imply: error:"),
        (["study", "gap"], "imply study gap: error:"),
        (["suite", "export"], "imply suite export: error:"),
        (["evaluate", "--suite", "/nonexistent", "-o", "REPORT", "--rollouts", "x.npz"], "imply evaluate: error:"),
        (["diagnose", "/nonexistent.csv", "-o", "REPORT", "--table", "/nonexistent.npz"], "imply diagnose: error:"),
        (["sim", "pushes", "/nonexistent.csv", "-o", "log.csv"], "imply sim pushes: error:"),
    ],
)
def test_every_refusal_is_one_line_with_the_command_s_prefix(tmp_path, monkeypatch, capsys, argv, prefix):
    monkeypatch.chdir(tmp_path)
    code, err = _refusal(argv, capsys)
    lines = [line for line in err.strip().splitlines() if not line.startswith("20")]  # log lines carry a date
    assert code == 2
    assert len(lines) == 1 and lines[0].startswith(prefix + " "), err


def test_a_missing_suite_or_table_says_the_command_that_builds_it(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    _, suite = _refusal(["evaluate", "--suite", "none", "-o", "r", "--rollouts", "x.npz"], capsys)
    assert "snakemake --cores 2 results/suite/manifest.json" in suite
    _, table = _refusal(["diagnose", "log.csv", "-o", "r"], capsys)
    assert "snakemake --cores 2 results/table/table.npz" in table


@pytest.mark.parametrize(
    ("command", "module"),
    [("diagnose", "imply.diagnose.report"), ("evaluate", "imply.evaluate.report")],
)
def test_a_report_command_s_help_names_every_file_it_writes(command, module):
    import importlib

    parser = dict((" ".join(w), p) for w, p, _ in COMMANDS)[f"imply {command}"]
    text = " ".join(parser.format_help().split())
    for name in importlib.import_module(module).REPORT_FILES:
        stem, _, ext = name.rpartition(".")
        assert name in text or f"{stem}.png/.{ext}" in text or f"{stem}.png/.pdf" in text, name


def test_a_study_step_without_study_names_the_command_to_run(capsys):
    code, err = _refusal(["--log", "run.log", "gap", "tables", "--table", "t.npz"], capsys)
    assert code == 2
    assert (
        err.strip()
        == "imply: error: 'gap' is a step of the study: run 'imply study gap ...' (see 'imply study --help')"
    )


def test_the_top_level_help_lists_the_user_s_commands_and_one_study_group():
    from imply.cli import GROUPS
    from imply.cli.study import STUDY_GROUPS

    top = {words[1] for words, _, _ in COMMANDS if len(words) == 2}
    assert top == set(GROUPS) == {"score", "table", "sim", "diagnose", "suite", "evaluate", "study"}
    assert {words[2] for words, _, _ in COMMANDS if len(words) >= 3 and words[1] == "study"} == set(STUDY_GROUPS)
