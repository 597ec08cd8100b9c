# The sim-to-real gap diagnostic's benchmark: effect tables -> push logs from the converged
# world of imply.realworld (labels sealed in a file the diagnose rules never read; the
# world's own numerical error measured beside them) -> the diagnosis of every log (`imply
# gap diagnose-many`, sharded over the threads) -> scoring against the sealed labels (a
# result document). Beside it, the same diagnosis of logs from worlds with a contact model of their own
# (imply.realworld.contact, and the Bullet engine of imply.realworld.bullet), scored into the same
# document. The stage's part: paper.smk.


rule gap_tables:
    conda:
        IMPLY_ENV
    input:
        table="results/table/table.npz",
    output:
        directory("results/gap/effect_tables"),
    params:
        grid=as_json(config["gap"]["effect_grid"]),
        options=as_json(config["gap"]["diagnose"]),
        effects=gap_effects_option(),
        library=gap_library_levels(),
    threads: 1
    # every diagnosis reads the effect tables: they go right after the training chain's jobs
    priority: OTHER_START_PRIORITY
    resources:
        mem_mb=2000,
        runtime=15,
    log:
        "results/logs/gap_tables.log",
    benchmark:
        "results/benchmarks/gap_tables/all.tsv"
    shell:
        "imply study gap tables --table {input.table} --effect-grid-json {params.grid} --options-json {params.options}"
        " {params.effects} --threads {threads} -o {output} > {log} 2>&1"


rule gap_generate:
    conda:
        IMPLY_ENV
    input:
        table="results/table/table.npz",
    output:
        logs=expand("results/gap/logs/{case}.csv", case=GAP_CASES),
        tracks=expand("results/gap/logs/{case}.track.csv", case=GAP_CASES),
        sealed="results/gap/sealed/labels.json",
        accuracy="results/gap/world_accuracy.json",
    params:
        bench=gap_set_json("benchmark", "sealed"),
        folder=lambda wildcards, output: folder_of(output.logs),
    # one thread: a job asking for both cores waits for the training chain to leave both idle
    threads: 1
    resources:
        mem_mb=3000,
        runtime=20,
    log:
        "results/logs/gap_generate.log",
    benchmark:
        "results/benchmarks/gap_generate/all.tsv"
    shell:
        "imply study gap generate --table {input.table} --bench-json {params.bench} --logs {params.folder}"
        " --sealed {output.sealed} --accuracy {output.accuracy} --threads {threads} > {log} 2>&1"


rule gap_diagnose:
    conda:
        IMPLY_ENV
    input:
        logs=gap_shard_logs,
        tracks=gap_shard_tracks,
        table="results/table/table.npz",
        tables="results/gap/effect_tables",
    output:
        directory("results/gap/reports/shard{shard}"),
    params:
        grid=as_json(config["gap"]["effect_grid"]),
        options=as_json(config["gap"]["diagnose"]),
        effects=gap_effects_option(),
    threads: 1
    resources:
        mem_mb=1500,
        runtime=20,
    log:
        "results/logs/gap_diagnose_shard{shard}.log",
    benchmark:
        "results/benchmarks/gap_diagnose/{shard}.tsv"
    shell:
        "imply study gap diagnose-many {input.logs} --table {input.table} --effect-grid-json {params.grid} {params.effects}"
        " --options-json {params.options} --cache-dir {input.tables} --threads 1 --no-plots -o {output} > {log} 2>&1"


rule gap_contact_generate:
    conda:
        IMPLY_ENV
    input:
        table="results/table/table.npz",
    output:
        logs=expand("results/gap/contact/logs/{case}.csv", case=GAP_CONTACT_CASES),
        tracks=expand("results/gap/contact/logs/{case}.track.csv", case=GAP_CONTACT_CASES),
        sealed="results/gap/contact/sealed/labels.json",
        accuracy="results/gap/contact/world_accuracy.json",
    params:
        bench=gap_set_json("contact_benchmark", "sealed"),
        folder=lambda wildcards, output: folder_of(output.logs),
    # one thread: a job asking for both cores waits for the training chain to leave both idle
    threads: 1
    resources:
        mem_mb=3000,
        runtime=20,
    log:
        "results/logs/gap_contact_generate.log",
    benchmark:
        "results/benchmarks/gap_contact_generate/all.tsv"
    shell:
        "imply study gap generate --table {input.table} --contact-bench-json {params.bench} --logs {params.folder}"
        " --sealed {output.sealed} --accuracy {output.accuracy} --threads {threads} > {log} 2>&1"


