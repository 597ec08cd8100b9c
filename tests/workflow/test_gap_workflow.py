"""The gap stage's workflow on a tiny config: world logs, sealed labels, diagnoses, benchmark part."""

from __future__ import annotations

import json
import subprocess

import pytest

from stored.make_effect_cache import assert_stored
from workflow_helpers import copy_workflow, plant_table, snakemake


def _snakemake_tiny(tmp_path, repo_root, *targets: str) -> subprocess.CompletedProcess:
    """``snakemake TARGET... --cores 2`` in the copied workflow at ``tmp_path``, on the tiny gap config."""
    return snakemake(tmp_path, *targets, "--configfile", str(repo_root / "tests/config/gap_tiny.yaml"), check=False)


LAB_TARGETS = ("results/gap/lab/separability.json", "results/gap/lab/sealed/score.json")
# the lab's development set is marked under the gap_development target only
LAB_DEVELOPMENT = "results/gap/lab/development/separability.json"


@pytest.mark.slow
def test_gap_workflow_tiny(tmp_path, repo_root, tiny_table_path, forked_imply):
    """The gap stage's part and the lab benchmark, in one run (they share the table and the effect tables)."""
    copy_workflow(tmp_path)
    plant_table(tmp_path, tiny_table_path)
    target = "results/paper/parts/gap.json"
    run = _snakemake_tiny(tmp_path, repo_root, target, *LAB_TARGETS, LAB_DEVELOPMENT)
    assert run.returncode == 0, run.stderr[-3000:]
    check_effect_tables(tmp_path / "results/gap/effect_tables")
    check_lab(tmp_path)
    check_development_target(tmp_path, repo_root)
    part = json.loads((tmp_path / target).read_text())
    assert part["stage"] == "gap"
    assert {
        "gapTopOneAcc",
        "gapFalseAlarm",
        "gapFalseAlarmHeavy",
        "gapBothNamed",
        "gapNoneRecall",
        "gapMagErr",
        "gapShrinkMedian",
        "gapWorldErrMax",
        "gapTableErrMax",
        "gapLogsN",
    } <= set(part["numbers"])
    assert {c["id"] for c in part["claims"]} == {
        "gap-world",
        "gap-null",
        "gap-top1",
        "gap-both",
        "gap-outside",
        "gap-magnitude",
        "gap-shrink",
        "gap-contact-null",
        "gap-contact-named",
        "gap-contact-contenders",
        "gap-contact-wrong",
        # the lab benchmark's sealed set alone and with probes ...
        "gap-lab-null",
        "gap-lab-pusher",
        "gap-lab-named",
        "gap-lab-wrong",
        "gap-lab-wrong-effect",
        "gap-lab-contact",
        # ... and against each log's reference session, with its closed loop
        "gap-lab-ref-null",
        "gap-lab-ref-single",
        "gap-lab-ref-named",
        "gap-lab-ref-wrong-effect",
        "gap-lab-ref-wrong",
        "gap-lab-ref-shrink",
        "gap-lab-ref-contact",
        "gap-lab-ref-loop",
    }
    assert "gapContactSingleRight" in part["numbers"]
    # the design variant with every observable (pusher speed, track) is scored on the development sets only
    assert not any(name.startswith("gapObs") for name in part["numbers"])
    assert {"gapLabNullNoLib", "gapLabSingleRightProbes", "gapLabLoopRight", "gapLabRefNullNoChange"} <= set(
        part["numbers"]
    )
    assert {"gapShrinkTruthWithin", "gapContactShrinkTruthWithin", "gapLabRefShrinkWithin"} <= set(part["numbers"])
    assert {
        "gapContactLogsN",
        "gapContactNullNoLib",
        "gapContactAmongNamed",
        "gapContactWrongSingle",
        "gapLoopRight",
        "gapLoopRandomRight",
    } <= set(part["numbers"])
    bench = json.loads((tmp_path / "results/gap/benchmark.json").read_text())["result"]
    assert bench["n_logs"] == 7 and bench["n_null"] == 3 and bench["n_double"] == 1 and bench["n_outside"] == 1
    # the world measured its own error, and the table's is beside it
    acc = json.loads((tmp_path / "results/gap/world_accuracy.json").read_text())
    assert acc["against_finer"]["log_d"]["n"] == 6 and acc["table_numerical_error"]["cells"] == 4
    # the diagnose rules never see the labels: the push logs hold what a lab records, named log-NNN
    files = sorted(p.name for p in (tmp_path / "results/gap/logs").iterdir())
    logs = [f"log-{k:03d}.csv" for k in range(7)]
    assert files == sorted(logs + [f"log-{k:03d}.track.csv" for k in range(7)])  # each log filmed
    for name in logs:
        header = (tmp_path / "results/gap/logs" / name).read_text().splitlines()[0].split(",")
        assert header[:4] == ["object_id", "speed", "direction", "displacement"]
        assert set(header) <= {
            "object_id",
            "speed",
            "direction",
            "displacement",
            "stop_time",
            "pusher_speed",
            "size_x",
            "size_y",
            "size_z",
            "mass",
        }
        assert "pusher_speed" in header  # a robot's encoders give it on every push
    md = (tmp_path / "results/gap/benchmark.md").read_text()
    assert md.startswith("# Gap diagnostic benchmark") and "## Confusion matrix" in md
    # the other-contact benchmark: MuJoCo contact models and Bullet, scored into the same result
    contact = bench["contact"]
    assert contact["n_logs"] == 4 and {row["engine"] for row in contact["cases"]} == {"mujoco", "bullet"}
    assert "# Other contact models" in md
    # beside each score, what the true effect's own hypothesis states whatever the verdict
    single = [row for row in contact["cases"] if row["group"] in ("single_contact", "single_engine")]
    assert single and all(isinstance(row["told_right"], bool) for row in single)
    assert all(row["told_error"] is None or row["told_error"] >= 0 for row in single)
    assert "told the cause: its own hypothesis within tolerance" in md
    assert not (tmp_path / "results/gap/reports_observed").exists() and "# With what a robot records" not in md
    report = next((tmp_path / "results/gap/reports").glob("shard*/log-*/report.md")).read_text()
    assert report.startswith("# Sim-to-real gap diagnosis\n\n**")
    # the closed loop: every undecided log's next pushes run in its world, and as many random ones
    loop = bench["contact"]["closed_loop"]
    rows = [
        json.loads((d / "closed_loop.json").read_text())["rows"]
        for d in (tmp_path / "results/gap/contact/closed_loop").iterdir()
    ]
    assert sum(len(r) for r in rows) == len(loop["rows"])
    assert {r["arm"] for r in loop["rows"]} <= {"next", "random"} and "## Closed loop" in md


