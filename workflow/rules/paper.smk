# The paper outputs: each stage's part (its registered numbers, read from its result
# documents, and its claims), Tables 1-3 and Figures 1-2, then every part merged into the
# macros, the numbers and the reproduction report. The optional config key paper.stages
# restricts the merge to some stages (common.smk's paper_parts).


rule paper_part:
    conda:
        IMPLY_ENV
    input:
        lambda wildcards: STAGE_RESULTS[wildcards.stage],
    output:
        "results/paper/parts/{stage}.json",
    resources:
        mem_mb=500,
        runtime=2,
    log:
        "results/logs/paper_part_{stage}.log",
    benchmark:
        "results/benchmarks/paper_part/{stage}.tsv"
    shell:
        "imply study paper part {wildcards.stage} {input} -o {output} > {log} 2>&1"


rule paper_tables_section4:
    conda:
        IMPLY_ENV
    input:
        part="results/paper/parts/section4.json",
    output:
        table1=report(
            "results/paper/tables/table1.tex",
            caption="../report/table1.rst",
            category="Section 4, controlled validation",
            subcategory="Tables",
        ),
        table2=report(
            "results/paper/tables/table2.tex",
            caption="../report/table2.rst",
            category="Section 4, controlled validation",
            subcategory="Tables",
        ),
    resources:
        mem_mb=500,
        runtime=1,
    log:
        "results/logs/paper_tables_section4.log",
    benchmark:
        "results/benchmarks/paper_tables_section4/all.tsv"
    shell:
        "imply study paper tables --part {input.part} --table1 {output.table1} --table2 {output.table2} > {log} 2>&1"


rule paper_table3:
    conda:
        IMPLY_ENV
    input:
        part="results/paper/parts/section5.json",
    output:
        report(
            "results/paper/tables/table3.tex",
            caption="../report/table3.rst",
            category="Section 5, learned model",
            subcategory="Tables",
        ),
    resources:
        mem_mb=500,
        runtime=1,
    log:
        "results/logs/paper_table3.log",
    benchmark:
        "results/benchmarks/paper_table3/all.tsv"
    shell:
        "imply study paper tables --part {input.part} --table3 {output} > {log} 2>&1"


rule paper_figure1:
    conda:
        IMPLY_ENV
    input:
        scores="results/section4/scores.csv",
        noise="results/section4/noise.json",
    output:
        pdf="results/paper/figures/figure1.pdf",
        png=report(
            "results/paper/figures/figure1.png",
            caption="../report/figure1.rst",
            category="Section 4, controlled validation",
            subcategory="Figures",
        ),
    resources:
        mem_mb=1000,
        runtime=2,
    log:
        "results/logs/paper_figure1.log",
    benchmark:
        "results/benchmarks/paper_figure1/all.tsv"
    shell:
        "imply study paper figure1 --scores {input.scores} --noise {input.noise} --pdf {output.pdf} --png {output.png}"
        " > {log} 2>&1"


rule paper_figure2:
    conda:
        IMPLY_ENV
    input:
        per_object="results/section5/per_object.csv",
    output:
        pdf="results/paper/figures/figure2.pdf",
        png=report(
            "results/paper/figures/figure2.png",
            caption="../report/figure2.rst",
            category="Section 5, learned model",
            subcategory="Figures",
        ),
    resources:
        mem_mb=1000,
        runtime=2,
    log:
        "results/logs/paper_figure2.log",
    benchmark:
        "results/benchmarks/paper_figure2/all.tsv"
    shell:
        "imply study paper figure2 --per-object {input.per_object} --pdf {output.pdf} --png {output.png} > {log} 2>&1"


rule paper_merge:
    conda:
        IMPLY_ENV
    input:
        paper_parts,
    params:
        # read, not an input: every job before this one wrote its benchmark file (the last run's timeline)
        benchmarks="results/benchmarks",
    output:
        macros=report(
            "results/paper/macros.tex",
            caption="../report/macros.rst",
            category="Paper numbers",
            subcategory="Merged numbers",
        ),
        numbers=report(
            "results/paper/numbers.json",
            caption="../report/numbers.rst",
            category="Paper numbers",
            subcategory="Merged numbers",
        ),
        report_md=report(
            "results/paper/reproduction.md",
            caption="../report/reproduction.rst",
            category="Paper numbers",
            subcategory="Reproduction report",
        ),
        report_csv=report(
            "results/paper/reproduction.csv",
            caption="../report/reproduction.rst",
            category="Paper numbers",
            subcategory="Reproduction report",
        ),
        report_html=report(
            "results/paper/reproduction.html",
            caption="../report/reproduction.rst",
            category="Paper numbers",
            subcategory="Reproduction report",
        ),
    resources:
        mem_mb=500,
        runtime=1,
    log:
        "results/logs/paper_merge.log",
    benchmark:
        "results/benchmarks/paper_merge/all.tsv"
    shell:
        "imply study paper merge {input} --macros {output.macros} --numbers {output.numbers}"
        " --report-md {output.report_md} --report-csv {output.report_csv} --report-html {output.report_html}"
        " --benchmarks {params.benchmarks} > {log} 2>&1"


# The documentation's snapshot of this run (`snakemake --cores 2 snapshot`, not part of the default target: it
# writes into docs/, which is committed): what the site shows before anything has run, stamped with the commit
# and the machine (imply.paper.snapshot).
rule snapshot:
    localrule: True
    conda:
        IMPLY_ENV
    input:
        final_outputs(),
    output:
        "docs/snapshot/snapshot.json",
    params:
        kernels=config.get("kernels", {}).get("pin", "numpy-avx2"),
        folder=lambda wildcards, output: folder_of(output),
    log:
        "results/logs/snapshot.log",
    shell:
        "imply study paper snapshot --root . --kernels {params.kernels} -o {params.folder} > {log} 2>&1"
