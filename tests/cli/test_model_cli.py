"""``imply study model train|readout|rollout`` on synthetic features, and ``imply study section5`` on ``imply evaluate`` reports, then the paper part."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from imply.cli import main
from synthetic_features import synth_split

# tiny tensors: extra torch threads only contend with the rest of the suite
pytestmark = pytest.mark.usefixtures("one_torch_thread")

TINY = {"width": 32, "depth": 2, "heads": 2}
TRAIN = {"epochs": 2, "context_free_epochs": None, "batch_size": 16, "rollout_steps": 2, "final_weight": 5.0}
# the smallest training (the default is the study's 40 epochs)
ONE_EPOCH = {"epochs": 1, "context_free_epochs": None}
QUERY = {"query_context": 1, "query_frames": [0, 1, 4, 7]}
VARIANTS = {"calib": {"calib": True, **QUERY}, "nocalib": {"calib": False, **QUERY}}


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    d = tmp_path_factory.mktemp("synth")
    synth_split(d, "train", 48, False, 1)
    synth_split(d, "heldout_calib", 12, True, 2)
    synth_split(d, "heldout_nocalib", 14, True, 3)
    synth_split(d, "validation", 10, True, 4)
    return d


def test_cli_train_validates_every_epoch_and_rolls_out(synth, tmp_path, tiny_table_path):
    d = synth
    assert (
        main(
            [
                "study",
                "model",
                "readout",
                "--features",
                str(d / "train.npz"),
                "--clips",
                str(d / "train.csv"),
                "--heldout",
                str(d / "heldout_calib.npz"),
                str(d / "heldout_calib.csv"),
                "--token-grid",
                "1",
                "2",
                "-o",
                str(tmp_path / "readout.npz"),
                "--report",
                str(tmp_path / "readout.json"),
            ]
        )
        == 0
    )
    r2 = json.loads((tmp_path / "readout.json").read_text())["heldout_r2_log"]["heldout_calib"]
    assert r2 > 0.8
    score = json.dumps({"grid": 21, "readout_floor": 1e-4})
    for variant in ("calib", "nocalib"):
        out = tmp_path / variant / "seed0"
        assert (
            main(
                [
                    "study",
                    "model",
                    "train",
                    "--features",
                    str(d / "train.npz"),
                    "--clips",
                    str(d / "train.csv"),
                    "--preset-json",
                    json.dumps(TINY),
                    "--variant-json",
                    json.dumps(VARIANTS[variant]),
                    "--train-json",
                    json.dumps(TRAIN),
                    "--seed",
                    "0",
                    "--threads",
                    "1",
                    "--token-grid",
                    "1",
                    "2",
                    "--readout",
                    str(tmp_path / "readout.npz"),
                    "--validation",
                    str(d / "validation.npz"),
                    str(d / "validation.csv"),
                    "--table",
                    str(tiny_table_path),
                    "--score-json",
                    score,
                    "-o",
                    str(out / "model.pt"),
                    "--history",
                    str(out / "training.json"),
                ]
            )
            == 0
        )
        assert (out / "checkpoint.pt").exists()
        history = json.loads((out / "training.json").read_text())["history"]
        assert [h["epoch"] for h in history] == [1, 2]
        # every Table 3 quantity of each context, the own-vs-swap shares, the baseline
        contexts = ("own", "swap", "none") if variant == "calib" else ("none",)
        fields = ("track", "error", "self_disagreement", "anchored_disagreement", "corr_anchored")
        keys = [f"{c}_{f}" for c in contexts for f in fields] + ["blind_error"]
        keys += ["own_lt_swap_self", "own_lt_swap_anchored"] if variant == "calib" else []
        assert all(np.isfinite(h[k]) for h in history for k in keys)
        assert 0 <= history[-1].get("own_lt_swap_anchored", 0) <= 100
    histories = [str(tmp_path / v / "seed0" / "training.json") for v in ("calib", "nocalib")]
    assert main(["study", "model", "plot", *histories, "-o", str(tmp_path / "training.png")]) == 0
    assert (tmp_path / "training.png").stat().st_size > 1000
    out = tmp_path / "calib" / "seed0"
    assert (
        main(
            [
                "study",
                "model",
                "rollout",
                "--model",
                str(out / "model.pt"),
                "--features",
                str(d / "heldout_calib.npz"),
                "--clips",
                str(d / "heldout_calib.csv"),
                "--readout",
                str(tmp_path / "readout.npz"),
                "--contexts",
                "own,swap,none",
                "--derangement-seed",
                "4",
                "--threads",
                "1",
                "-o",
                str(out / "rollouts.csv"),
            ]
        )
        == 0
    )
    ro = pd.read_csv(out / "rollouts.csv")
    assert set(ro["context"]) == {"own", "swap", "none"}
    assert len(ro[(ro.role == "rollout") & (ro.context == "own")]) == 12 * 5
    sw = ro[ro.context == "swap"]
    assert (sw["context_object"] != sw["object_id"]).all()
    # validation needs its instruments: refused before any training, nothing written
    rc = main(
        [
            "study",
            "model",
            "train",
            "--features",
            str(d / "train.npz"),
            "--clips",
            str(d / "train.csv"),
            "--preset-json",
            json.dumps(TINY),
            "--variant-json",
            json.dumps(VARIANTS["calib"]),
            "--train-json",
            json.dumps(ONE_EPOCH),
            "--seed",
            "0",
            "--token-grid",
            "1",
            "2",
            "--validation",
            str(d / "validation.npz"),
            str(d / "validation.csv"),
            "-o",
            str(tmp_path / "no_table.pt"),
        ]
    )
    assert rc == 2 and not (tmp_path / "no_table.pt").exists()


def _evaluation_report(suite_dir, folder, *, model: str, seed: int, conditions: tuple[str, ...]) -> str:
    """An imply evaluate report of displacements made up from the suite's truth: own calibration
    tracks the object, another object's and none do not."""
    from imply.evaluate.suite import load_suite, load_truth

    suite = load_suite(suite_dir)
    truth = load_truth(suite)
    rng = np.random.default_rng([seed, len(model)])
    rows = []
    for cond in conditions:
        disp = truth.displacement if cond == "own" else truth.displacement[suite.partner]
        if cond == "none":
            disp = np.broadcast_to(np.exp(np.log(truth.displacement).mean(axis=0)), disp.shape)
        noisy = disp * np.exp(rng.normal(0, 0.05, disp.shape))
        for i, obj in enumerate(suite.object_ids):
            for k, v in enumerate(suite.query_speeds):
                rows.append({"object_id": obj, "condition": cond, "speed": v, "sample": 0, "displacement": noisy[i, k]})
    csv = folder / f"{model}_seed{seed}.csv"
    pd.DataFrame(rows).to_csv(csv, index=False)
    report = folder / f"{model}_seed{seed}"
    assert (
        main(
            [
                "evaluate",
                "--rollouts",
                str(csv),
                "--suite",
                str(suite_dir),
                "-o",
                str(report),
                "--conditions",
                ",".join(conditions),
                "--bootstrap",
                "20",
                "--no-progress",
            ]
        )
        == 0
    )
    return f"{model}:{seed}:{report}"


