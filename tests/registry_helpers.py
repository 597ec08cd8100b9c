"""Stand-in result documents for every registered number of a stage (tests of parts, tables, claims)."""

from __future__ import annotations

from imply.realworld.lab import LabBenchmarkConfig
from imply.realworld.lab_score import METRICS as LAB_METRICS


def fake_results(reg, stage: str, value: float = 0.5) -> dict:
    """Result documents holding ``value`` at every registered path of a stage (and what its claims read)."""
    results: dict = {}
    for e in reg.of_stage(stage):
        node = results.setdefault(e.source, {})
        *keys, last = e.path.split(".")
        for key in keys:
            node = node.setdefault(key, {})
        node[last] = value
    if stage == "section5":  # paths index the seed list
        doc = results["imply.study.section5.scoring.section5_results"]
        doc["seeds"] = [doc["seeds"]["0"], doc["seeds"]["1"]]
    extra = {
        "clips": {"r2_threshold": 0.95, "heldout_clips": 1, "features": "f.npz"},
        "gap": {
            "targets": {
                "false_alarm": 0.05,
                "top1": 0.9,
                "both_named": 0.8,
                "none_outside": 0.8,
                "magnitude_error": 0.1,
                "shrinkage": 0.8,
            },
            "min_size_sd": 2.0,
            "n_shrinkage": 3,
        },
    }.get(stage, {})
    for doc in results.values():
        doc.update(extra)
    if stage == "gap":
        lab = results["imply.realworld.lab_score.score_lab"]
        lab["targets"] = dict(LabBenchmarkConfig().targets)
        for variant in ("probes", "no_probes"):
            for subset in ("all", "separable", "not_separable", "probe_logs_separable"):
                node = lab.setdefault(variant, {}).setdefault(subset, {})
                for key, *_ in LAB_METRICS:
                    node.setdefault(key, value)
        doc = results["imply.realworld.benchmark.score_cases"]
        doc["world_error"]["table_rms"] = value
        contact = doc.setdefault("contact", {})
        contact.update(
            targets={
                "null_no_library": 0.9,
                "among_named": 0.9,
                "contenders_mean": 3.0,
                "magnitude_within": 0.3,
                "wrong_single": 0.1,
                "closed_loop": 0.6,
                "observed_single_right": 0.8,
            },
            min_size_sd=2.0,
        )
        for key in (
            "null_no_library",
            "among_named",
            "one_cause",
            "one_cause_right",
            "named",
            "wrong_single",
            "wrong_mechanism",
            "contenders_mean",
            "contenders_max",
        ):
            for suffix in ("", "_mujoco", "_bullet"):
                contact.setdefault(f"{key}{suffix}", value)
                contact.setdefault(f"n_{key}{suffix}", value)
    return results
