# Shared wiring: the config check, and the getters that tell the rules their inputs,
# parameters and the DAG's final outputs (rules files hold rules only).
import json
import os
import shlex
from pathlib import Path

from snakemake.utils import min_version

from imply.config_check import PAPER_STAGES, validate_workflow_config
from imply.kernels import environment as kernel_environment
from imply.models.weights import encoder_weight_files
from imply.realworld.cases import BenchmarkConfig, ContactBenchmarkConfig, case_ids
from imply.realworld.lab import LabBenchmarkConfig
from imply.sim.effects import EFFECTS, MODEL

min_version("8.0")

# the whole config, every stage's section and released encoder weights, before any job runs (one line on error)
validate_workflow_config(config, Path(workflow.current_basedir).parent / "schemas")

# the software environment of every rule under `snakemake --use-conda` (pinned versions)
IMPLY_ENV = "../../envs/imply.yaml"
# Job priorities on two cores. Snakemake starts the set of ready jobs with the largest sum of priorities, so the table
# (TABLE_PRIORITY, both cores) outweighs any two one-thread jobs; the training chain, the study's longest, goes before
# the other jobs that wait on nothing (the gap stage's effect tables and the pixel model, OTHER_START_PRIORITY), and
# the rest fills the other core.
TABLE_PRIORITY = 50
TRAINING_CHAIN_PRIORITY = 12
OTHER_START_PRIORITY = 10

# every job computes with the same numerical kernels on any x86-64 machine (imply.kernels):
# jobs inherit this process's environment, here and on a cluster (each job reads the Snakefile)
os.environ.update(kernel_environment(config.get("kernels", {}).get("pin", "numpy-avx2")))

CLIP_SPLITS = ["train", "heldout_calib", "heldout_nocalib", "pretrain", "validation"]
FEATURE_SPLITS = ["train", "heldout_calib", "heldout_nocalib", "validation"]
HELDOUT_SPLITS = ["heldout_calib", "heldout_nocalib"]
MODEL_VARIANTS = ["nocalib", "calib"]
MODEL_SEEDS = [int(s) for s in config["model"]["seeds"]]
# the suite each variant is evaluated on (the main suite holds heldout_calib's objects), and the
# conditions it is asked (a model trained without calibration is asked with none only)
SECTION5_SUITE = {"calib": "results/suite", "nocalib": "results/section5/suite_nocalib"}
EVALUATE_CONDITIONS = {"calib": "own,other,none", "nocalib": "none"}
# the pixel-space world model's variants and the conditions each is asked (beyond the paper)
PIXEL_VARIANTS = ["calib", "nocalib"]
PIXEL_CONDITIONS = {"calib": "own,other", "nocalib": "none"}
SUITE_FILES = ["manifest.json", "suite.npz", "truth.npz", "table.npz", "README.md"]
GAP_CASES = case_ids(BenchmarkConfig.from_dict(config["gap"]["benchmark"]))
GAP_CONTACT_CASES = case_ids(ContactBenchmarkConfig.from_dict(config["gap"]["contact_benchmark"]))
# the benchmark's diagnoses run in one process per shard (imports and tables loaded once); two shards
# per core keep each job to a minute or two, so the last ones do not hold one core while the other idles
GAP_SHARDS = list(range(2 * config["threads"]))
# each stage's result documents, from which its part reads the registered numbers
STAGE_RESULTS = {
    "section4": ["results/section4/metrics.json", "results/section4/noise.json", "results/section4/selection.json"],
    "clips": ["results/readout/metrics.json"],
    "section5": ["results/section5/metrics.json"],
    "gap": ["results/gap/benchmark.json", "results/gap/lab/sealed/score.json"],
    "evaluate": ["results/evaluate/standins.json"],
    "pixel": ["results/pixel/metrics.json"],
}


def as_json(obj):
    """A config subset as one shell-quoted JSON argument (rule params carry only this)."""
    return shlex.quote(json.dumps(obj, sort_keys=True))


def score_subset(*keys):
    """Only the ``score`` keys a rule reads."""
    return as_json({k: config["score"][k] for k in keys})


# -- clips and encoder --------------------------------------------------------------


def encoder_weights(wildcards):
    """The CPU default encoder is built by the workflow; released weights are local files given in config
    (inputs all the same, so replacing them reruns the features)."""
    if config["encoder"]["kind"] == "cpu":
        return ["results/encoder/encoder.pt"]
    return encoder_weight_files(config["encoder"])


