"""One command-line convention, checked on every parser: help everywhere, -o/--output, one error prefix."""

from __future__ import annotations

import argparse
import subprocess
import sys

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


@pytest.mark.parametrize(
    ("argv", "prefix"),
    [
        ([], "imply: error:"),
        (["gap"], "imply gap: error:"),
        (["suite", "export"], "imply suite export: error:"),
        (["evaluate", "--suite", "/nonexistent", "-o", "REPORT", "--rollouts", "x.npz"], "imply evaluate: error:"),
        (["diagnose", "/nonexistent.csv", "-o", "REPORT", "--table", "/nonexistent.npz"], "imply diagnose: error:"),
        (["sim", "pushes", "/nonexistent.csv", "-o", "log.csv"], "imply sim pushes: error:"),
    ],
)
def test_every_refusal_is_one_line_with_the_command_s_prefix(tmp_path, argv, prefix):
    run = subprocess.run([sys.executable, "-m", "imply.cli", *argv], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(prefix + " "), run.stderr


def test_a_missing_suite_or_table_says_the_command_that_builds_it(tmp_path):
    suite = subprocess.run(
        [
            sys.executable,
            "-m",
            "imply.cli",
            "evaluate",
            "--suite",
            str(tmp_path / "none"),
            "-o",
            str(tmp_path / "r"),
            "--rollouts",
            "x.npz",
        ],
        capture_output=True,
        text=True,
    )
    assert "snakemake --cores 2 results/suite/manifest.json" in suite.stderr
    table = subprocess.run(
        [sys.executable, "-m", "imply.cli", "diagnose", "log.csv", "-o", "r"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert "snakemake --cores 2 results/table/table.npz" in table.stderr


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
