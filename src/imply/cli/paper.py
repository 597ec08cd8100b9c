"""``imply study paper part|tables|figure1|figure2|merge``: the paper outputs, from the stages' result documents.

* ``part STAGE RESULT...``: every registered number of a stage (:mod:`imply.paper.registry`)
  read from its result documents, and the stage's claims checked on them;
* ``tables``: Tables 1 and 2 (from the section4 part) or Table 3 (from the section5 part);
* ``figure1``, ``figure2``: the figures, from the per-object scores;
* ``merge PART...``: ``macros.tex``, ``numbers.json`` and the reproduction report.
"""

from __future__ import annotations

import argparse
import logging
from typing import TYPE_CHECKING

from imply.cli.common import UserError, existing_file, int_range, user_errors

if TYPE_CHECKING:
    from imply.paper.parts import ClaimsFunction

log = logging.getLogger("imply.paper")


def register(sub: argparse._SubParsersAction) -> None:
    pp = sub.add_parser("paper", help="paper outputs: parts, tables, figures, macros, numbers, reproduction report")
    psub = pp.add_subparsers(dest="paper_command", required=True)

    p = psub.add_parser("part", help="a stage's registered numbers and checked claims (results/paper/parts/STAGE.json)")
    p.add_argument("stage", help="section4 | clips | section5 | gap")
    p.add_argument("results", nargs="+", type=existing_file, help="the stage's result documents")
    p.add_argument("-o", "--output", required=True, help="the stage's part to write (results/paper/parts/STAGE.json)")
    p.set_defaults(func=cmd_part)

    t = psub.add_parser("tables", help="the paper's tables as booktabs LaTeX, from a stage's part")
    t.add_argument(
        "--part", type=existing_file, required=True, help="the stage's part (results/paper/parts/STAGE.json)"
    )
    t.add_argument("--table1", help="Table 1 (.tex; from the section4 part)")
    t.add_argument("--table2", help="Table 2 (.tex; from the section4 part)")
    t.add_argument("--table3", help="Table 3 (.tex; from the section5 part)")
    t.set_defaults(func=cmd_tables)

    f1 = psub.add_parser("figure1", help="Figure 1 as PDF and PNG")
    f1.add_argument("--scores", type=existing_file, required=True, help="results/section4/scores.csv")
    f1.add_argument("--noise", type=existing_file, required=True, help="results/section4/noise.json")
    f1.add_argument("--pdf", required=True, help="the figure to write as PDF")
    f1.add_argument("--png", required=True, help="the figure to write as PNG")
    f1.set_defaults(func=cmd_figure1)

    f2 = psub.add_parser("figure2", help="Figure 2 as PDF and PNG")
    f2.add_argument("--per-object", type=existing_file, required=True, help="results/section5/per_object.csv")
    f2.add_argument("--seed", type=int_range(0), default=None, help="data-order seed shown (default: the smallest)")
    f2.add_argument("--pdf", required=True, help="the figure to write as PDF")
    f2.add_argument("--png", required=True, help="the figure to write as PNG")
    f2.set_defaults(func=cmd_figure2)

    m = psub.add_parser(
        "merge",
        help="merge result parts into macros.tex, numbers.json and the reproduction report",
        description="Merges every given part (results/paper/parts/<stage>.json); paper numbers that no part "
        "reports show as 'not produced'.",
    )
    m.add_argument("parts", nargs="*", type=existing_file, help="result part files")
    m.add_argument("--macros", required=True, help="macros.tex to write")
    m.add_argument("--numbers", required=True, help="numbers.json to write")
    m.add_argument("--report-md", required=True, help="reproduction.md to write")
    m.add_argument("--report-csv", required=True, help="reproduction.csv to write")
    m.add_argument("--report-html", help="reproduction.html to write (the page the Snakemake report shows)")
    m.add_argument(
        "--benchmarks",
        help="folder of the rules' benchmark files (results/benchmarks): the last run's "
        "time per rule and the jobs it waited on join the report",
    )
    m.set_defaults(func=cmd_merge)

    sn = psub.add_parser(
        "snapshot",
        help="copy a finished run's results that the documentation shows into a committed snapshot folder",
        description="Copies from ROOT/results the reproduction report, numbers.json, the stand-ins' known answers "
        "and every figure a documentation page names, with each stage's times, into the snapshot folder, and stamps "
        "it (snapshot.json: commit, date, machine, wall time, claims that hold); fills the README's snapshot line. "
        "The site shows the snapshot wherever results/ lacks a file.",
    )
    sn.add_argument("--root", default=".", help="the checkout whose results/ to take (default: here)")
    sn.add_argument("--kernels", help="the numerical kernels the run pinned (config kernels.pin)")
    sn.add_argument(
        "-o",
        "--output",
        default="docs/snapshot",
        help="the snapshot folder to write: snapshot.json and results/... (default %(default)s)",
    )
    sn.set_defaults(func=cmd_snapshot)


