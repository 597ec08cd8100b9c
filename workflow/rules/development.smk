# The gap benchmarks' development sets: the same designs as the sealed sets, drawn with their development seeds
# (config gap.*.development_seed), diagnosed and scored exactly as the sealed sets are, and with the design variant
# that reads every observable a log carries (the pusher's measured speed, the box's track). The diagnostic's
# settings are chosen on these, never on the sealed sets, so they are not part of the default run:
# `snakemake --cores 2 gap_development` builds them (results/gap/development/ and results/gap/lab/development/).

GAP_DEV = "results/gap/development"
gap_dev_shard_logs = shard_logs(f"{GAP_DEV}/logs", GAP_CASES)
gap_dev_shard_tracks = shard_tracks(f"{GAP_DEV}/logs", GAP_CASES)
gap_dev_contact_shard_logs = shard_logs(f"{GAP_DEV}/contact/logs", GAP_CONTACT_CASES)
gap_dev_contact_shard_tracks = shard_tracks(f"{GAP_DEV}/contact/logs", GAP_CONTACT_CASES)


rule gap_development:
    input:
        f"{GAP_DEV}/benchmark.json",
        f"{GAP_DEV}/benchmark.md",
        "results/gap/lab/development/separability.json",
        "results/gap/lab/development/score.json",
        "results/gap/lab/development/score.md",


use rule gap_generate as gap_dev_generate with:
    output:
        logs=expand(f"{GAP_DEV}/logs/{{case}}.csv", case=GAP_CASES),
        tracks=expand(f"{GAP_DEV}/logs/{{case}}.track.csv", case=GAP_CASES),
        sealed=f"{GAP_DEV}/labels.json",
        accuracy=f"{GAP_DEV}/world_accuracy.json",
    params:
        bench=gap_set_json("benchmark", "development"),
        folder=lambda wildcards, output: folder_of(output.logs),
    log:
        "results/logs/gap_dev_generate.log",
    benchmark:
        "results/benchmarks/gap_dev_generate/all.tsv"


use rule gap_contact_generate as gap_dev_contact_generate with:
    output:
        logs=expand(f"{GAP_DEV}/contact/logs/{{case}}.csv", case=GAP_CONTACT_CASES),
        tracks=expand(f"{GAP_DEV}/contact/logs/{{case}}.track.csv", case=GAP_CONTACT_CASES),
        sealed=f"{GAP_DEV}/contact/labels.json",
        accuracy=f"{GAP_DEV}/contact/world_accuracy.json",
    params:
        bench=gap_set_json("contact_benchmark", "development"),
        folder=lambda wildcards, output: folder_of(output.logs),
    log:
        "results/logs/gap_dev_contact_generate.log",
    benchmark:
        "results/benchmarks/gap_dev_contact_generate/all.tsv"


use rule gap_diagnose as gap_dev_diagnose with:
    input:
        logs=gap_dev_shard_logs,
        tracks=gap_dev_shard_tracks,
        table="results/table/table.npz",
        tables="results/gap/effect_tables",
    output:
        directory(f"{GAP_DEV}/reports/shard{{shard}}"),
    log:
        "results/logs/gap_dev_diagnose_shard{shard}.log",
    benchmark:
        "results/benchmarks/gap_dev_diagnose/{shard}.tsv"


use rule gap_diagnose as gap_dev_diagnose_observed with:
    input:
        logs=gap_dev_shard_logs,
        tracks=gap_dev_shard_tracks,
        table="results/table/table.npz",
        tables="results/gap/effect_tables",
    output:
        directory(f"{GAP_DEV}/reports_observed/shard{{shard}}"),
    params:
        grid=as_json(config["gap"]["effect_grid"]),
        options=as_json(GAP_OBSERVED_OPTIONS),
        effects=gap_effects_option(),
    log:
        "results/logs/gap_dev_diagnose_observed_shard{shard}.log",
    benchmark:
        "results/benchmarks/gap_dev_diagnose_observed/{shard}.tsv"


