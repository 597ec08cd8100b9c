"""Subcommands of the controlled validation and of the paper outputs.

``imply section4 STEP`` runs one step of :mod:`imply.section4` (objects, truth,
standins, scores, metrics, noise, selection, part, tables, figure); each workflow rule
of ``workflow/rules/section4.smk`` calls one, passing only its config subset as JSON.
``imply paper merge`` merges every stage's result part into ``macros.tex``,
``numbers.json`` and the reproduction report (``workflow/rules/paper.smk``).

Config subsets: ``--section4-json`` is (part of) config key ``section4`` -- the keys a
step reads: ``seed`` and ``objects`` (objects), ``seed`` and ``standins`` (standins),
``standins.jitter_sd`` (metrics), ``seed`` and ``noise`` (noise), ``seed`` and
``selection`` (selection, part); ``--score-json`` is config key ``score``;
``--scene-json`` is config key ``scene``.
"""

from __future__ import annotations

import argparse
import functools
import json
import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

from imply.cli import UserError, existing_file, json_arg
from imply.io import write_csv, write_json, write_text

if TYPE_CHECKING:
    import pandas as pd

    from imply.table import PushTable

log = logging.getLogger("imply.section4")


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``imply section4 ...`` and ``imply paper ...``."""
    s4 = sub.add_parser("section4", help="the controlled validation (paper Section 4), step by step")
    ssub = s4.add_subparsers(dest="section4_command", required=True)

    def step(name: str, help_: str, func, inputs: list[str], outputs: list[str], opts: list[str]):
        p = ssub.add_parser(name, help=help_)
        for flag in inputs:
            p.add_argument(f"--{flag}", required=True, type=existing_file)
        for flag in outputs:
            p.add_argument(
                f"--{flag}" if flag != "output" else "-o",
                required=True,
                **({"dest": "output"} if flag == "output" else {}),
            )
        for opt in opts:
            if opt == "threads":
                p.add_argument("--threads", type=int, default=0, help="simulation threads (0: all CPUs)")
            else:
                p.add_argument(f"--{opt}-json", type=json_arg, required=True, help=f"config key '{opt}' as JSON")
        p.set_defaults(func=_user_errors(func))
        return p

    step("objects", "draw evaluation and training objects", cmd_objects, ["table"], ["output"], ["section4", "scene"])
    step(
        "truth", "simulate the objects' true pushes", cmd_truth, ["objects"], ["output"], ["score", "scene", "threads"]
    )
    step(
        "standins", "the four stand-ins' rollouts", cmd_standins, ["objects", "truth", "table"], ["output"],
        ["section4", "score", "scene", "threads"],
    )  # fmt: skip
    step(
        "scores",
        "score every stand-in's rollouts",
        cmd_scores,
        ["objects", "truth", "rollouts", "table"],
        ["output"],
        ["score"],
    )
    step(
        "metrics",
        "Table 1 and the oracle's recovery",
        cmd_metrics,
        ["scores", "table"],
        ["output"],
        ["section4", "score"],
    )
    step(
        "noise",
        "readout-noise sweep (Table 2 top)",
        cmd_noise,
        ["truth", "rollouts", "table"],
        ["output"],
        ["section4", "score"],
    )
    step(
        "selection", "selection among candidates (Table 2 bottom)", cmd_selection, ["truth", "rollouts", "table"],
        ["output", "choices"], ["section4", "score"],
    )  # fmt: skip
    step(
        "part",
        "Section 4 numbers and claims as a result part",
        cmd_part,
        ["metrics", "noise", "selection"],
        ["output"],
        ["section4"],
    )
    step("tables", "Tables 1 and 2 as booktabs LaTeX", cmd_tables, ["part"], ["table1", "table2"], [])
    step("figure", "Figure 1 as PDF and PNG", cmd_figure, ["scores", "noise"], ["pdf", "png"], [])

    pp = sub.add_parser("paper", help="paper outputs: macros, numbers, reproduction report")
    psub = pp.add_subparsers(dest="paper_command", required=True)
    m = psub.add_parser(
        "merge",
        help="merge result parts into macros.tex, numbers.json and the reproduction report",
        description="Merges every given part (results/paper/parts/<stage>.json); paper numbers that no part "
        "reports show as 'not produced'.",
    )
    m.add_argument("parts", nargs="*", type=existing_file, help="result part files")
    m.add_argument("--values", type=existing_file, help="the paper's values CSV (default: the package's)")
    m.add_argument("--macros", required=True, help="macros.tex to write")
    m.add_argument("--numbers", required=True, help="numbers.json to write")
    m.add_argument("--report-md", required=True, help="reproduction.md to write")
    m.add_argument("--report-csv", required=True, help="reproduction.csv to write")
    m.set_defaults(func=_user_errors(cmd_paper_merge))


def _user_errors(func):
    """Report bad inputs or settings in one line (exit 2) instead of a traceback."""

    @functools.wraps(func)
    def wrapper(args: argparse.Namespace) -> int:
        import pandas as pd

        from imply.table import TableError

        try:
            return func(args)
        except UserError:
            raise
        except (TableError, KeyError, ValueError, pd.errors.ParserError) as exc:
            msg = f"missing setting or column {exc}" if isinstance(exc, KeyError) else str(exc)
            raise UserError(msg) from exc

    return wrapper


def _table(args) -> PushTable:
    from imply.table import PushTable

    return PushTable.load(args.table)


def _scene(args):
    from imply.sim import SceneConfig

    return SceneConfig.from_dict(args.scene_json)


def _csv(path: Path) -> pd.DataFrame:
    import pandas as pd

    return pd.read_csv(path, keep_default_na=True)


def _need(cfg: dict[str, Any], *keys: str, where: str = "section4") -> None:
    for k in keys:
        if k not in cfg:
            raise UserError(f"--{where}-json: missing key {k!r}")


def cmd_objects(args) -> int:
    from imply import section4 as s4

    _need(args.section4_json, "seed", "objects")
    frame = s4.draw_objects(args.section4_json["objects"], _scene(args), int(args.section4_json["seed"]), _table(args))
    write_csv(args.output, frame)
    log.info("drew %d objects -> %s", len(frame), args.output)
    return 0


def cmd_truth(args) -> int:
    from imply import section4 as s4

    sc = args.score_json
    frame = s4.simulate_truth(
        _csv(args.objects), sc["query_speeds"], sc["calibration_speeds"], _scene(args), args.threads, progress=True
    )
    n_bad = int((~frame["ok"].astype(bool)).sum())
    if n_bad:
        log.warning("%d true pushes failed the simulator's checks; kept as simulated", n_bad)
    write_csv(args.output, frame)
    log.info("simulated %d true pushes -> %s", len(frame), args.output)
    return 0


def cmd_standins(args) -> int:
    from imply import section4 as s4

    cfg, sc = args.section4_json, args.score_json
    _need(cfg, "seed", "standins")
    frame = s4.make_standins(
        _csv(args.objects), _csv(args.truth), cfg["standins"], int(cfg["seed"]), _table(args),
        sc["query_speeds"], sc["calibration_speeds"], float(sc["readout_floor"]), _scene(args),
        args.threads, progress=True,
    )  # fmt: skip
    write_csv(args.output, frame)
    log.info("wrote %d stand-in rollouts -> %s", len(frame), args.output)
    return 0


def cmd_scores(args) -> int:
    from imply import section4 as s4

    frame = s4.score_rollouts(_table(args), _csv(args.objects), _csv(args.truth), _csv(args.rollouts), args.score_json)
    write_csv(args.output, frame)
    log.info("scored %d rollout sets -> %s", len(frame), args.output)
    return 0


def cmd_metrics(args) -> int:
    from imply import section4 as s4

    cfg = args.section4_json
    _need(cfg, "standins")
    out = s4.table1_metrics(
        _csv(args.scores), _table(args), float(cfg["standins"]["jitter_sd"]), len(args.score_json["query_speeds"])
    )
    write_json(args.output, out)
    log.info("Table 1 metrics -> %s", args.output)
    return 0


def cmd_noise(args) -> int:
    from imply import section4 as s4

    cfg = args.section4_json
    _need(cfg, "seed", "noise")
    frame = s4.noise_sweep(
        _table(args), _csv(args.truth), _csv(args.rollouts), cfg["noise"], int(cfg["seed"]), args.score_json
    )
    write_csv(args.output, frame)
    log.info("noise sweep -> %s", args.output)
    return 0


def cmd_selection(args) -> int:
    from imply import section4 as s4

    cfg = args.section4_json
    _need(cfg, "seed", "selection")
    summary, choices = s4.selection_study(
        _table(args), _csv(args.truth), _csv(args.rollouts), cfg["selection"], int(cfg["seed"]), args.score_json
    )
    write_csv(args.choices, choices)
    write_csv(args.output, summary)
    log.info("selection -> %s", args.output)
    return 0


def cmd_part(args) -> int:
    from imply import section4 as s4
    from imply.paper.parts import write_part

    cfg = args.section4_json
    _need(cfg, "selection")
    with open(args.metrics) as fh:
        metrics = json.load(fh)
    numbers, claims = s4.section4_part(metrics, _csv(args.noise), _csv(args.selection), cfg)
    write_part(args.output, "section4", numbers, claims)
    held = sum(c.holds for c in claims)
    log.info("section4 part: %d numbers, %d of %d claims hold -> %s", len(numbers), held, len(claims), args.output)
    return 0


def cmd_tables(args) -> int:
    from imply.paper.parts import read_part
    from imply.paper.tables import table1_tex, table2_tex

    numbers = read_part(args.part)["numbers"]
    write_text(args.table1, table1_tex(numbers))
    write_text(args.table2, table2_tex(numbers))
    log.info("tables -> %s, %s", args.table1, args.table2)
    return 0


def cmd_figure(args) -> int:
    from imply.paper.figures import figure1

    figure1(_csv(args.scores), _csv(args.noise), args.pdf, args.png)
    log.info("figure 1 -> %s, %s", args.pdf, args.png)
    return 0


def cmd_paper_merge(args) -> int:
    from imply.paper.macros import merge_parts, write_macros
    from imply.paper.report import write_report
    from imply.paper.values import load_paper_values

    values = load_paper_values(args.values)
    merged = merge_parts(args.parts)
    write_macros(merged, args.macros, args.numbers)
    frame = write_report(values, merged, args.report_md, args.report_csv)
    counts = frame["status"].value_counts().to_dict()
    log.info("merged %d parts, %d numbers; paper numbers: %s", len(merged.stages), len(merged.numbers), counts)
    return 0
