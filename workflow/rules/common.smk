# Shared wiring: config validation and helpers that pass config subsets to the CLI.
import json
import shlex

from snakemake.utils import min_version, validate

min_version("8.0")

validate(config, schema="../schemas/config.schema.yaml")


def as_json(obj):
    """A config subset as one shell-quoted JSON argument (rule params carry only this)."""
    return shlex.quote(json.dumps(obj, sort_keys=True))


# the software environment of every rule under `snakemake --use-conda` (pinned versions)
IMPLY_ENV = "../../envs/imply.yaml"

# final outputs of every stage; each rules file extends this list
FINAL_TARGETS = []

# result parts (results/paper/parts/<stage>.json) that the paper rule merges; each stage extends it
PAPER_PARTS = []