rule gap_contact_diagnose:
    conda:
        IMPLY_ENV
    input:
        logs=gap_contact_shard_logs,
        tracks=gap_contact_shard_tracks,
        table="results/table/table.npz",
        tables="results/gap/effect_tables",
    output:
        directory("results/gap/contact/reports/shard{shard}"),
    params:
        grid=as_json(config["gap"]["effect_grid"]),
        options=as_json(config["gap"]["diagnose"]),
        effects=gap_effects_option(),
    threads: 1
    resources:
        mem_mb=1500,
        runtime=20,
    log:
        "results/logs/gap_contact_diagnose_shard{shard}.log",
    benchmark:
        "results/benchmarks/gap_contact_diagnose/{shard}.tsv"
    shell:
        "imply study gap diagnose-many {input.logs} --table {input.table} --effect-grid-json {params.grid} {params.effects}"
        " --options-json {params.options} --cache-dir {input.tables} --threads 1 --no-plots -o {output} > {log} 2>&1"


rule gap_contact_closed_loop:
    conda:
        IMPLY_ENV
    input:
        logs=gap_contact_shard_logs,
        reports="results/gap/contact/reports/shard{shard}",
        table="results/table/table.npz",
        tables="results/gap/effect_tables",
    output:
        directory("results/gap/contact/closed_loop/shard{shard}"),
    params:
        bench=gap_set_json("contact_benchmark", "sealed"),
        grid=as_json(config["gap"]["effect_grid"]),
        options=as_json(config["gap"]["diagnose"]),
        effects=gap_effects_option(),
        folder=lambda wildcards, input: folder_of(input.logs),
    threads: 1
    resources:
        mem_mb=1500,
        runtime=30,
    log:
        "results/logs/gap_contact_closed_loop_shard{shard}.log",
    benchmark:
        "results/benchmarks/gap_contact_closed_loop/{shard}.tsv"
    shell:
        "imply study gap closed-loop --contact-bench-json {params.bench} --logs {params.folder} --reports {input.reports}"
        " --table {input.table} --effect-grid-json {params.grid} {params.effects} --options-json {params.options}"
        " --cache-dir {input.tables} --threads 1 --no-plots -o {output} > {log} 2>&1"


rule gap_benchmark:
    conda:
        IMPLY_ENV
    input:
        reports=expand("results/gap/reports/shard{shard}", shard=GAP_SHARDS),
        sealed="results/gap/sealed/labels.json",
        accuracy="results/gap/world_accuracy.json",
        table="results/table/table.npz",
        contact_reports=expand("results/gap/contact/reports/shard{shard}", shard=GAP_SHARDS),
        contact_sealed="results/gap/contact/sealed/labels.json",
        closed_loop=expand("results/gap/contact/closed_loop/shard{shard}", shard=GAP_SHARDS),
    output:
        result=report(
            "results/gap/benchmark.json",
            caption="../report/gap_benchmark.rst",
            category="Gap diagnostic benchmark",
            subcategory="Benchmark",
        ),
        markdown=report(
            "results/gap/benchmark.md",
            caption="../report/gap_benchmark.rst",
            category="Gap diagnostic benchmark",
            subcategory="Benchmark",
        ),
    params:
        bench=gap_set_json("benchmark", "sealed"),
        contact=gap_set_json("contact_benchmark", "sealed"),
        # the development target scores its sets with the observables too (development.smk)
        observed="",
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/gap_benchmark.log",
    benchmark:
        "results/benchmarks/gap_benchmark/all.tsv"
    shell:
        "imply study gap benchmark --table {input.table} --bench-json {params.bench} --sealed {input.sealed}"
        " --accuracy {input.accuracy} --reports {input.reports} -o {output.result} --markdown {output.markdown}"
        " --contact-bench-json {params.contact} --contact-sealed {input.contact_sealed}"
        " --contact-reports {input.contact_reports} --closed-loop {input.closed_loop} {params.observed} > {log} 2>&1"