def test_cli_section5_reads_evaluate_reports(synth, tiny_suite, tmp_path, tiny_table_path):
    d = synth
    specs = []
    for seed in (0, 1):
        specs += [
            "--evaluation",
            _evaluation_report(tiny_suite, tmp_path, model="calib", seed=seed, conditions=("own", "other", "none")),
        ]
        specs += [
            "--evaluation",
            _evaluation_report(tiny_suite, tmp_path, model="nocalib", seed=seed, conditions=("none",)),
        ]
    suites = ["--suite", f"calib:{tiny_suite}", "--suite", f"nocalib:{tiny_suite}"]
    score = json.dumps({"grid": 21, "readout_floor": 1e-4})
    metrics, part, paper = tmp_path / "s5" / "metrics.json", tmp_path / "parts" / "section5.json", tmp_path / "paper"
    args = [
        "study",
        "section5",
        *specs,
        *suites,
        "--table",
        str(tiny_table_path),
        "--train-clips",
        str(d / "train.csv"),
        "--score-json",
        score,
        "--selection-seed",
        "1",
        "--metrics",
        str(metrics),
        "--per-object",
        str(tmp_path / "s5" / "per_object.csv"),
    ]
    assert main(args) == 0
    doc = json.loads(metrics.read_text())
    assert doc["result"]["seeds"][0]["readouts"]["calib"]["name"] == "as given"
    assert main(["study", "paper", "part", "section5", str(metrics), "-o", str(part)]) == 0
    numbers = json.loads(part.read_text())["numbers"]
    # the report names the instrument behind every number: each model's readout
    read_by = json.loads(part.read_text())["read_by"]
    assert read_by.count("as given") == 4 and "nocalib seed 1" in read_by
    m = tmp_path / "merged"
    assert (
        main(
            [
                "study",
                "paper",
                "merge",
                str(part),
                "--macros",
                str(m / "macros.tex"),
                "--numbers",
                str(m / "n.json"),
                "--report-md",
                str(m / "r.md"),
                "--report-csv",
                str(m / "r.csv"),
            ]
        )
        == 0
    )
    report = (m / "r.md").read_text()
    assert "[section5] calib seed 0: as given" in report and "| vjCTrack | 5 |" in report
    assert pd.read_csv(m / "r.csv").set_index("name").loc["vjCTrack", "read_by"] == read_by
    for name in (
        "vjNOne",
        "vjNTwo",
        "vjQTrack",
        "vjCAnch",
        "vjSelAnchOwn",
        "vjSOneSCorrAnch",
        "vjSelfOwnLtSwap",
        "vjBErr",
        "vjBQErr",
        "vjSOneQErr",
    ):
        assert name in numbers
    assert numbers["vjNOne"] == 6 and numbers["vjNTwo"] == 6
    # made-up own rollouts track the truth, the partner's do not
    assert numbers["vjCTrack"] > 0.9 and numbers["vjCErr"] < numbers["vjSErr"]
    claims = json.loads(part.read_text())["claims"]
    assert {c["id"] for c in claims} >= {
        "s5-self-chance",
        "s5-anchored-prefers-own",
        "s5-second-seed",
        "s5-own-beats-blind",
        "s5-nocalib-blind",
        "s5-self-no-error-track",
        "s5-targets-seed0",
        "s5-targets-seed1",
    }
    assert all(isinstance(c["holds"], bool) for c in claims)
    assert main(["study", "paper", "tables", "--part", str(part), "--table3", str(paper / "table3.tex")]) == 0
    tex = (paper / "table3.tex").read_text()
    assert r"\toprule" in tex and tex.count(r"\\") >= 8 and "object-blind baseline" in tex
    assert (
        main(
            [
                "study",
                "paper",
                "figure2",
                "--per-object",
                str(tmp_path / "s5" / "per_object.csv"),
                "--pdf",
                str(paper / "figure2.pdf"),
                "--png",
                str(paper / "figure2.png"),
            ]
        )
        == 0
    )
    assert (paper / "figure2.pdf").stat().st_size > 1000 and (paper / "figure2.png").exists()
    first = metrics.read_bytes()
    assert main(args) == 0
    assert metrics.read_bytes() == first
    # a report scored on another suite, or a missing model, is refused
    assert main([*args[:2], *specs[:2], *suites, *args[len(specs) + len(suites) + 2 :]]) == 2