def check_effect_tables(folder):
    """The rule built a table for each candidate the library tabulates, the observables' baseline and the model floor;
    on the tiny table and the stored cache's grid, those the stored cache holds are its files
    (tests/stored/effect-cache, which the diagnosing tests start from)."""
    built = sorted(p.name for p in folder.glob("[!.]*") if p.name != "manifest.json")
    assert [name.rsplit("-", 1)[0] for name in built] == ["effects-air_drag", "effects-viscous", "floor", "observables"]
    assert_stored(folder, [name for name in built if not name.startswith("effects-air_drag")])


def check_development_target(tmp_path, repo_root):
    """``gap_development`` builds the development sets of the three benchmarks (drawn with their own seeds) and
    scores them as the sealed sets are, without remaking anything the default run built."""
    run = _snakemake_tiny(tmp_path, repo_root, "gap_development", "-n", "--quiet", "rules")
    assert run.returncode == 0, run.stderr[-3000:]
    planned = run.stdout + run.stderr
    for rule in (
        "gap_dev_generate",
        "gap_dev_contact_generate",
        "gap_dev_diagnose",
        "gap_dev_diagnose_observed",
        "gap_dev_contact_diagnose_observed",
        "gap_dev_contact_closed_loop",
        "gap_dev_benchmark",
        "gap_lab_diagnose_reference",
        "gap_lab_score",
    ):
        assert rule in planned, planned
    for rule in ("gap_generate ", "gap_diagnose ", "gap_tables", "gap_lab_separability_development"):
        assert rule not in planned, planned