def encode_weights_option(wildcards, input):
    """The CPU default's weights file; released weights are read from encoder.weights in the encoder JSON."""
    return f"--weights {input.weights}" if config["encoder"]["kind"] == "cpu" else ""


def split_files(split):
    """A clip split's frames, metadata and encoder features, in the order `imply study readout fit` takes them."""
    return [f"results/clips/{split}.npz", f"results/clips/{split}.csv", f"results/features/{split}.npz"]


# -- the predictor ------------------------------------------------------------------


def preset_json(wildcards):
    model = config["model"]
    return as_json(model["presets"][model["preset"]])


def variant_json(wildcards):
    return as_json(config["model"]["variants"][wildcards.variant])


def train_json(wildcards):
    """config model.train as this variant trains it (TrainConfig.for_layout): a change of context_free_epochs
    reruns the context-free trainings only."""
    from imply.models.config import Layout, TrainConfig

    model = config["model"]
    layout = Layout.from_dict({**model["variants"][wildcards.variant], "rest_state": model["rest_state"]})
    return as_json(TrainConfig.from_dict(model["train"]).for_layout(layout).to_dict())


def token_grid_option(wildcards=None):
    """--token-grid ROWS COLS for the predictor's pooled tokens (empty: the encoder's own grid)."""
    grid = config["model"].get("token_grid")
    return f"--token-grid {grid[0]} {grid[1]}" if grid else ""


def training_histories():
    return expand("results/model/{variant}/seed{seed}/training.json", variant=MODEL_VARIANTS, seed=MODEL_SEEDS)


# the clips keys the suite reads: the objects' draws, the frame times, the camera, the batch
SUITE_CLIPS_KEYS = [
    "seed",
    "masses",
    "frictions",
    "size_scale",
    "train_speed",
    "n_train_episodes",
    "n_heldout_calib",
    "n_heldout_nocalib",
    "frame_times",
    "camera",
    "batch",
]


def suite_clips_json():
    """Only the clips keys a suite reads."""
    return as_json({k: config["clips"][k] for k in SUITE_CLIPS_KEYS})


def section5_suite_files(wildcards):
    """The suite a variant's model is evaluated on."""
    return [f"{SECTION5_SUITE[wildcards.variant]}/{f}" for f in SUITE_FILES]


def section5_evaluations():
    """Each trained model's imply evaluate report (its readings; the folder is the report)."""
    return expand(
        "results/section5/evaluate/{variant}_seed{seed}/per_object.csv", variant=MODEL_VARIANTS, seed=MODEL_SEEDS
    )


def section5_suites():
    return {variant: f"{folder}/manifest.json" for variant, folder in SECTION5_SUITE.items()}


def evaluation_options(wildcards, input):
    """`imply study section5 --evaluation MODEL:SEED:FOLDER ... --suite MODEL:FOLDER` from the rule's input."""
    pairs = [(v, s) for v in MODEL_VARIANTS for s in MODEL_SEEDS]
    evaluations = [
        f"--evaluation {v}:{s}:{Path(path).parent}" for (v, s), path in zip(pairs, input.evaluations, strict=True)
    ]
    suite_manifests = {"calib": input.suite_calib, "nocalib": input.suite_nocalib}
    suites = [f"--suite {v}:{Path(suite_manifests[v]).parent}" for v in MODEL_VARIANTS]
    return " ".join([*evaluations, *suites])


# -- the gap benchmark ----------------------------------------------------------------


def gap_library_levels():
    """The tabulated library effects and their levels (imply.sim.effects), so that a change of the library rebuilds
    the effect tables."""
    return as_json({e.name: list(e.levels) for e in EFFECTS.values() if e.kind == MODEL})


def gap_effects_option():
    """--effects for the candidate list (empty: the whole library)."""
    candidates = config["gap"].get("candidates")
    return "--effects " + ",".join(candidates) if candidates else ""


def gap_lab_diagnose_options(wildcards, probes=None):
    """The diagnosis options (config gap.diagnose), with the logs' probes used or not as the variant (or ``probes``)
    says."""
    with_probes = wildcards.variant == "probes" if probes is None else probes
    return as_json({**config["gap"]["diagnose"], "use_probes": with_probes})