def cmd_snapshot(args: argparse.Namespace) -> int:
    from pathlib import Path

    from imply.paper.snapshot import label, write_snapshot

    with user_errors(FileNotFoundError, message="--root {error}"):
        stamp = write_snapshot(Path(args.root), Path(args.output), kernels=args.kernels)
    log.info("snapshot of %s -> %s", label(stamp), args.output)
    return 0


def stage_claims(stage: str) -> ClaimsFunction:
    """The function that checks a stage's claims: the one place that ties a stage to its claims' module.

    It lives here, above both the study and the paper, so that neither imports the other;
    imported on demand, so that a stage's heavy imports load only for that stage.
    """
    if stage == "section4":
        from imply.study.section4.claims import section4_claims

        return section4_claims
    if stage == "clips":
        from imply.study.readout_evaluation import readout_claims

        return readout_claims
    if stage == "section5":
        from imply.study.section5.claims import section5_claims

        return section5_claims
    if stage == "gap":
        from imply.realworld.benchmark_report import benchmark_claims

        return benchmark_claims
    if stage == "evaluate":
        from imply.study.section4.through_evaluate import known_answer_claims

        return known_answer_claims
    if stage == "pixel":
        from imply.study.pixel_model import pixel_claims

        return pixel_claims
    from imply.paper.registry import STAGES

    raise UserError(f"unknown stage {stage!r} (one of {', '.join(STAGES)})")


def stage_read_by(stage: str, results: dict) -> str | None:
    """What read the rollouts behind a stage's numbers, in one line (None: the stage reads none)."""
    if stage == "section5":
        from imply.study.section5.claims import section5_read_by

        return section5_read_by(results)
    return None


def cmd_part(args: argparse.Namespace) -> int:
    from imply.paper.parts import build_part, write_part
    from imply.paper.results import read_results

    claims_of_stage = stage_claims(args.stage)
    with user_errors(KeyError, ValueError, TypeError):
        results = read_results(args.results)
        numbers, claims = build_part(args.stage, results, claims=claims_of_stage)
        read_by = stage_read_by(args.stage, results)
    write_part(args.output, stage=args.stage, numbers=numbers, claims=claims, read_by=read_by)
    held = sum(c.holds for c in claims)
    log.info(
        "%s part: %d numbers, %d of %d claims hold -> %s", args.stage, len(numbers), held, len(claims), args.output
    )
    return 0


def cmd_tables(args: argparse.Namespace) -> int:
    from imply.io import write_text
    from imply.paper.latex_tables import table1_tex, table2_tex, table3_tex
    from imply.paper.parts import read_part
    from imply.paper.registry import load_registry

    values = load_registry().values(read_part(args.part)["numbers"])
    for path, build in ((args.table1, table1_tex), (args.table2, table2_tex), (args.table3, table3_tex)):
        if path:
            write_text(path, build(values))
            log.info("wrote %s", path)
    return 0


def cmd_figure1(args: argparse.Namespace) -> int:
    import pandas as pd

    from imply.paper.figures import figure1
    from imply.paper.results import read_result
    from imply.study.section4.standins import STANDINS

    _, noise = read_result(args.noise)
    figure1(pd.read_csv(args.scores), noise, standins=STANDINS, pdf_path=args.pdf, png_path=args.png)
    log.info("figure 1 -> %s, %s", args.pdf, args.png)
    return 0


def cmd_figure2(args: argparse.Namespace) -> int:
    import pandas as pd

    from imply.paper.figures import figure2

    per_object = pd.read_csv(args.per_object, dtype={"object_id": str})
    seed = args.seed if args.seed is not None else int(per_object["seed"].min())
    figure2(per_object, seed=seed, pdf_path=args.pdf, png_path=args.png)
    log.info("figure 2 -> %s, %s", args.pdf, args.png)
    return 0


def cmd_merge(args: argparse.Namespace) -> int:
    from imply.paper.macros import merge_parts, write_macros
    from imply.paper.registry import load_registry
    from imply.paper.report import write_report

    with user_errors(KeyError, ValueError):
        merged = merge_parts(args.parts)
    write_macros(merged, args.macros, args.numbers)
    timings = None
    if args.benchmarks:
        from imply.paper.timings import markdown, read_benchmarks

        timings = markdown(read_benchmarks(args.benchmarks))
    frame = write_report(
        load_registry(),
        merged,
        md_path=args.report_md,
        csv_path=args.report_csv,
        html_path=args.report_html,
        timings=timings,
    )
    counts = frame["status"].value_counts().to_dict()
    log.info("merged %d parts, %d numbers; paper numbers: %s", len(merged.stages), len(merged.numbers), counts)
    return 0