def check_lab(tmp_path):
    """The lab benchmark's two sets on every engine, with probes and reference sessions, each effect log marked, and
    the sealed set diagnosed alone, with its probes and against its references, and scored."""
    target, score = LAB_TARGETS
    result = json.loads((tmp_path / target).read_text())["result"]
    assert set(result["sets"]) == {"sealed"}
    sealed = result["sets"]["sealed"]
    dev_result = json.loads((tmp_path / LAB_DEVELOPMENT).read_text())["result"]
    assert set(dev_result["sets"]) == {"development"}
    dev = dev_result["sets"]["development"]
    # the engine never used to choose is in the sealed set only
    assert {m["engine"] for m in sealed["logs"]} == {"mujoco", "bullet", "sapien"}
    assert {m["engine"] for m in dev["logs"]} == {"mujoco", "bullet"}
    for m in sealed["logs"] + dev["logs"]:
        if m["effect"] is None:
            assert m["null_gap_sd"] > 0
        else:
            assert set(m["sets"]) == {"displacement", "stop_time", "pusher_track", "probes"}
            assert all(-1 <= s["cos"] <= 1 and s["separable"] == (abs(s["cos"]) < 0.95) for s in m["sets"].values())
    assert sealed["summary"]["all"]["effect_logs"] == 3 and "sapien" in sealed["timing"]
    md = (tmp_path / "results/gap/lab/separability.md").read_text()
    assert md.startswith("# Lab benchmark") and "| + probes |" in md
    # probes where drawn: every probe file names probes of the three kinds, and is read by the diagnostic's reader
    from imply.diagnose.inputs.probes import read_probes
    from imply.diagnose.inputs.pushlog import read_pushlog

    labels = json.loads((tmp_path / "results/gap/lab/sealed/labels.json").read_text())
    folder = tmp_path / "results/gap/lab/sealed/logs"
    probed = sorted(p.name.split(".")[0] for p in folder.glob("*.probes.csv"))
    assert probed == sorted(k for k, lab in labels.items() if lab["probes"])
    for name in probed:
        pushlog = read_pushlog(folder / f"{name}.csv")
        probes = read_probes(folder / f"{name}.probes.csv", objects=pushlog.objects, log_path=pushlog.path)
        assert probes.free_stroke_speed.size and probes.friction.size and probes.n_added
    # the sealed set's score: both variants over its logs, split by separability, the closed loop, and a report
    scored = json.loads((tmp_path / score).read_text())["result"]
    assert scored["n_logs"] == len(labels) == 4
    for variant in ("probes", "no_probes"):
        assert scored[variant]["all"]["n_logs"] == 4
        assert {c["case"] for c in scored[variant]["all"]["cases"]} == set(labels)
        singles = scored[variant]["separable"]["n_logs"] + scored[variant]["not_separable"]["n_logs"]
        assert singles == sum(lab["group"].startswith("single") for lab in labels.values())
    # a log with probes says in its report whether they entered its fits
    for name, lab in labels.items():
        for variant in ("probes", "no_probes"):
            report = (tmp_path / f"results/gap/lab/sealed/reports_{variant}/{name}/report.md").read_text()
            if lab["probes"]:
                said = "entered every fit" if variant == "probes" else "no fit used them"
                assert said in report
    # every log has a reference session: its boxes, one push of each of its pushes' conditions, probes where it has
    # them; its diagnosis against it says both gaps, and the tier is scored apart
    refs = tmp_path / "results/gap/lab/sealed/references"
    shards = sorted((tmp_path / "results/gap/lab/sealed/reports_reference").iterdir())
    assert len(shards) > 1 and shards == sorted((tmp_path / "results/gap/lab/sealed/reports_reference").glob("shard*"))
    for name, lab in labels.items():
        ref, own = read_pushlog(refs / f"{name}.csv"), read_pushlog(folder / f"{name}.csv")
        assert ref.objects == own.objects and (refs / f"{name}.probes.csv").is_file() == bool(lab["probes"])
        conditions = {(o, round(v, 6), round(d, 6)) for o, v, d in zip(own.obj, own.speed, own.direction, strict=True)}
        assert ref.n == len(conditions)
        # the reference tier is sharded: each log diagnosed once, in the shard of its place in the sorted set
        found = sorted((tmp_path / "results/gap/lab/sealed/reports_reference").glob(f"shard*/{name}/summary.json"))
        assert [p.parts[-3] for p in found] == [f"shard{sorted(labels).index(name) % len(shards)}"]
        summary = json.loads(found[0].read_text())
        assert summary["reference"]["objects_shared"] == own.objects and "cause_shrink" in summary
        assert summary["sentence"].startswith("The standing gap, read from the reference session")
    assert scored["reference"]["all"]["n_logs"] == 4
    single = [c for c in scored["reference"]["all"]["cases"] if c["group"].startswith("single")]
    assert all(c["true_share"] is None or -1 < c["true_share"] <= 1 for c in single)
    # the closed loop ran (probes allowed) on the logs the reference tier left with several contenders
    loops = sorted((tmp_path / "results/gap/lab/sealed/closed_loop").glob("shard*/closed_loop.json"))
    assert len(loops) == len(shards)
    rows = [r for path in loops for r in json.loads(path.read_text())["rows"]]
    assert {r["arm"] for r in rows} <= {"next", "random"}
    assert set(scored["closed_loop"]) >= {"next", "random", "rows"}
    md = (tmp_path / "results/gap/lab/sealed/score.md").read_text()
    assert md.startswith("# Lab benchmark") and "## Closed loop" in md and "## How far the gap shrinks" in md
