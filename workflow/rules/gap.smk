# The sim-to-real gap diagnostic and its benchmark: effect tables -> push logs from the
# converged world of imply.realworld (labels sealed in a file the diagnose rules never
# read; the world's own numerical error measured beside them) -> the diagnosis of every
# log (`imply gap diagnose-many`, sharded over the threads) -> scoring against the sealed
# labels -> results/paper/parts/gap.json.

from imply.realworld.cases import BenchmarkDesign, case_ids

GAP = "results/gap"
GAP_CASES = case_ids(BenchmarkDesign.from_dict(config["gap"]["benchmark"]))
# --effects option for the candidate list (empty: the whole library)
GAP_EFFECTS = "--effects " + ",".join(config["gap"]["candidates"]) if config["gap"].get("candidates") else ""


rule gap_tables:
    conda:
        IMPLY_ENV
    input:
        table="results/table/table.npz",
    output:
        f"{GAP}/effect_tables.json",
    params:
        grid=as_json(config["gap"]["effect_grid"]),
        options=as_json(config["gap"]["diagnose"]),
        cache=f"{GAP}/cache",
        effects=GAP_EFFECTS,
    threads: config["threads"]
    resources:
        mem_mb=2000,
        runtime=15,
    log:
        "results/logs/gap_tables.log",
    shell:
        "imply gap tables --table {input.table} --effect-grid-json {params.grid} --options-json {params.options}"
        " --cache-dir {params.cache} {params.effects} --threads {threads} -o {output} > {log} 2>&1"


rule gap_generate:
    conda:
        IMPLY_ENV
    input:
        table="results/table/table.npz",
    output:
        logs=expand(f"{GAP}/logs/{{case}}.csv", case=GAP_CASES),
        sealed=f"{GAP}/sealed/labels.json",
        accuracy=f"{GAP}/world_accuracy.json",
    params:
        bench=as_json(config["gap"]["benchmark"]),
        logs=f"{GAP}/logs",
    threads: config["threads"]
    resources:
        mem_mb=3000,
        runtime=20,
    log:
        "results/logs/gap_generate.log",
    shell:
        "imply gap generate --table {input.table} --bench-json {params.bench} --logs {params.logs}"
        " --sealed {output.sealed} --accuracy {output.accuracy} --threads {threads} > {log} 2>&1"


# the benchmark's diagnoses run in one process per shard (imports and tables loaded once),
# each log exactly as `imply diagnose` would; the sealed labels are not an input
GAP_SHARDS = list(range(config["threads"]))


def gap_shard_logs(wildcards):
    k = int(wildcards.shard)
    return [f"{GAP}/logs/{c}.csv" for i, c in enumerate(GAP_CASES) if i % len(GAP_SHARDS) == k]


rule gap_diagnose:
    conda:
        IMPLY_ENV
    input:
        logs=gap_shard_logs,
        table="results/table/table.npz",
        tables=f"{GAP}/effect_tables.json",
    output:
        directory(f"{GAP}/reports/shard{{shard}}"),
    params:
        grid=as_json(config["gap"]["effect_grid"]),
        options=as_json(config["gap"]["diagnose"]),
        cache=f"{GAP}/cache",
        effects=GAP_EFFECTS,
    threads: 1
    resources:
        mem_mb=1500,
        runtime=20,
    log:
        "results/logs/gap_diagnose_shard{shard}.log",
    shell:
        "imply gap diagnose-many {input.logs} --table {input.table} --effect-grid-json {params.grid} {params.effects}"
        " --options-json {params.options} --cache-dir {params.cache} --threads 1 -o {output} > {log} 2>&1"


rule gap_benchmark:
    conda:
        IMPLY_ENV
    input:
        reports=expand(f"{GAP}/reports/shard{{shard}}", shard=GAP_SHARDS),
        sealed=f"{GAP}/sealed/labels.json",
        accuracy=f"{GAP}/world_accuracy.json",
        table="results/table/table.npz",
    output:
        result=f"{GAP}/benchmark.json",
        markdown=f"{GAP}/benchmark.md",
        part="results/paper/parts/gap.json",
    params:
        bench=as_json(config["gap"]["benchmark"]),
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/gap_benchmark.log",
    shell:
        "imply gap benchmark --table {input.table} --bench-json {params.bench} --sealed {input.sealed}"
        " --accuracy {input.accuracy} --reports {input.reports} -o {output.result} --markdown {output.markdown}"
        " --part {output.part} > {log} 2>&1"


FINAL_TARGETS.extend([f"{GAP}/benchmark.json", f"{GAP}/benchmark.md", "results/paper/parts/gap.json"])
PAPER_PARTS.append("results/paper/parts/gap.json")