# The lab benchmark: pushes beside calibration probes on MuJoCo contact variants, Bullet and SAPIEN, in a
# development set and a sealed set (imply.realworld.lab); each effect log marked separable or not from its
# contact, per observable set, from its label (imply.realworld.separability).
rule gap_lab_generate:
    conda:
        IMPLY_ENV
    input:
        table="results/table/table.npz",
    output:
        logs=directory("results/gap/lab/{set}/logs"),
        references=directory("results/gap/lab/{set}/references"),
        labels="results/gap/lab/{set}/labels.json",
        timing="results/gap/lab/{set}/timing.json",
    params:
        lab=gap_lab_set_json,
    wildcard_constraints:
        set="development|sealed",
    # one thread: the worlds of other engines step one push at a time
    threads: 1
    # the head of the stage's longest chain (generation, two diagnoses, the closed loop, the score): it starts
    # beside the first training, not after the four
    priority: 15
    resources:
        mem_mb=3000,
        runtime=40,
    log:
        "results/logs/gap_lab_generate_{set}.log",
    benchmark:
        "results/benchmarks/gap_lab_generate/{set}.tsv"
    shell:
        "imply study gap lab-generate --lab-json {params.lab} --set {wildcards.set} --table {input.table}"
        " --logs {output.logs} --references {output.references} --labels {output.labels} --timing {output.timing}"
        " --threads {threads} > {log} 2>&1"


# The sealed set's marking (the development set's is part of the gap_development target: development.smk).
rule gap_lab_separability:
    conda:
        IMPLY_ENV
    input:
        labels="results/gap/lab/sealed/labels.json",
        timing="results/gap/lab/sealed/timing.json",
    output:
        result="results/gap/lab/separability.json",
        markdown=report(
            "results/gap/lab/separability.md",
            caption="../report/gap_benchmark.rst",
            category="Gap diagnostic benchmark",
            subcategory="Lab benchmark",
        ),
    params:
        lab=as_json(config["gap"]["lab_benchmark"]),
        set="sealed",
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/gap_lab_separability.log",
    benchmark:
        "results/benchmarks/gap_lab_separability/all.tsv"
    shell:
        "imply study gap separability --lab-json {params.lab} --labels {params.set}={input.labels}"
        " --timing {params.set}={input.timing} -o {output.result} --markdown {output.markdown} > {log} 2>&1"


# One lab set diagnosed with its calibration probes and without them (the logs without probes read alike either
# way), then scored against its labels. The development set is the one to choose on; the sealed set is scored once
# per design.
rule gap_lab_diagnose:
    conda:
        IMPLY_ENV
    input:
        logs="results/gap/lab/{set}/logs",
        table="results/table/table.npz",
        tables="results/gap/effect_tables",
    output:
        directory("results/gap/lab/{set}/reports_{variant}"),
    params:
        grid=as_json(config["gap"]["effect_grid"]),
        options=gap_lab_diagnose_options,
        effects=gap_effects_option(),
    wildcard_constraints:
        set="development|sealed",
        variant="probes|no_probes",
    threads: 1
    resources:
        mem_mb=1500,
        runtime=30,
    log:
        "results/logs/gap_lab_diagnose_{set}_{variant}.log",
    benchmark:
        "results/benchmarks/gap_lab_diagnose/{set}_{variant}.tsv"
    shell:
        "imply study gap diagnose-many {input.logs} --table {input.table} --effect-grid-json {params.grid} {params.effects}"
        " --options-json {params.options} --cache-dir {input.tables} --threads 1 --no-plots -o {output} > {log} 2>&1"


