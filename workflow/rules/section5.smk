# Paper Section 5 results: each trained predictor runs through `imply evaluate` as a latents
# world model (imply.models.world_model), its rollouts read by a ridge fitted on its encoder's
# tokens of the suite's real training clips; the reports are scored into a result document and
# a per-object table. Table 3, Figure 2 and the stage's part: paper.smk.


rule section5_suite_nocalib:
    conda:
        IMPLY_ENV
    input:
        table="results/table/table.npz",
    output:
        [f"results/section5/suite_nocalib/{f}" for f in SUITE_FILES],
    params:
        # the model trained without calibration is scored on its own held-out objects, all of them
        suite=as_json(
            {**config["suite"], "split": "heldout_nocalib", "n_objects": config["clips"]["n_heldout_nocalib"]}
        ),
        clips=suite_clips_json(),
        scene=as_json(config["scene"]),
        score=score_subset("calibration_speeds", "query_speeds"),
        out=lambda wildcards, output: Path(output[0]).parent,
    # one thread: its files are the same with more, and a job asking for both cores waits until both are idle
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    log:
        "results/logs/section5_suite_nocalib.log",
    benchmark:
        "results/benchmarks/section5_suite_nocalib/all.tsv"
    shell:
        "imply suite build --suite-json {params.suite} --clips-json {params.clips} --scene-json {params.scene}"
        " --score-json {params.score} --table {input.table} --threads {threads} -o {params.out} > {log} 2>&1"


rule section5_evaluate:
    conda:
        IMPLY_ENV
    input:
        model="results/model/{variant}/seed{seed}/model.pt",
        encoder="results/encoder/encoder.pt",
        suite=section5_suite_files,
    output:
        results="results/section5/evaluate/{variant}_seed{seed}/results.json",
        report="results/section5/evaluate/{variant}_seed{seed}/report.md",
        per_object="results/section5/evaluate/{variant}_seed{seed}/per_object.csv",
    params:
        spec=lambda wildcards, input: (
            "imply.models.world_model:trained_predictor,"
            f"checkpoint={input.model},encoder={input.encoder},name={wildcards.variant}_seed{wildcards.seed},"
            f"batch_size={config['model']['rollout_batch']}"
        ),
        suite=lambda wildcards, input: Path(input.suite[0]).parent,
        report=lambda wildcards, output: Path(output.results).parent,
        conditions=lambda wildcards: EVALUATE_CONDITIONS[wildcards.variant],
        bootstrap=config["evaluate"]["bootstrap"],
        seed=config["evaluate"]["seed"],
    threads: config["model"]["resources"]["rollout_threads"]
    resources:
        mem_mb=config["model"]["resources"]["rollout_mem_mb"],
        runtime=config["model"]["resources"]["rollout_runtime"],
    log:
        "results/logs/section5_evaluate_{variant}_seed{seed}.log",
    benchmark:
        "results/benchmarks/section5_evaluate/{variant}-{seed}.tsv"
    shell:
        # --force: snakemake removed the old outputs; the folder may keep a report's figures
        "OMP_NUM_THREADS={threads} imply evaluate --model {params.spec} --suite {params.suite} -o {params.report}"
        " --conditions {params.conditions} --bootstrap {params.bootstrap} --seed {params.seed} --samples 1"
        " --force --no-progress > {log} 2>&1"


rule section5:
    conda:
        IMPLY_ENV
    input:
        evaluations=section5_evaluations(),
        suite_calib=section5_suites()["calib"],
        suite_nocalib=section5_suites()["nocalib"],
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
        evaluations=evaluation_options,
        score=score_subset("grid", "readout_floor"),
        selection_seed=config["model"]["selection_seed"],
    threads: 1
    resources:
        mem_mb=3000,
        runtime=10,
    log:
        "results/logs/section5.log",
    benchmark:
        "results/benchmarks/section5/all.tsv"
    shell:
        "imply study section5 {params.evaluations} --table {input.table} --train-clips {input.train_clips}"
        " --score-json {params.score}"
        " --selection-seed {params.selection_seed} --metrics {output.metrics} --per-object {output.per_object}"
        " > {log} 2>&1"
