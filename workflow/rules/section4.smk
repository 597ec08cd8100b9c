# The controlled validation (paper Section 4): objects -> true pushes -> stand-in rollouts
# -> scores -> Table 1 metrics, noise sweep, selection -> result part, tables, figure.
# Each rule passes only the config keys it reads, so editing e.g. section4.selection
# reruns only the selection, the part and what follows.

S4 = "results/section4"
S4_SPEEDS = {k: config["score"][k] for k in ("query_speeds", "calibration_speeds")}


rule s4_objects:
    conda:
        IMPLY_ENV
    input:
        table="results/table/table.npz",
    output:
        f"{S4}/objects.csv",
    params:
        s4=as_json({k: config["section4"][k] for k in ("seed", "objects")}),
        scene=as_json(config["scene"]),
    resources:
        mem_mb=500,
        runtime=2,
    log:
        "results/logs/s4_objects.log",
    shell:
        "imply section4 objects --table {input.table} --section4-json {params.s4} --scene-json {params.scene}"
        " -o {output} > {log} 2>&1"


rule s4_truth:
    conda:
        IMPLY_ENV
    input:
        objects=f"{S4}/objects.csv",
    output:
        f"{S4}/truth.csv",
    params:
        score=as_json(S4_SPEEDS),
        scene=as_json(config["scene"]),
    threads: config["threads"]
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/s4_truth.log",
    shell:
        "imply section4 truth --objects {input.objects} --score-json {params.score} --scene-json {params.scene}"
        " --threads {threads} -o {output} > {log} 2>&1"


rule s4_standins:
    conda:
        IMPLY_ENV
    input:
        objects=f"{S4}/objects.csv",
        truth=f"{S4}/truth.csv",
        table="results/table/table.npz",
    output:
        f"{S4}/rollouts.csv",
    params:
        s4=as_json({k: config["section4"][k] for k in ("seed", "standins")}),
        score=as_json({**S4_SPEEDS, "readout_floor": config["score"]["readout_floor"]}),
        scene=as_json(config["scene"]),
    threads: config["threads"]
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/s4_standins.log",
    shell:
        "imply section4 standins --objects {input.objects} --truth {input.truth} --table {input.table}"
        " --section4-json {params.s4} --score-json {params.score} --scene-json {params.scene}"
        " --threads {threads} -o {output} > {log} 2>&1"


rule s4_scores:
    conda:
        IMPLY_ENV
    input:
        objects=f"{S4}/objects.csv",
        truth=f"{S4}/truth.csv",
        rollouts=f"{S4}/rollouts.csv",
        table="results/table/table.npz",
    output:
        f"{S4}/scores.csv",
    params:
        score=as_json(config["score"]),
    resources:
        mem_mb=2000,
        runtime=5,
    log:
        "results/logs/s4_scores.log",
    shell:
        "imply section4 scores --objects {input.objects} --truth {input.truth} --rollouts {input.rollouts}"
        " --table {input.table} --score-json {params.score} -o {output} > {log} 2>&1"


rule s4_metrics:
    conda:
        IMPLY_ENV
    input:
        scores=f"{S4}/scores.csv",
        table="results/table/table.npz",
    output:
        f"{S4}/metrics.json",
    params:
        s4=as_json({"standins": {"jitter_sd": config["section4"]["standins"]["jitter_sd"]}}),
        score=as_json({"query_speeds": config["score"]["query_speeds"]}),
    resources:
        mem_mb=500,
        runtime=2,
    log:
        "results/logs/s4_metrics.log",
    shell:
        "imply section4 metrics --scores {input.scores} --table {input.table} --section4-json {params.s4}"
        " --score-json {params.score} -o {output} > {log} 2>&1"


rule s4_noise:
    conda:
        IMPLY_ENV
    input:
        truth=f"{S4}/truth.csv",
        rollouts=f"{S4}/rollouts.csv",
        table="results/table/table.npz",
    output:
        f"{S4}/noise.csv",
    params:
        s4=as_json({k: config["section4"][k] for k in ("seed", "noise")}),
        score=as_json(config["score"]),
    resources:
        mem_mb=2000,
        runtime=5,
    log:
        "results/logs/s4_noise.log",
    shell:
        "imply section4 noise --truth {input.truth} --rollouts {input.rollouts} --table {input.table}"
        " --section4-json {params.s4} --score-json {params.score} -o {output} > {log} 2>&1"


rule s4_selection:
    conda:
        IMPLY_ENV
    input:
        truth=f"{S4}/truth.csv",
        rollouts=f"{S4}/rollouts.csv",
        table="results/table/table.npz",
    output:
        summary=f"{S4}/selection.csv",
        choices=f"{S4}/selection_choices.csv",
    params:
        s4=as_json({k: config["section4"][k] for k in ("seed", "selection")}),
        score=as_json(config["score"]),
    resources:
        mem_mb=2000,
        runtime=5,
    log:
        "results/logs/s4_selection.log",
    shell:
        "imply section4 selection --truth {input.truth} --rollouts {input.rollouts} --table {input.table}"
        " --section4-json {params.s4} --score-json {params.score} -o {output.summary}"
        " --choices {output.choices} > {log} 2>&1"


rule s4_part:
    conda:
        IMPLY_ENV
    input:
        metrics=f"{S4}/metrics.json",
        noise=f"{S4}/noise.csv",
        selection=f"{S4}/selection.csv",
    output:
        "results/paper/parts/section4.json",
    params:
        s4=as_json({"selection": config["section4"]["selection"]}),
    resources:
        mem_mb=500,
        runtime=2,
    log:
        "results/logs/s4_part.log",
    shell:
        "imply section4 part --metrics {input.metrics} --noise {input.noise} --selection {input.selection}"
        " --section4-json {params.s4} -o {output} > {log} 2>&1"


rule s4_tables:
    conda:
        IMPLY_ENV
    input:
        part="results/paper/parts/section4.json",
    output:
        table1="results/paper/tables/table1.tex",
        table2="results/paper/tables/table2.tex",
    resources:
        mem_mb=500,
        runtime=1,
    log:
        "results/logs/s4_tables.log",
    shell:
        "imply section4 tables --part {input.part} --table1 {output.table1} --table2 {output.table2} > {log} 2>&1"


rule s4_figure:
    conda:
        IMPLY_ENV
    input:
        scores=f"{S4}/scores.csv",
        noise=f"{S4}/noise.csv",
    output:
        pdf="results/paper/figures/figure1.pdf",
        png="results/paper/figures/figure1.png",
    resources:
        mem_mb=1000,
        runtime=2,
    log:
        "results/logs/s4_figure.log",
    shell:
        "imply section4 figure --scores {input.scores} --noise {input.noise} --pdf {output.pdf}"
        " --png {output.png} > {log} 2>&1"


FINAL_TARGETS.extend(
    [
        "results/paper/tables/table1.tex",
        "results/paper/tables/table2.tex",
        "results/paper/figures/figure1.pdf",
        "results/paper/figures/figure1.png",
    ]
)
PAPER_PARTS.append("results/paper/parts/section4.json")
