# Paper Section 5 data: rendered push clips -> frozen encoder (CPU default pretrained here,
# or released V-JEPA 2 weights) -> cached features -> ridge and frame-difference readouts.
# Formats: imply.data.clips, imply.models.encoder, imply.readout (module docstrings).


# torch rules run with OMP_WAIT_POLICY=PASSIVE: on a shared machine, spinning OpenMP
# threads wait on each other and made the encoder several times slower (measured).
CLIP_SPLITS = ["train", "heldout_calib", "heldout_nocalib", "pretrain"]
FEATURE_SPLITS = ["train", "heldout_calib", "heldout_nocalib"]
CLIP_SPEEDS = {k: config["score"][k] for k in ("calibration_speeds", "query_speeds")}
ENCODER_ON_GPU = 1 if config["encoder"]["kind"] != "cpu" else 0


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
        score=as_json(CLIP_SPEEDS),
        scene=as_json(config["scene"]),
    threads: config["threads"]
    resources:
        mem_mb=4000,
        runtime=30,
    log:
        "results/logs/clips_render_{clip_split}.log",
    shell:
        "imply clips render --split {wildcards.clip_split} --clips-json {params.clips} --score-json {params.score}"
        " --scene-json {params.scene} --threads {threads} --out-npz {output.npz} --out-csv {output.csv}"
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
    threads: config["threads"]
    resources:
        mem_mb=4000,
        runtime=30,
    log:
        "results/logs/encoder_pretrain.log",
    shell:
        "OMP_WAIT_POLICY=PASSIVE imply encoder pretrain --clips {input} --encoder-json {params.encoder} --threads {threads}"
        " -o {output} > {log} 2>&1"


def _encoder_weights(wildcards):
    # the CPU default is built by the workflow; released weights are a local file given in config
    if config["encoder"]["kind"] == "cpu":
        return ["results/encoder/encoder.pt"]
    return []


rule encoder_encode:
    conda:
        IMPLY_ENV
    input:
        clips="results/clips/{feature_split}.npz",
        weights=_encoder_weights,
    output:
        "results/features/{feature_split}.npz",
    params:
        encoder=as_json(config["encoder"]),
        weights=lambda wc, input: f"--weights {input.weights}" if input.weights else "",
    threads: config["threads"]
    resources:
        mem_mb=8000,
        runtime=60,
        gpu=ENCODER_ON_GPU,
    log:
        "results/logs/encoder_encode_{feature_split}.log",
    shell:
        "OMP_WAIT_POLICY=PASSIVE imply encoder encode --clips {input.clips} --encoder-json {params.encoder} {params.weights}"
        " --threads {threads} -o {output} > {log} 2>&1"


rule readout_fit:
    conda:
        IMPLY_ENV
    input:
        clips=expand("results/clips/{s}.{ext}", s=FEATURE_SPLITS, ext=["npz", "csv"]),
        features=expand("results/features/{s}.npz", s=FEATURE_SPLITS),
    output:
        ridge="results/readout/ridge.npz",
        metrics="results/readout/metrics.json",
        part="results/paper/parts/clips.json",
    params:
        readout=as_json(config["readout"]),
        clips=as_json(config["clips"]),
    threads: 1
    resources:
        mem_mb=6000,
        runtime=20,
    log:
        "results/logs/readout_fit.log",
    shell:
        "imply readout fit --train results/clips/train --train-features results/features/train.npz"
        " --heldout results/clips/heldout_calib results/clips/heldout_nocalib"
        " --heldout-features results/features/heldout_calib.npz results/features/heldout_nocalib.npz"
        " --readout-json {params.readout} --clips-json {params.clips}"
        " -o {output.ridge} --metrics {output.metrics} --part {output.part} > {log} 2>&1"


FINAL_TARGETS.extend(
    [
        "results/readout/ridge.npz",
        "results/readout/metrics.json",
        *expand("results/features/{s}.npz", s=FEATURE_SPLITS),
    ]
)
PAPER_PARTS.append("results/paper/parts/clips.json")
