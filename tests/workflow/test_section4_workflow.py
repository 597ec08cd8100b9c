"""The Section 4 DAG and the paper merge, run by Snakemake on a small config in a temp dir."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from conftest import send_to_imply_server
from run_folders import built_once
from workflow_helpers import ROOT, copy_workflow, plant_table
from workflow_helpers import snakemake as run_snakemake

SMALL = ROOT / "tests" / "config" / "section4_small.yaml"
TARGETS = [
    "results/paper/reproduction.md",
    "results/paper/reproduction.csv",
    "results/paper/reproduction.html",
    "results/paper/macros.tex",
    "results/paper/numbers.json",
    "results/paper/tables/table1.tex",
    "results/paper/tables/table2.tex",
    "results/paper/figures/figure1.pdf",
    "results/paper/figures/figure1.png",
]
PAPER_S4_MACROS = [
    "nObjects",
    "kSpeeds",
    "jitterSd",
    "OrSelf",
    "JitCorr",
    "BlSelf",
    "BlAnch",
    "BlErr",
    "BlAurocSelf",
    "BlAurocAnch",
    "BlCorr",
    "orMassR",
    "orFricR",
    "selFirstMiss",
    "selConsMiss",
    "selAnchMiss",
    "selPickedOracle",
    "selK",
    "noiseMax",
    "noiseMaxAurocBlind",
]


def snakemake(workdir: Path, *args: str, over: Path | None = None) -> subprocess.CompletedProcess:
    """The small config's run (``over``: a config file over it) in ``workdir``; targets go in ``args``."""
    configs = [str(SMALL)] + ([str(over)] if over else [])
    return run_snakemake(workdir, *args, "--configfile", *configs, check=False, timeout=600)


@pytest.fixture(scope="module")
def dag_dir(tmp_path_factory, tiny_table_path, imply_server) -> Path:
    """The small config's Section 4 run, built by one test worker for both tests (the second only plans), its
    ``imply`` jobs in forks of the worker's fork server."""

    def build(work: Path) -> None:
        copy_workflow(work)
        # the small config's table grid is the tiny fixture's: reuse it instead of rebuilding
        plant_table(work, tiny_table_path)
        with pytest.MonkeyPatch.context() as env:
            send_to_imply_server(env, imply_server)
            proc = snakemake(work, *TARGETS)
        assert proc.returncode == 0, proc.stderr[-3000:]

    return built_once(tmp_path_factory, "s4dag", build)


@pytest.mark.slow
def test_dag_outputs(dag_dir):
    for t in TARGETS:
        assert (dag_dir / t).stat().st_size > 0, t
    part = json.loads((dag_dir / "results/paper/parts/section4.json").read_text())
    numbers = json.loads((dag_dir / "results/paper/numbers.json").read_text())
    # numbers.json carries the part's unrounded values under the same names
    for name, v in part["numbers"].items():
        assert numbers[name] == v or (numbers[name] is None and v != v), name
    v = part["numbers"]
    # by construction: the oracle explains its own rollouts almost exactly, collapse does not
    assert v["OrSelf"] < 0.05 and v["OrErr"] == 0.0
    assert v["ColSelf"] > 1.0 and v["ColAurocSelf"] == 1.0
    assert v["nObjects"] == 12 and v["kSpeeds"] == 5 and v["selK"] == 4 and v["tableNSpeeds"] == 7
    assert v["selOracPickedOracle"] == 100.0
    macros = (dag_dir / "results/paper/macros.tex").read_text()
    for name in PAPER_S4_MACROS:
        assert f"\\newcommand{{\\{name}}}{{" in macros, name
    assert "\\newcommand{\\nObjects}{12}" in macros and "\\newcommand{\\jitterSd}{0.25}" in macros
    report = (dag_dir / "results/paper/reproduction.md").read_text()
    for claim in part["claims"]:
        assert claim["statement"] in report
    assert "not produced" in report  # Section 5 numbers: no part for them in this run
    # every rule wrote its benchmark, and the report times the run rule by rule with its critical path
    assert (dag_dir / "results/benchmarks/s4_standins/all.tsv").is_file()
    assert (dag_dir / "results/benchmarks/paper_part/section4.tsv").is_file()
    assert "## Time per rule" in report and "| s4_standins | 1 |" in report and "A core stood idle for" in report
    csv = (dag_dir / "results/paper/reproduction.csv").read_text().splitlines()
    assert csv[0] == "name,section,paper,reproduced,reproduced_unrounded,stage,status,read_by"
    assert any(line.startswith("vjCTrack,5,0.91,not produced") for line in csv)
    assert (dag_dir / "results/paper/figures/figure1.png").read_bytes()[:4] == b"\x89PNG"
    assert (dag_dir / "results/paper/figures/figure1.pdf").read_bytes()[:4] == b"%PDF"
    t1 = (dag_dir / "results/paper/tables/table1.tex").read_text()
    assert t1.count("\\\\") == 6 and "\\bottomrule" in t1
    for log in ("s4_truth", "s4_standins", "paper_part_section4", "paper_merge"):
        assert (dag_dir / "results/logs" / f"{log}.log").exists()


@pytest.mark.slow
def test_dag_up_to_date_and_param_scoped_reruns(dag_dir, forked_imply):
    proc = snakemake(dag_dir, *TARGETS, "-n")
    assert proc.returncode == 0 and "Nothing to be done" in proc.stdout + proc.stderr
    # changing only the selection settings reruns only the selection and what follows it
    over = dag_dir / "over.yaml"
    over.write_text("section4:\n  selection:\n    noise_sd: 0.05\n")
    proc = snakemake(dag_dir, *TARGETS, "-n", over=over)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout + proc.stderr
    stats = out[out.index("Job stats") :].splitlines()[3:]
    jobs = {line.split()[0] for line in stats[: next(i for i, x in enumerate(stats) if x.startswith("total"))]}
    assert jobs == {"s4_selection", "paper_part", "paper_tables_section4", "paper_merge"}
