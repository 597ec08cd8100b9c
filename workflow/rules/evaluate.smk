# imply evaluate's frozen evaluation suite (imply.evaluate.suite): the study's held-out objects
# with their calibration clips and query context frames, real training clips for the readouts,
# a sealed truth file and a byte copy of the push table, so results/suite/ scores on its own.

# the clips keys the suite reads: the objects' draws, the frame times, the camera, the batch
SUITE_CLIPS_KEYS = [
    "seed",
    "masses",
    "frictions",
    "size_scale",
    "train_speed",
    "n_train_episodes",
    "n_heldout_calib",
    "n_heldout_nocalib",
    "frame_times",
    "camera",
    "batch",
]


rule suite_build:
    conda:
        IMPLY_ENV
    input:
        table="results/table/table.npz",
    output:
        manifest="results/suite/manifest.json",
        suite="results/suite/suite.npz",
        truth="results/suite/truth.npz",
        table="results/suite/table.npz",
        readme="results/suite/README.md",
    params:
        suite=as_json(config["suite"]),
        clips=as_json({k: config["clips"][k] for k in SUITE_CLIPS_KEYS}),
        scene=as_json(config["scene"]),
        score=score_subset("calibration_speeds", "query_speeds"),
        out=lambda wildcards, output: Path(output.manifest).parent,
    threads: config["threads"]
    resources:
        mem_mb=4000,
        runtime=30,
    log:
        "results/logs/suite_build.log",
    shell:
        "imply suite build --suite-json {params.suite} --clips-json {params.clips} --scene-json {params.scene}"
        " --score-json {params.score} --table {input.table} --threads {threads} -o {params.out} > {log} 2>&1"
