# Paper Section 5 data: rendered push clips -> frozen encoder (the CPU default pretrained
# here, or released V-JEPA 2 weights) -> cached features -> ridge and frame-difference
# readouts. Formats: imply.data.clips, imply.models.encoder, imply.readout.


# torch rules run with OMP_WAIT_POLICY=PASSIVE: on a shared machine, spinning OpenMP
# threads wait on each other and made the encoder several times slower (measured).
wildcard_constraints:
    clip_split="|".join(CLIP_SPLITS),
    feature_split="|".join(FEATURE_SPLITS),


rule clips_render:
    conda:
        IMPLY_ENV
    output:
        npz="results/clips/{clip_split}.npz",
        csv="results/clips/{clip_split}.csv",
    params:
        clips=as_json(config["clips"]),
        score=score_subset("calibration_speeds", "query_speeds"),
        scene=as_json(config["scene"]),
    # one thread: its files are the same with more, and a job asking for both cores waits until both are idle
    threads: 1
    priority: TRAINING_CHAIN_PRIORITY
    resources:
        mem_mb=4000,
        runtime=30,
    log:
        "results/logs/clips_render_{clip_split}.log",
    benchmark:
        "results/benchmarks/clips_render/{clip_split}.tsv"
    shell:
        "imply study clips render --split {wildcards.clip_split} --clips-json {params.clips} --score-json {params.score}"
        " --scene-json {params.scene} --threads {threads} -o {output.npz}"
        " > {log} 2>&1"


rule encoder_pretrain:
    conda:
        IMPLY_ENV
    input:
        "results/clips/pretrain.npz",
    output:
        "results/encoder/encoder.pt",
    params:
        encoder=as_json({k: config["encoder"][k] for k in ("cpu_arch", "pretrain")}),
    # one thread: on two cores a job asking for both waits until both are idle at once, which the lab's long
    # generation (one core for a quarter of the run) would delay past the trainings
    threads: 1
    priority: TRAINING_CHAIN_PRIORITY
    resources:
        mem_mb=4000,
        runtime=30,
    log:
        "results/logs/encoder_pretrain.log",
    benchmark:
        "results/benchmarks/encoder_pretrain/all.tsv"
    shell:
        "OMP_WAIT_POLICY=PASSIVE imply study encoder pretrain --clips {input} --encoder-json {params.encoder}"
        " --threads {threads} -o {output} > {log} 2>&1"


rule encoder_encode:
    conda:
        IMPLY_ENV
    input:
        clips="results/clips/{feature_split}.npz",
        weights=encoder_weights,
    output:
        "results/features/{feature_split}.npz",
    params:
        encoder=as_json(config["encoder"]),
        weights=encode_weights_option,
    threads: config["model"]["resources"]["encode_threads"]
    priority: TRAINING_CHAIN_PRIORITY
    resources:
        mem_mb=config["model"]["resources"]["encode_mem_mb"],
        runtime=config["model"]["resources"]["encode_runtime"],
        gpu=int(config["encoder"]["kind"] != "cpu"),
    log:
        "results/logs/encoder_encode_{feature_split}.log",
    benchmark:
        "results/benchmarks/encoder_encode/{feature_split}.tsv"
    shell:
        "OMP_WAIT_POLICY=PASSIVE imply study encoder encode --clips {input.clips} --encoder-json {params.encoder}"
        " {params.weights} --threads {threads} -o {output} > {log} 2>&1"


rule readout_fit:
    conda:
        IMPLY_ENV
    input:
        train=split_files("train"),
        heldout_calib=split_files("heldout_calib"),
        heldout_nocalib=split_files("heldout_nocalib"),
    output:
        ridge="results/readout/ridge.npz",
        metrics=report(
            "results/readout/metrics.json",
            caption="../report/readout_metrics.rst",
            category="Section 5, readout on clips",
            subcategory="Result documents",
        ),
    params:
        readout=as_json(config["readout"]),
        pretrain_episodes=config["clips"]["n_pretrain_episodes"],
    threads: 1
    priority: TRAINING_CHAIN_PRIORITY
    resources:
        mem_mb=6000,
        runtime=20,
    log:
        "results/logs/readout_fit.log",
    benchmark:
        "results/benchmarks/readout_fit/all.tsv"
    shell:
        "imply study readout fit --train {input.train} --heldout {input.heldout_calib} --heldout {input.heldout_nocalib}"
        " --readout-json {params.readout} --pretrain-episodes {params.pretrain_episodes}"
        " -o {output.ridge} --metrics {output.metrics} > {log} 2>&1"
