"""The benchmarks' generation cut to what is read, and split into shards: the same files either way."""

from __future__ import annotations

import filecmp
import json
from pathlib import Path

import pytest

from imply.cli import main
from imply.realworld import lab
from imply.realworld.lab import RUNS, LabBenchmarkConfig, write_lab_set
from imply.realworld.separability import mark_logs
from imply.realworld.shards import merge_labels, merge_timing, shard_cases
from run_folders import built_once

# a lab set of what the cut is about, 2 boxes x 3 speeds each: a null log without probes, an effect log with weighed
# masses and probes, an effect log in Bullet with unweighed masses in the four-direction design
LAB = {
    "seed": 5,
    "logs": {"null_contact": 1, "single_contact": 1, "single_bullet": 1},
    "development_logs": {},
    "n_objects": 2,
    "speeds": [0.3, 0.6, 0.9],
    "masses": [0.3, 1.5],
    "frictions": [0.15, 0.45],
    "four_share": 0.4,
    "probe_share": 0.5,
    "measured_mass_share": 0.5,
}
CONTACT = {
    "seed": 4,
    "logs": {"null_contact": 1, "single_contact": 1, "single_engine": 1},
    "n_objects": 2,
    "speeds": [0.3, 0.6, 0.9],
    "four_share": 0.5,
    "accuracy": {"pushes": 2, "nominal": 1, "factor": 2},
}


def _same_files(a: Path, b: Path) -> None:
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir()) and names
    match, mismatch, errors = filecmp.cmpfiles(a, b, names, shallow=False)
    assert not mismatch and not errors, (mismatch, errors)


def _marks(path: Path, design: LabBenchmarkConfig) -> str:
    """The marking of every log of a labels file, as JSON text (NaN equal to NaN)."""
    labels = json.loads(path.read_text())
    marks = mark_logs(
        labels, alias_cos=design.alias_cos, min_size_sd=design.min_size_sd, crossing_sd=design.crossing_sd
    )
    return json.dumps(marks, sort_keys=True)


def _lab_args(tmp_path: Path, table: Path, name: str, *shard: str) -> list[str]:
    return [
        "study",
        "gap",
        "lab-generate",
        "--lab-json",
        json.dumps(LAB),
        "--set",
        "sealed",
        "--table",
        str(table),
        "--logs",
        str(tmp_path / name / "logs"),
        "--labels",
        str(tmp_path / name / "labels.json"),
        "--timing",
        str(tmp_path / name / "timing.json"),
        "--threads",
        "1",
        *shard,
    ]


@pytest.fixture(scope="module")
def lab_set(tiny_table_path, tmp_path_factory) -> Path:
    """The LAB set, written by one unsharded 'imply study gap lab-generate' into a folder (logs/, labels.json,
    timing.json), by one test worker for the module's tests whichever workers run them."""

    def build(root: Path) -> None:
        assert main(_lab_args(root, tiny_table_path, "one")) == 0

    return built_once(tmp_path_factory, "lab-set", build) / "one"


def test_runs_cut_to_what_the_marking_reads_leave_the_logs_and_the_marking_alone(lab_set, scene, tmp_path, monkeypatch):
    design = LabBenchmarkConfig.from_dict(LAB)
    cases = lab.draw_lab_cases(design)
    # the design holds what the cut is about
    assert any(not c["effects"] and not c["probes"] for c in cases)
    assert any(c["effects"] and c["measured_mass"] for c in cases)
    assert any(c["design"] == "four" for c in cases)
    # what every label held before: all five runs, each with every probe
    monkeypatch.setattr(lab, "run_probes", lambda case: {r: True for r in RUNS if r != "contact" or case["effects"]})
    write_lab_set(design, scene, logs=tmp_path / "logs", labels=tmp_path / "labels.json", timing=tmp_path / "t.json")
    _same_files(lab_set / "logs", tmp_path / "logs")
    cut, full = (json.loads((folder / "labels.json").read_text()) for folder in (lab_set, tmp_path))
    assert all(
        set(full[c]["noise_free"]) - set(cut[c]["noise_free"]) == {"log_mass"} for c in cut if cut[c]["measured_mass"]
    )
    assert _marks(lab_set / "labels.json", design) == _marks(tmp_path / "labels.json", design)
    pushes = [
        json.loads((folder / name).read_text())["mujoco"]["pushes"]
        for folder, name in ((lab_set, "timing.json"), (tmp_path, "t.json"))
    ]
    assert pushes[0] < pushes[1]


