# IMPLY: the whole study as one DAG. `snakemake --cores 2` reproduces every number.
# Rules live in workflow/rules/ (one file per stage); every path they use comes from their
# input/output, and what the DAG builds in the end comes from getters in common.smk.

configfile: "config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"


rule all:
    input:
        final_outputs(),
    default_target: True


include: "workflow/rules/table.smk"
include: "workflow/rules/section4.smk"
include: "workflow/rules/clips.smk"
include: "workflow/rules/model.smk"
include: "workflow/rules/section5.smk"
include: "workflow/rules/evaluate.smk"
include: "workflow/rules/gap.smk"
include: "workflow/rules/development.smk"
include: "workflow/rules/pixel.smk"
include: "workflow/rules/paper.smk"
