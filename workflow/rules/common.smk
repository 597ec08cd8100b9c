# Shared wiring: config validation and helpers that pass config subsets to the CLI.
import json
import shlex
from pathlib import Path

from snakemake.utils import min_version

from imply.config_check import validate_workflow_config

min_version("8.0")

# the whole config, every stage's section, before any job runs (one line on error)
validate_workflow_config(config, Path(workflow.current_basedir).parent / "schemas")


def as_json(obj):
    """A config subset as one shell-quoted JSON argument (rule params carry only this)."""
    return shlex.quote(json.dumps(obj, sort_keys=True))


# the software environment of every rule under `snakemake --use-conda` (pinned versions)
IMPLY_ENV = "../../envs/imply.yaml"

# final outputs of every stage; each rules file extends this list
FINAL_TARGETS = []

# result parts (results/paper/parts/<stage>.json) that the paper rule merges; each stage extends it
PAPER_PARTS = []
