# The paper outputs: every stage's result part (PAPER_PARTS, filled by the stages' rules
# files, which are included before this one) merged into macros, numbers and the
# reproduction report. The merge picks up whatever parts exist in PAPER_PARTS; the
# optional config key paper.stages (a list of stage names) restricts it to those stages.

from imply.paper.values import default_path as _paper_values_path


def _paper_parts(wildcards):
    """Every stage's part, or only those of the stages in config paper.stages (e.g. a test)."""
    stages = config.get("paper", {}).get("stages")
    if stages is None:
        return sorted(PAPER_PARTS)
    return sorted(p for p in PAPER_PARTS if p.rsplit("/", 1)[-1].removesuffix(".json") in stages)


rule paper_merge:
    conda:
        IMPLY_ENV
    input:
        values=str(_paper_values_path()),
        parts=_paper_parts,
    output:
        macros="results/paper/macros.tex",
        numbers="results/paper/numbers.json",
        report_md="results/paper/reproduction.md",
        report_csv="results/paper/reproduction.csv",
    resources:
        mem_mb=500,
        runtime=1,
    log:
        "results/logs/paper_merge.log",
    shell:
        "imply paper merge {input.parts} --values {input.values} --macros {output.macros}"
        " --numbers {output.numbers} --report-md {output.report_md} --report-csv {output.report_csv}"
        " > {log} 2>&1"


FINAL_TARGETS.extend(
    [
        "results/paper/macros.tex",
        "results/paper/numbers.json",
        "results/paper/reproduction.md",
        "results/paper/reproduction.csv",
    ]
)
