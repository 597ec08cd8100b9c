# Paper Section 5 results: scores of the predictor's rollouts (every variant and seed), as
# a result document and a per-object table. Table 3, Figure 2 and the stage's part: paper.smk.


rule section5:
    conda:
        IMPLY_ENV
    input:
        rollouts=model_rollouts(),
        table="results/table/table.npz",
        train_clips="results/clips/train.csv",
    output:
        metrics=report(
            "results/section5/metrics.json",
            caption="../report/section5_metrics.rst",
            category="Section 5, learned model",
            subcategory="Result documents",
        ),
        per_object=report(
            "results/section5/per_object.csv",
            caption="../report/section5_per_object.rst",
            category="Section 5, learned model",
            subcategory="Result documents",
        ),
    params:
        rollouts=rollouts_options,
        score=score_subset("grid", "readout_floor"),
        selection_seed=config["model"]["selection_seed"],
    threads: 1
    resources:
        mem_mb=3000,
        runtime=10,
    log:
        "results/logs/section5.log",
    shell:
        "imply section5 {params.rollouts} --table {input.table} --train-clips {input.train_clips}"
        " --score-json {params.score}"
        " --selection-seed {params.selection_seed} --metrics {output.metrics} --per-object {output.per_object}"
        " > {log} 2>&1"
