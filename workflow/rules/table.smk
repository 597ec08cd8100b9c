# The push table f(v, m, mu) -> log d (with its measured numerical error) and the scene's MJCF.


rule table:
    conda:
        IMPLY_ENV
    output:
        "results/table/table.npz",
    params:
        scene=as_json(config["scene"]),
        grid=as_json(config["table"]),
        check=as_json(config.get("table_check", {})),
    # first, on both cores while nothing else runs: the trainings and every gap job wait on the table, and it is the
    # only job asking for more than one thread (one asking for both waits until both are idle at once). Snakemake
    # starts the set of ready jobs with the largest sum of priorities, so the table's is above any two others'
    threads: config["threads"]
    priority: TABLE_PRIORITY
    resources:
        mem_mb=2000,
        runtime=15,
    log:
        "results/logs/table.log",
    benchmark:
        "results/benchmarks/table/all.tsv"
    shell:
        "imply table build --scene-json {params.scene} --grid-json {params.grid}"
        " --check-json {params.check} --threads {threads} -o {output} > {log} 2>&1"


rule scene_xml:
    conda:
        IMPLY_ENV
    output:
        "results/table/scene.xml",
    params:
        scene=as_json(config["scene"]),
    resources:
        mem_mb=500,
        runtime=1,
    log:
        "results/logs/scene_xml.log",
    benchmark:
        "results/benchmarks/scene_xml/all.tsv"
    shell:
        "imply sim export-xml --scene-json {params.scene} -o {output} > {log} 2>&1"
