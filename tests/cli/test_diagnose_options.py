"""``imply diagnose`` and ``imply study gap diagnose-many`` share one set of options, checked once into one request;
command groups import nothing from each other but ``imply.cli.common``."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import imply.cli
from imply.cli import build_parser
from imply.cli.common import UserError, diagnose_request, user_errors
from sample_inputs import PUSHLOG_CSV

SHARED = [
    "--table",
    "t.npz",
    "--cache-dir",
    "c",
    "--effects",
    "tilt",
    "--effect-grid-json",
    '{"n_speeds": 4}',
    "--options-json",
    '{"alpha": 0.01}',
    "--noise-sd",
    "0.03",
    "--ignore-measured",
    "--threads",
    "2",
    "--force",
]


def _options(args) -> dict:
    keep = (
        "table",
        "cache_dir",
        "effects",
        "effect_grid_json",
        "options_json",
        "noise_sd",
        "ignore_measured",
        "threads",
        "force",
    )
    return {k: getattr(args, k) for k in keep}


def test_diagnose_and_diagnose_many_take_the_same_options():
    parser = build_parser()
    one = parser.parse_args(["diagnose", "log.csv", "-o", "r", *SHARED])
    many = parser.parse_args(["study", "gap", "diagnose-many", "a.csv", "b.csv", "-o", "r", *SHARED])
    assert _options(one) == _options(many)
    assert many.noise_sd == 0.03 and many.ignore_measured and many.options_json == {"alpha": 0.01}


def test_the_request_carries_every_option_checked(tmp_path, tiny_table_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("log.csv").write_text(PUSHLOG_CSV)
    args = build_parser().parse_args(["diagnose", "log.csv", "-o", "r", *SHARED[2:], "--table", str(tiny_table_path)])
    request = diagnose_request(args, [("log.csv", Path("r"))])
    assert [c.name for c in request.candidates] == ["tilt"]
    assert request.options.noise_sd == 0.03 and request.options.alpha == 0.01 and not request.options.use_measured
    assert request.grid.n_speeds == 4 and request.threads == 2 and request.force
    assert request.cache_dir == Path("c")
    (report,) = request.reports
    assert report.folder == Path("r") and report.pushlog.path == "log.csv" and report.pushlog.n == 6
    assert not Path("r").exists()  # checking writes nothing


def test_user_errors_become_one_line_with_their_context():
    with pytest.raises(UserError, match=r"^--model bad value$"), user_errors(ValueError, message="--model {error}"):
        raise ValueError("bad value")
    with pytest.raises(KeyError), user_errors(ValueError):  # other errors pass through
        raise KeyError("x")


def test_command_groups_import_only_common():
    folder = Path(imply.cli.__file__).parent
    from imply.cli.study import STUDY_GROUPS

    groups = [folder / f"{name}.py" for name in [*imply.cli.GROUPS, *STUDY_GROUPS]]
    assert len(groups) > 10 and all(p.is_file() for p in groups)
    for path in [*groups, folder / "common.py"]:
        tree = ast.parse(path.read_text())
        imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
        imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        # a group may import its own parts (imply.cli.gap_logs for gap.py), and nothing else of the CLI but common
        own = f"imply.cli.{path.stem}_"
        others = {
            m for m in imported if m.startswith("imply.cli") and m != "imply.cli.common" and not m.startswith(own)
        }
        assert not others, f"{path.name} imports {others}"