use rule gap_contact_diagnose as gap_dev_contact_diagnose with:
    input:
        logs=gap_dev_contact_shard_logs,
        tracks=gap_dev_contact_shard_tracks,
        table="results/table/table.npz",
        tables="results/gap/effect_tables",
    output:
        directory(f"{GAP_DEV}/contact/reports/shard{{shard}}"),
    log:
        "results/logs/gap_dev_contact_diagnose_shard{shard}.log",
    benchmark:
        "results/benchmarks/gap_dev_contact_diagnose/{shard}.tsv"


use rule gap_contact_diagnose as gap_dev_contact_diagnose_observed with:
    input:
        logs=gap_dev_contact_shard_logs,
        tracks=gap_dev_contact_shard_tracks,
        table="results/table/table.npz",
        tables="results/gap/effect_tables",
    output:
        directory(f"{GAP_DEV}/contact/reports_observed/shard{{shard}}"),
    params:
        grid=as_json(config["gap"]["effect_grid"]),
        options=as_json(GAP_OBSERVED_OPTIONS),
        effects=gap_effects_option(),
    log:
        "results/logs/gap_dev_contact_diagnose_observed_shard{shard}.log",
    benchmark:
        "results/benchmarks/gap_dev_contact_diagnose_observed/{shard}.tsv"


use rule gap_contact_closed_loop as gap_dev_contact_closed_loop with:
    input:
        logs=gap_dev_contact_shard_logs,
        reports=f"{GAP_DEV}/contact/reports/shard{{shard}}",
        table="results/table/table.npz",
        tables="results/gap/effect_tables",
    output:
        directory(f"{GAP_DEV}/contact/closed_loop/shard{{shard}}"),
    params:
        bench=gap_set_json("contact_benchmark", "development"),
        grid=as_json(config["gap"]["effect_grid"]),
        options=as_json(config["gap"]["diagnose"]),
        effects=gap_effects_option(),
        folder=lambda wildcards, input: folder_of(input.logs),
    log:
        "results/logs/gap_dev_contact_closed_loop_shard{shard}.log",
    benchmark:
        "results/benchmarks/gap_dev_contact_closed_loop/{shard}.tsv"


use rule gap_benchmark as gap_dev_benchmark with:
    input:
        reports=expand(f"{GAP_DEV}/reports/shard{{shard}}", shard=GAP_SHARDS),
        sealed=f"{GAP_DEV}/labels.json",
        accuracy=f"{GAP_DEV}/world_accuracy.json",
        table="results/table/table.npz",
        contact_reports=expand(f"{GAP_DEV}/contact/reports/shard{{shard}}", shard=GAP_SHARDS),
        contact_sealed=f"{GAP_DEV}/contact/labels.json",
        closed_loop=expand(f"{GAP_DEV}/contact/closed_loop/shard{{shard}}", shard=GAP_SHARDS),
        observed=expand(f"{GAP_DEV}/reports_observed/shard{{shard}}", shard=GAP_SHARDS),
        contact_observed=expand(f"{GAP_DEV}/contact/reports_observed/shard{{shard}}", shard=GAP_SHARDS),
    output:
        result=f"{GAP_DEV}/benchmark.json",
        markdown=f"{GAP_DEV}/benchmark.md",
    params:
        bench=gap_set_json("benchmark", "development"),
        contact=gap_set_json("contact_benchmark", "development"),
        observed=lambda wildcards, input: " ".join(
            ["--observed-reports", *input.observed, "--observed-contact-reports", *input.contact_observed]
        ),
    log:
        "results/logs/gap_dev_benchmark.log",
    benchmark:
        "results/benchmarks/gap_dev_benchmark/all.tsv"


use rule gap_lab_separability as gap_lab_separability_development with:
    input:
        labels="results/gap/lab/development/labels.json",
        timing="results/gap/lab/development/timing.json",
    output:
        result="results/gap/lab/development/separability.json",
        markdown="results/gap/lab/development/separability.md",
    params:
        lab=as_json(config["gap"]["lab_benchmark"]),
        set="development",
    log:
        "results/logs/gap_lab_separability_development.log",
    benchmark:
        "results/benchmarks/gap_lab_separability/development.tsv"
