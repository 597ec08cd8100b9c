# Paper Section 5 model: the V-JEPA 2-AC action-conditioned predictor (imply.models) trained
# on the cached encoder features, per variant (context) and data-order seed, then rolled out
# on the held-out objects and read out to displacement.


MODEL = config["model"]
MODEL_VARIANTS = ["nocalib", "calib"]
MODEL_SEEDS = [int(s) for s in MODEL["seeds"]]
MODEL_RES = MODEL["resources"]
# which held-out split and contexts each variant is rolled out on
ROLLOUT_SPLIT = {"calib": "heldout_calib", "nocalib": "heldout_nocalib"}
ROLLOUT_CONTEXTS = {"calib": "own,swap,none", "nocalib": "none"}


wildcard_constraints:
    variant="|".join(MODEL_VARIANTS),
    seed=r"\d+",


def _train_subset(variant):
    """Only what defines a training run, so other model keys do not retrain it."""
    return {
        "preset": MODEL["preset"],
        "presets": {MODEL["preset"]: MODEL["presets"][MODEL["preset"]]},
        "variants": {variant: MODEL["variants"][variant]},
        "train": MODEL["train"],
        "rest_state": MODEL["rest_state"],
    }


rule model_readout:
    conda:
        IMPLY_ENV
    input:
        features="results/features/train.npz",
        clips="results/clips/train.csv",
        heldout=expand("results/{kind}/{s}.{ext}", zip, kind=["features", "clips"] * 2,
                       s=["heldout_calib", "heldout_calib", "heldout_nocalib", "heldout_nocalib"],
                       ext=["npz", "csv"] * 2),
    output:
        ridge="results/model/readout_ln.npz",
        report="results/model/readout_ln.json",
    threads: 1
    resources:
        mem_mb=6000,
        runtime=20,
    log:
        "results/logs/model_readout.log",
    shell:
        "imply model readout --features {input.features} --clips {input.clips}"
        " --heldout results/features/heldout_calib.npz results/clips/heldout_calib.csv"
        " --heldout results/features/heldout_nocalib.npz results/clips/heldout_nocalib.csv"
        " -o {output.ridge} > {log} 2>&1"


rule model_train:
    conda:
        IMPLY_ENV
    input:
        features="results/features/train.npz",
        clips="results/clips/train.csv",
    output:
        "results/model/{variant}/seed{seed}/model.pt",
    params:
        model=lambda wc: as_json(_train_subset(wc.variant)),
        device=MODEL["device"],
    threads: config["threads"]
    resources:
        mem_mb=MODEL_RES["train_mem_mb"],
        runtime=MODEL_RES["train_runtime"],
        gpu=MODEL_RES["gpu"],
    log:
        "results/logs/model_train_{variant}_seed{seed}.log",
    shell:
        # a killed run leaves results/model/{variant}/seed{seed}/checkpoint.pt; rerunning resumes from it
        "imply model train --features {input.features} --clips {input.clips} --model-json {params.model}"
        " --variant {wildcards.variant} --seed {wildcards.seed} --threads {threads} --device {params.device}"
        " -o {output} > {log} 2>&1"


rule model_rollout:
    conda:
        IMPLY_ENV
    input:
        model="results/model/{variant}/seed{seed}/model.pt",
        features=lambda wc: f"results/features/{ROLLOUT_SPLIT[wc.variant]}.npz",
        clips=lambda wc: f"results/clips/{ROLLOUT_SPLIT[wc.variant]}.csv",
        readout="results/model/readout_ln.npz",
    output:
        "results/model/{variant}/seed{seed}/rollouts.csv",
    params:
        contexts=lambda wc: ROLLOUT_CONTEXTS[wc.variant],
        derangement_seed=MODEL["derangement_seed"],
        batch=MODEL["rollout_batch"],
    threads: config["threads"]
    resources:
        mem_mb=MODEL_RES["rollout_mem_mb"],
        runtime=MODEL_RES["rollout_runtime"],
        gpu=MODEL_RES["gpu"],
    log:
        "results/logs/model_rollout_{variant}_seed{seed}.log",
    shell:
        "imply model rollout --model {input.model} --features {input.features} --clips {input.clips}"
        " --readout {input.readout} --contexts {params.contexts} --derangement-seed {params.derangement_seed}"
        " --batch-size {params.batch} --threads {threads} -o {output} > {log} 2>&1"


FINAL_TARGETS.extend(
    expand("results/model/{variant}/seed{seed}/rollouts.csv", variant=MODEL_VARIANTS, seed=MODEL_SEEDS)
)
