# imply evaluate's frozen evaluation suite (imply.evaluate.suite): the study's held-out objects
# with their calibration clips and query context frames, real training clips for the readouts,
# a sealed truth file and a byte copy of the push table, so results/suite/ scores on its own.

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
        clips=suite_clips_json(),
        scene=as_json(config["scene"]),
        score=score_subset("calibration_speeds", "query_speeds"),
        out=lambda wildcards, output: Path(output.manifest).parent,
    # one thread: its files are the same with more, and a job asking for both cores waits until both are idle
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    log:
        "results/logs/suite_build.log",
    benchmark:
        "results/benchmarks/suite_build/all.tsv"
    shell:
        "imply suite build --suite-json {params.suite} --clips-json {params.clips} --scene-json {params.scene}"
        " --score-json {params.score} --table {input.table} --threads {threads} -o {params.out} > {log} 2>&1"


rule evaluate_standins:
    conda:
        IMPLY_ENV
    input:
        manifest="results/suite/manifest.json",
        suite="results/suite/suite.npz",
        truth="results/suite/truth.npz",
        table="results/suite/table.npz",
    output:
        summary="results/evaluate/standins.json",
        results="results/evaluate/standins/results.json",
        report="results/evaluate/standins/report.md",
        per_object="results/evaluate/standins/per_object.csv",
        slides=report(
            "results/evaluate/standins/slides.png",
            caption="../report/evaluate_slides.rst",
            category="imply evaluate, known answers",
        ),
        scores=report(
            "results/evaluate/standins/scores.png",
            caption="../report/evaluate_scores.rst",
            category="imply evaluate, known answers",
        ),
    params:
        suite=lambda wildcards, input: Path(input.manifest).parent,
        report=lambda wildcards, output: Path(output.results).parent,
        evaluate=as_json(config["evaluate"]),
        score=score_subset("grid", "readout_floor"),
    resources:
        mem_mb=4000,
        runtime=15,
    log:
        "results/logs/evaluate_standins.log",
    benchmark:
        "results/benchmarks/evaluate_standins/all.tsv"
    shell:
        "imply study section4 through-evaluate --suite {params.suite} --report {params.report} -o {output.summary}"
        " --evaluate-json {params.evaluate} --score-json {params.score} --no-progress > {log} 2>&1"