def test_a_sharded_lab_set_merges_into_the_unsharded_one(lab_set, tmp_path, tiny_table_path):
    for k in (0, 1):
        assert main(_lab_args(tmp_path, tiny_table_path, "two", "--shard", str(k), "--shards", "2")) == 0
        (tmp_path / "two" / "labels.json").rename(tmp_path / f"labels{k}.json")
        (tmp_path / "two" / "timing.json").rename(tmp_path / f"timing{k}.json")
    parts = [str(tmp_path / f"labels{k}.json") for k in (0, 1)]
    timings = [str(tmp_path / f"timing{k}.json") for k in (0, 1)]
    merged, merged_timing = tmp_path / "labels.json", tmp_path / "timing.json"
    args = [
        "study",
        "gap",
        "merge-labels",
        *parts,
        "-o",
        str(merged),
        "--timing",
        *timings,
        "--timing-output",
        str(merged_timing),
    ]
    assert main(args) == 0
    assert filecmp.cmp(merged, lab_set / "labels.json", shallow=False)
    _same_files(tmp_path / "two" / "logs", lab_set / "logs")
    # each shard simulated its own logs' pushes: together as many as one run
    one, two = (json.loads(path.read_text()) for path in (lab_set / "timing.json", merged_timing))
    assert {e: t["pushes"] for e, t in two.items()} == {e: t["pushes"] for e, t in one.items()}


def _generate_args(tmp_path: Path, table: Path, name: str, *extra: str) -> list[str]:
    return [
        "study",
        "gap",
        "generate",
        "--table",
        str(table),
        "--contact-bench-json",
        json.dumps(CONTACT),
        "--logs",
        str(tmp_path / name / "logs"),
        "--sealed",
        str(tmp_path / name / "labels.json"),
        "--threads",
        "1",
        *extra,
    ]


def test_sharded_benchmark_logs_merge_into_the_unsharded_ones(tmp_path, tiny_table_path):
    assert main(_generate_args(tmp_path, tiny_table_path, "one", "--accuracy", str(tmp_path / "one" / "a.json"))) == 0
    for k in (0, 1):
        # the world's error measured once, by shard 0, on the same sample of every log's pushes
        extra = ["--accuracy", str(tmp_path / "two" / "a.json")] if k == 0 else []
        assert main(_generate_args(tmp_path, tiny_table_path, "two", "--shard", str(k), "--shards", "2", *extra)) == 0
        (tmp_path / "two" / "labels.json").rename(tmp_path / "two" / f"labels{k}.json")
    parts = [str(tmp_path / "two" / f"labels{k}.json") for k in (0, 1)]
    assert main(["study", "gap", "merge-labels", *parts, "-o", str(tmp_path / "two" / "labels.json")]) == 0
    for name in ("labels.json", "a.json"):
        assert filecmp.cmp(tmp_path / "two" / name, tmp_path / "one" / name, shallow=False), name
    _same_files(tmp_path / "two" / "logs", tmp_path / "one" / "logs")
    # one shard's labels hold its logs alone: every second log from its own on
    assert sorted(json.loads(Path(parts[1]).read_text())) == ["log-001"]


def test_shards_split_the_logs_by_index_and_merging_refuses_a_log_twice():
    cases = [{"id": f"log-{k:03d}"} for k in range(5)]
    assert [c["id"] for c in shard_cases(cases, 1, 2)] == ["log-001", "log-003"]
    assert sum((shard_cases(cases, k, 3) for k in range(3)), []) != cases  # interleaved, not in blocks
    assert sorted(c["id"] for k in range(3) for c in shard_cases(cases, k, 3)) == [c["id"] for c in cases]
    with pytest.raises(ValueError, match="shard 2 of 2"):
        shard_cases(cases, 2, 2)
    with pytest.raises(ValueError, match="log-001"):
        merge_labels([{"log-001": {}}, {"log-001": {}, "log-002": {}}])
    timing = merge_timing([{"mujoco": {"pushes": 3, "seconds": 1.5}}, {"mujoco": {"pushes": 1, "seconds": 0.5}}])
    assert timing == {"mujoco": {"pushes": 4, "seconds": 2.0, "seconds_per_push": 0.5}}


def test_an_unsharded_generation_still_needs_the_accuracy_and_a_shard_its_range(tmp_path, tiny_table_path, capsys):
    assert main(_generate_args(tmp_path, tiny_table_path, "x")) == 2
    assert "--accuracy is required" in capsys.readouterr().err
    assert main(_generate_args(tmp_path, tiny_table_path, "x", "--shard", "2", "--shards", "2")) == 2
    assert "--shard 2" in capsys.readouterr().err
