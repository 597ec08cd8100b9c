# Paper Section 5 model: the V-JEPA 2-AC action-conditioned predictor (imply.models) trained
# on the cached encoder features, per variant (context) and data-order seed, validated after
# every epoch on the validation split (every Table 3 quantity, read by the real-clip readout).
# Its held-out rollouts run through `imply evaluate` (section5.smk).


wildcard_constraints:
    variant="|".join(MODEL_VARIANTS),
    seed=r"\d+",


rule model_readout:
    conda:
        IMPLY_ENV
    input:
        features="results/features/train.npz",
        clips="results/clips/train.csv",
        calib=["results/features/heldout_calib.npz", "results/clips/heldout_calib.csv"],
        nocalib=["results/features/heldout_nocalib.npz", "results/clips/heldout_nocalib.csv"],
    output:
        readout="results/model/readout_ln.npz",
        report="results/model/readout_ln.json",
    params:
        token_grid=token_grid_option,
    threads: 1
    priority: TRAINING_CHAIN_PRIORITY
    resources:
        mem_mb=6000,
        runtime=20,
    log:
        "results/logs/model_readout.log",
    benchmark:
        "results/benchmarks/model_readout/all.tsv"
    shell:
        "imply study model readout --features {input.features} --clips {input.clips} --heldout {input.calib}"
        " --heldout {input.nocalib} {params.token_grid} -o {output.readout} --report {output.report} > {log} 2>&1"


rule model_train:
    conda:
        IMPLY_ENV
    input:
        features="results/features/train.npz",
        clips="results/clips/train.csv",
        readout="results/model/readout_ln.npz",
        validation=["results/features/validation.npz", "results/clips/validation.csv"],
        table="results/table/table.npz",
    output:
        model="results/model/{variant}/seed{seed}/model.pt",
        history="results/model/{variant}/seed{seed}/training.json",
    params:
        preset=preset_json,
        token_grid=token_grid_option,
        variant=variant_json,
        train=train_json,
        rest_state=config["model"]["rest_state"],
        device=config["model"]["device"],
        score=score_subset("grid", "readout_floor"),
        derangement_seed=config["model"]["derangement_seed"],
    threads: config["model"]["resources"]["train_threads"]
    priority: TRAINING_CHAIN_PRIORITY
    resources:
        mem_mb=config["model"]["resources"]["train_mem_mb"],
        runtime=config["model"]["resources"]["train_runtime"],
        gpu=config["model"]["resources"]["gpu"],
    log:
        "results/logs/model_train_{variant}_seed{seed}.log",
    benchmark:
        "results/benchmarks/model_train/{variant}-{seed}.tsv"
    shell:
        # a killed run leaves checkpoint.pt beside the model; rerunning resumes from it
        "imply study model train --features {input.features} --clips {input.clips} --readout {input.readout}"
        " --validation {input.validation} --table {input.table} --score-json {params.score}"
        " --derangement-seed {params.derangement_seed}"
        " --preset-json {params.preset} {params.token_grid} --variant-json {params.variant}"
        " --train-json {params.train} --rest-state {params.rest_state} --seed {wildcards.seed}"
        " --threads {threads} --device {params.device} -o {output.model} --history {output.history} > {log} 2>&1"


rule model_training_plot:
    conda:
        IMPLY_ENV
    input:
        training_histories(),
    output:
        report(
            "results/model/training.png",
            caption="../report/training.rst",
            category="Section 5, learned model",
            subcategory="Figures",
        ),
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    log:
        "results/logs/model_training_plot.log",
    benchmark:
        "results/benchmarks/model_training_plot/all.tsv"
    shell:
        "imply study model plot {input} -o {output} > {log} 2>&1"