def gap_lab_set_json(wildcards):
    """The lab benchmark's config as one set's rule needs it (the other set's seed and logs left out)."""
    return as_json(LabBenchmarkConfig.set_subset(config["gap"]["lab_benchmark"], wildcards.set))


def gap_set_json(section, set_name):
    """Config ``gap.<section>`` (the main or the contact benchmark) as one set's rules need it: the sealed set's
    seed, or the development set's in its place; the other set's seed left out, so that choosing on a new
    development set does not remake the sealed one."""
    bench = {k: v for k, v in config["gap"][section].items() if k != "development_seed"}
    if set_name == "development":
        bench["seed"] = config["gap"][section]["development_seed"]
    return as_json(bench)


def shard_logs(folder, cases):
    """A getter of the logs of shard ``{shard}`` of ``cases`` in ``folder`` (every len(GAP_SHARDS)-th case)."""

    def logs(wildcards):
        k = int(wildcards.shard)
        return [f"{folder}/{c}.csv" for i, c in enumerate(cases) if i % len(GAP_SHARDS) == k]

    return logs


def shard_tracks(folder, cases):
    """A getter of the tracks of shard ``{shard}``'s logs (beside them, where `imply study gap diagnose-many` finds them)."""
    logs = shard_logs(folder, cases)
    return lambda wildcards: [log.removesuffix(".csv") + ".track.csv" for log in logs(wildcards)]


gap_shard_logs = shard_logs("results/gap/logs", GAP_CASES)
gap_shard_tracks = shard_tracks("results/gap/logs", GAP_CASES)
gap_contact_shard_logs = shard_logs("results/gap/contact/logs", GAP_CONTACT_CASES)
gap_contact_shard_tracks = shard_tracks("results/gap/contact/logs", GAP_CONTACT_CASES)


# the design variant of the development target: the diagnosis with every observable a log carries
GAP_OBSERVED_OPTIONS = {**config["gap"]["diagnose"], "use_pusher_speed": True, "use_track": True}


def folder_of(files):
    """The folder holding a list of files (how a rule names a folder of its declared outputs)."""
    return str(Path(files[0]).parent)


# -- the paper ------------------------------------------------------------------------


def paper_parts(wildcards=None):
    """Every stage's part, or only those of the stages in config paper.stages (e.g. a test)."""
    stages = config.get("paper", {}).get("stages", PAPER_STAGES)
    return [f"results/paper/parts/{stage}.json" for stage in PAPER_STAGES if stage in stages]


# the files of an imply evaluate report that the workflow names (imply.evaluate.report writes them all)
EVALUATE_REPORT_FILES = ["results.json", "report.md", "per_object.csv", "slides.png", "scores.png"]


def final_outputs():
    """What `snakemake` builds by default: every stage's outputs and the merged paper outputs."""
    stages = config.get("paper", {}).get("stages", PAPER_STAGES)
    out = ["results/table/table.npz", "results/table/scene.xml"]
    if "section4" in stages:
        out += expand("results/paper/tables/table{n}.tex", n=[1, 2])
        out += expand("results/paper/figures/figure1.{ext}", ext=["pdf", "png"])
    if "clips" in stages:
        out += ["results/readout/ridge.npz", "results/readout/metrics.json"]
    if "section5" in stages:
        out += ["results/paper/tables/table3.tex", *expand("results/paper/figures/figure2.{ext}", ext=["pdf", "png"])]
        out += ["results/model/training.png"]
    if "gap" in stages:
        out += ["results/gap/benchmark.json", "results/gap/benchmark.md"]
        out += ["results/gap/lab/separability.json", "results/gap/lab/separability.md"]
        out += ["results/gap/lab/sealed/score.json", "results/gap/lab/sealed/score.md"]
    if "evaluate" in stages:
        out += [f"results/evaluate/standins/{name}" for name in EVALUATE_REPORT_FILES]
    if "pixel" in stages:
        out += expand("results/paper/figures/figure3.{ext}", ext=["pdf", "png"])
        out += [f"results/pixel/evaluate/{v}/{name}" for v in PIXEL_VARIANTS for name in EVALUATE_REPORT_FILES]
    out += paper_parts()
    out += [f"results/paper/{name}" for name in ("macros.tex", "numbers.json", "reproduction.md", "reproduction.csv", "reproduction.html")]
    return out
