# Beyond the paper: a pixel-space, stochastic world model (imply.models.pixel_video), both variants
# trained on the training clips and run through `imply evaluate` on the study's suite as a frames
# model (read by the frame-difference readout fitted on real clips), evaluate.samples sample sets
# per object; scored into one result document (imply.study.pixel_model), Figure 3 and the part.


rule pixel_train:
    conda:
        IMPLY_ENV
    input:
        clips="results/clips/train.npz",
        meta="results/clips/train.csv",
    output:
        model="results/pixel/{variant}/model.pt",
        history="results/pixel/{variant}/training.json",
    params:
        recipe=as_json(config["pixel"]["recipe"]),
    wildcard_constraints:
        variant="calib|nocalib",
    # one thread: a job asking for both cores waits until both are idle at once (encoder_pretrain says why)
    threads: 1
    priority: OTHER_START_PRIORITY
    resources:
        mem_mb=6000,
        runtime=30,
    log:
        "results/logs/pixel_train_{variant}.log",
    benchmark:
        "results/benchmarks/pixel_train/{variant}.tsv"
    shell:
        "imply study pixel train --clips {input.clips} --recipe-json {params.recipe} --variant {wildcards.variant}"
        " --threads {threads} -o {output.model} --history {output.history} --no-progress > {log} 2>&1"


rule pixel_evaluate:
    conda:
        IMPLY_ENV
    input:
        model="results/pixel/{variant}/model.pt",
        suite=[f"results/suite/{f}" for f in SUITE_FILES],
    output:
        [f"results/pixel/evaluate/{{variant}}/{name}" for name in EVALUATE_REPORT_FILES],
    params:
        spec=lambda wildcards, input: (
            "imply.models.pixel_video:trained_pixel_video,"
            f"checkpoint={input.model},name=pixel_{wildcards.variant},batch_size={config['pixel']['rollout_batch']}"
        ),
        suite=lambda wildcards, input: Path(input.suite[0]).parent,
        report=lambda wildcards, output: Path(output[0]).parent,
        conditions=lambda wildcards: PIXEL_CONDITIONS[wildcards.variant],
        samples=config["evaluate"]["samples"],
        bootstrap=config["evaluate"]["bootstrap"],
        seed=config["evaluate"]["seed"],
    wildcard_constraints:
        variant="calib|nocalib",
    # one thread: its files are the same with more, and a job asking for both cores waits until both are idle
    threads: 1
    resources:
        mem_mb=6000,
        runtime=30,
    log:
        "results/logs/pixel_evaluate_{variant}.log",
    benchmark:
        "results/benchmarks/pixel_evaluate/{variant}.tsv"
    shell:
        # --force: snakemake removed the old outputs; the folder may keep a report's figures
        "OMP_NUM_THREADS={threads} imply evaluate --model {params.spec} --suite {params.suite} -o {params.report}"
        " --conditions {params.conditions} --samples {params.samples} --bootstrap {params.bootstrap}"
        " --seed {params.seed} --force --no-cache --no-progress > {log} 2>&1"


rule pixel_score:
    conda:
        IMPLY_ENV
    input:
        calib="results/pixel/evaluate/calib/results.json",
        nocalib="results/pixel/evaluate/nocalib/results.json",
        calib_history="results/pixel/calib/training.json",
        nocalib_history="results/pixel/nocalib/training.json",
    output:
        report(
            "results/pixel/metrics.json",
            caption="../report/pixel_metrics.rst",
            category="Beyond the paper, pixel-space model",
        ),
    params:
        calib=lambda wildcards, input: Path(input.calib).parent,
        nocalib=lambda wildcards, input: Path(input.nocalib).parent,
    resources:
        mem_mb=1000,
        runtime=2,
    log:
        "results/logs/pixel_score.log",
    benchmark:
        "results/benchmarks/pixel_score/all.tsv"
    shell:
        "imply study pixel score --calib {params.calib} --nocalib {params.nocalib} --calib-history {input.calib_history}"
        " --nocalib-history {input.nocalib_history} -o {output} > {log} 2>&1"


rule paper_figure3:
    conda:
        IMPLY_ENV
    input:
        metrics="results/pixel/metrics.json",
        calib_model="results/pixel/calib/model.pt",
        calib="results/pixel/evaluate/calib/per_object.csv",
        nocalib="results/pixel/evaluate/nocalib/per_object.csv",
        suite=[f"results/suite/{f}" for f in SUITE_FILES],
    output:
        pdf="results/paper/figures/figure3.pdf",
        png=report(
            "results/paper/figures/figure3.png",
            caption="../report/figure3.rst",
            category="Beyond the paper, pixel-space model",
        ),
    params:
        suite=lambda wildcards, input: Path(input.suite[0]).parent,
    resources:
        mem_mb=2000,
        runtime=5,
    log:
        "results/logs/paper_figure3.log",
    benchmark:
        "results/benchmarks/paper_figure3/all.tsv"
    shell:
        "imply study pixel figure --metrics {input.metrics} --calib-model {input.calib_model} --calib {input.calib}"
        " --nocalib {input.nocalib} --suite {params.suite} --pdf {output.pdf} --png {output.png} > {log} 2>&1"