def test_cli_rejects_bad_options(synth, tmp_path, capsys):
    d = synth
    rc = main(
        [
            "study",
            "model",
            "train",
            "--features",
            str(d / "train.npz"),
            "--clips",
            str(d / "train.csv"),
            "--preset-json",
            json.dumps({**TINY, "widht": 3}),
            "--variant-json",
            json.dumps(VARIANTS["calib"]),
            "--train-json",
            json.dumps(ONE_EPOCH),
            "--seed",
            "0",
            "-o",
            str(tmp_path / "m.pt"),
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "widht" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "m.pt").exists()
    rc = main(
        [
            "study",
            "model",
            "train",
            "--features",
            str(d / "train.npz"),
            "--clips",
            str(d / "train.csv"),
            "--preset-json",
            json.dumps({**TINY, "heads": 3}),
            "--variant-json",
            json.dumps(VARIANTS["calib"]),
            "--train-json",
            json.dumps(ONE_EPOCH),
            "--seed",
            "0",
            "-o",
            str(tmp_path / "m.pt"),
        ]
    )
    assert rc == 2 and "heads" in capsys.readouterr().err and not (tmp_path / "m.pt").exists()


def test_cli_rollout_refuses_a_readout_of_other_tokens(synth, tmp_path, capsys):
    d = synth
    assert (
        main(
            [
                "study",
                "model",
                "readout",
                "--features",
                str(d / "train.npz"),
                "--clips",
                str(d / "train.csv"),
                "-o",
                str(tmp_path / "readout.npz"),
                "--report",
                str(tmp_path / "readout.json"),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "study",
                "model",
                "train",
                "--features",
                str(d / "train.npz"),
                "--clips",
                str(d / "train.csv"),
                "--preset-json",
                json.dumps(TINY),
                "--variant-json",
                json.dumps(VARIANTS["nocalib"]),
                "--train-json",
                json.dumps(ONE_EPOCH),
                "--seed",
                "0",
                "--threads",
                "1",
                "--token-grid",
                "1",
                "2",
                "-o",
                str(tmp_path / "m.pt"),
            ]
        )
        == 0
    )
    capsys.readouterr()
    rc = main(
        [
            "study",
            "model",
            "rollout",
            "--model",
            str(tmp_path / "m.pt"),
            "--features",
            str(d / "heldout_nocalib.npz"),
            "--clips",
            str(d / "heldout_nocalib.csv"),
            "--readout",
            str(tmp_path / "readout.npz"),
            "--contexts",
            "none",
            "-o",
            str(tmp_path / "r.csv"),
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "--token-grid" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "r.csv").exists()
    rc = main(
        [
            "study",
            "model",
            "train",
            "--features",
            str(d / "train.npz"),
            "--clips",
            str(d / "train.csv"),
            "--preset-json",
            json.dumps(TINY),
            "--variant-json",
            json.dumps(VARIANTS["nocalib"]),
            "--train-json",
            json.dumps(ONE_EPOCH),
            "--seed",
            "0",
            "--token-grid",
            "3",
            "2",
            "-o",
            str(tmp_path / "m3.pt"),
        ]
    )
    assert rc == 2 and "does not divide" in capsys.readouterr().err and not (tmp_path / "m3.pt").exists()


def test_cli_train_checks_every_output_before_training(synth, tmp_path, capsys):
    d = synth
    (tmp_path / "a_folder").mkdir()
    rc = main(
        [
            "study",
            "model",
            "train",
            "--features",
            str(d / "train.npz"),
            "--clips",
            str(d / "train.csv"),
            "--preset-json",
            json.dumps(TINY),
            "--variant-json",
            json.dumps(VARIANTS["nocalib"]),
            "--train-json",
            json.dumps(ONE_EPOCH),
            "--seed",
            "0",
            "--token-grid",
            "1",
            "2",
            "-o",
            str(tmp_path / "m.pt"),
            "--history",
            str(tmp_path / "a_folder"),
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "--history" in err and "folder" in err
    assert not (tmp_path / "m.pt").exists() and not (tmp_path / "checkpoint.pt").exists()
