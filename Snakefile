# IMPLY: the whole study as one DAG. `snakemake --cores 2` reproduces every number.
# Rules live in workflow/rules/; each calls the `imply` CLI with only its config subset.
# Each rules file appends its final outputs to FINAL_TARGETS (defined in common.smk).

configfile: "config.yaml"


include: "workflow/rules/common.smk"


rule all:
    input:
        lambda wildcards: FINAL_TARGETS,
    default_target: True


include: "workflow/rules/table.smk"
include: "workflow/rules/section4.smk"
include: "workflow/rules/gap.smk"
include: "workflow/rules/clips.smk"
include: "workflow/rules/model.smk"
include: "workflow/rules/section5.smk"
include: "workflow/rules/paper.smk"
