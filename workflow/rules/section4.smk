# The controlled validation (paper Section 4): objects -> true pushes -> stand-in rollouts
# -> scores -> Table 1 metrics, noise sweep, selection (result documents). Each rule passes
# only the config keys it reads, so editing e.g. section4.selection reruns only the
# selection and what follows it. The stage's part, tables and figure: paper.smk.


rule s4_objects:
    conda:
        IMPLY_ENV
    input:
        table="results/table/table.npz",
    output:
        "results/section4/objects.csv",
    params:
        seed=config["section4"]["seed"],
        objects=as_json(config["section4"]["objects"]),
        scene=as_json(config["scene"]),
    resources:
        mem_mb=500,
        runtime=2,
    log:
        "results/logs/s4_objects.log",
    benchmark:
        "results/benchmarks/s4_objects/all.tsv"
    shell:
        "imply study section4 objects --table {input.table} --seed {params.seed} --objects-json {params.objects}"
        " --scene-json {params.scene} -o {output} > {log} 2>&1"


rule s4_truth:
    conda:
        IMPLY_ENV
    input:
        objects="results/section4/objects.csv",
    output:
        "results/section4/truth.csv",
    params:
        score=score_subset("query_speeds", "calibration_speeds"),
        scene=as_json(config["scene"]),
    # one thread: its files are the same with more, and a job asking for both cores waits until both are idle
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/s4_truth.log",
    benchmark:
        "results/benchmarks/s4_truth/all.tsv"
    shell:
        "imply study section4 truth --objects {input.objects} --score-json {params.score} --scene-json {params.scene}"
        " --threads {threads} -o {output} > {log} 2>&1"


rule s4_standins:
    conda:
        IMPLY_ENV
    input:
        objects="results/section4/objects.csv",
        truth="results/section4/truth.csv",
        table="results/table/table.npz",
    output:
        "results/section4/rollouts.csv",
    params:
        seed=config["section4"]["seed"],
        standins=as_json(config["section4"]["standins"]),
        score=score_subset("query_speeds", "calibration_speeds", "readout_floor"),
        scene=as_json(config["scene"]),
    # one thread: its files are the same with more, and a job asking for both cores waits until both are idle
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/s4_standins.log",
    benchmark:
        "results/benchmarks/s4_standins/all.tsv"
    shell:
        "imply study section4 standins --objects {input.objects} --truth {input.truth} --table {input.table}"
        " --seed {params.seed} --standins-json {params.standins} --score-json {params.score}"
        " --scene-json {params.scene} --threads {threads} -o {output} > {log} 2>&1"


rule s4_scores:
    conda:
        IMPLY_ENV
    input:
        objects="results/section4/objects.csv",
        truth="results/section4/truth.csv",
        rollouts="results/section4/rollouts.csv",
        table="results/table/table.npz",
    output:
        "results/section4/scores.csv",
    params:
        score=as_json(config["score"]),
    resources:
        mem_mb=2000,
        runtime=5,
    log:
        "results/logs/s4_scores.log",
    benchmark:
        "results/benchmarks/s4_scores/all.tsv"
    shell:
        "imply study section4 scores --objects {input.objects} --truth {input.truth} --rollouts {input.rollouts}"
        " --table {input.table} --score-json {params.score} -o {output} > {log} 2>&1"


rule s4_metrics:
    conda:
        IMPLY_ENV
    input:
        scores="results/section4/scores.csv",
        table="results/table/table.npz",
    output:
        report(
            "results/section4/metrics.json",
            caption="../report/section4_metrics.rst",
            category="Section 4, controlled validation",
            subcategory="Result documents",
        ),
    params:
        standins=as_json({"jitter_sd": config["section4"]["standins"]["jitter_sd"]}),
        score=score_subset("query_speeds"),
    resources:
        mem_mb=500,
        runtime=2,
    log:
        "results/logs/s4_metrics.log",
    benchmark:
        "results/benchmarks/s4_metrics/all.tsv"
    shell:
        "imply study section4 metrics --scores {input.scores} --table {input.table} --standins-json {params.standins}"
        " --score-json {params.score} -o {output} > {log} 2>&1"


rule s4_noise:
    conda:
        IMPLY_ENV
    input:
        truth="results/section4/truth.csv",
        rollouts="results/section4/rollouts.csv",
        table="results/table/table.npz",
    output:
        report(
            "results/section4/noise.json",
            caption="../report/section4_noise.rst",
            category="Section 4, controlled validation",
            subcategory="Result documents",
        ),
    params:
        seed=config["section4"]["seed"],
        noise=as_json(config["section4"]["noise"]),
        score=as_json(config["score"]),
    resources:
        mem_mb=2000,
        runtime=5,
    log:
        "results/logs/s4_noise.log",
    benchmark:
        "results/benchmarks/s4_noise/all.tsv"
    shell:
        "imply study section4 noise --truth {input.truth} --rollouts {input.rollouts} --table {input.table}"
        " --seed {params.seed} --noise-json {params.noise} --score-json {params.score} -o {output} > {log} 2>&1"


rule s4_selection:
    conda:
        IMPLY_ENV
    input:
        truth="results/section4/truth.csv",
        rollouts="results/section4/rollouts.csv",
        table="results/table/table.npz",
    output:
        summary=report(
            "results/section4/selection.json",
            caption="../report/section4_selection.rst",
            category="Section 4, controlled validation",
            subcategory="Result documents",
        ),
        choices="results/section4/selection_choices.csv",
    params:
        seed=config["section4"]["seed"],
        selection=as_json(config["section4"]["selection"]),
        score=as_json(config["score"]),
    resources:
        mem_mb=2000,
        runtime=5,
    log:
        "results/logs/s4_selection.log",
    benchmark:
        "results/benchmarks/s4_selection/all.tsv"
    shell:
        "imply study section4 selection --truth {input.truth} --rollouts {input.rollouts} --table {input.table}"
        " --seed {params.seed} --selection-json {params.selection} --score-json {params.score}"
        " -o {output.summary} --choices {output.choices} > {log} 2>&1"