# The third tier: each log diagnosed against its reference session (the same world and boxes without the effect,
# one push of each, fresh noise; with probes where the log has them). This tier and its closed loop are the end of
# the stage's longest chain: sharded like the main set's diagnoses, so that the study's last minutes use both cores.
rule gap_lab_diagnose_reference:
    conda:
        IMPLY_ENV
    input:
        logs="results/gap/lab/{set}/logs",
        references="results/gap/lab/{set}/references",
        table="results/table/table.npz",
        tables="results/gap/effect_tables",
    output:
        directory("results/gap/lab/{set}/reports_reference/shard{shard}"),
    params:
        grid=as_json(config["gap"]["effect_grid"]),
        options=lambda wildcards: gap_lab_diagnose_options(wildcards, probes=True),
        effects=gap_effects_option(),
        shards=len(GAP_SHARDS),
    wildcard_constraints:
        set="development|sealed",
    threads: 1
    priority: 15
    resources:
        mem_mb=1500,
        runtime=20,
    log:
        "results/logs/gap_lab_diagnose_reference_{set}_shard{shard}.log",
    benchmark:
        "results/benchmarks/gap_lab_diagnose_reference/{set}_{shard}.tsv"
    shell:
        "imply study gap diagnose-many {input.logs} --shard {wildcards.shard} --shards {params.shards}"
        " --references {input.references} --table {input.table}"
        " --effect-grid-json {params.grid} {params.effects} --options-json {params.options} --cache-dir {input.tables}"
        " --threads 1 --no-plots -o {output} > {log} 2>&1"


# The closed loop on the reference tier, probes allowed: each log its diagnosis against the reference leaves with
# several contenders gets its recommended next pushes and probe, or as many random pushes of its own design, in its
# own world, and is diagnosed against its reference again.
rule gap_lab_closed_loop:
    conda:
        IMPLY_ENV
    input:
        logs="results/gap/lab/{set}/logs",
        references="results/gap/lab/{set}/references",
        reports="results/gap/lab/{set}/reports_reference/shard{shard}",
        table="results/table/table.npz",
        tables="results/gap/effect_tables",
    output:
        directory("results/gap/lab/{set}/closed_loop/shard{shard}"),
    params:
        lab=gap_lab_set_json,
        grid=as_json(config["gap"]["effect_grid"]),
        options=lambda wildcards: gap_lab_diagnose_options(wildcards, probes=True),
        effects=gap_effects_option(),
    wildcard_constraints:
        set="development|sealed",
    threads: 1
    priority: 15
    resources:
        mem_mb=2000,
        runtime=20,
    log:
        "results/logs/gap_lab_closed_loop_{set}_shard{shard}.log",
    benchmark:
        "results/benchmarks/gap_lab_closed_loop/{set}_{shard}.tsv"
    shell:
        "imply study gap closed-loop --lab-json {params.lab} --set {wildcards.set} --logs {input.logs}"
        " --reports {input.reports} --references {input.references} --table {input.table}"
        " --effect-grid-json {params.grid} {params.effects} --options-json {params.options} --cache-dir {input.tables}"
        " --threads 1 --no-plots -o {output} > {log} 2>&1"


rule gap_lab_score:
    conda:
        IMPLY_ENV
    input:
        labels="results/gap/lab/{set}/labels.json",
        probes="results/gap/lab/{set}/reports_probes",
        no_probes="results/gap/lab/{set}/reports_no_probes",
        reference=expand("results/gap/lab/{{set}}/reports_reference/shard{shard}", shard=GAP_SHARDS),
        closed_loop=expand("results/gap/lab/{{set}}/closed_loop/shard{shard}", shard=GAP_SHARDS),
        table="results/table/table.npz",
    output:
        result="results/gap/lab/{set}/score.json",
        markdown=report(
            "results/gap/lab/{set}/score.md",
            caption="../report/gap_benchmark.rst",
            category="Gap diagnostic benchmark",
            subcategory="Lab benchmark",
        ),
    params:
        lab=as_json(config["gap"]["lab_benchmark"]),
    wildcard_constraints:
        set="development|sealed",
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/gap_lab_score_{set}.log",
    benchmark:
        "results/benchmarks/gap_lab_score/{set}.tsv"
    shell:
        "imply study gap lab-score --lab-json {params.lab} --set {wildcards.set} --labels {input.labels}"
        " --reports-probes {input.probes} --reports-no-probes {input.no_probes} --reports-reference {input.reference}"
        " --closed-loop {input.closed_loop} --table {input.table}"
        " -o {output.result} --markdown {output.markdown} > {log} 2>&1"
