# Paper Section 5 results: scores of the predictor's rollouts, Table 3, Figure 2, selection,
# the second seed's replication, and the stage's part of the paper outputs (imply.section5).


rule section5:
    conda:
        IMPLY_ENV
    input:
        rollouts=expand("results/model/{variant}/seed{seed}/rollouts.csv", variant=MODEL_VARIANTS, seed=MODEL_SEEDS),
        table="results/table/table.npz",
    output:
        metrics="results/section5/metrics.json",
        per_object="results/section5/per_object.csv",
        part="results/paper/parts/section5.json",
        table3="results/paper/tables/table3.tex",
        pdf="results/paper/figures/figure2.pdf",
        png="results/paper/figures/figure2.png",
    params:
        score=as_json({k: config["score"][k] for k in ("grid", "readout_floor")}),
        rollouts=" ".join(
            f"--rollouts {v}:{s}:results/model/{v}/seed{s}/rollouts.csv" for s in MODEL_SEEDS for v in MODEL_VARIANTS
        ),
        selection_seed=MODEL["selection_seed"],
    threads: 1
    resources:
        mem_mb=3000,
        runtime=10,
    log:
        "results/logs/section5.log",
    shell:
        "imply section5 {params.rollouts} --table {input.table} --score-json {params.score}"
        " --selection-seed {params.selection_seed} --out-dir results/section5 --part {output.part}"
        " --table-tex {output.table3} --figure results/paper/figures/figure2 > {log} 2>&1"


FINAL_TARGETS.extend(
    [
        "results/section5/metrics.json",
        "results/paper/tables/table3.tex",
        "results/paper/figures/figure2.pdf",
        "results/paper/figures/figure2.png",
    ]
)
PAPER_PARTS.append("results/paper/parts/section5.json")
