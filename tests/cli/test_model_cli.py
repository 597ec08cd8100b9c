"""``imply model train|readout|rollout`` and ``imply section5`` end to end on synthetic features, then the paper part."""

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
TRAIN = {"epochs": 2, "batch_size": 16, "rollout_steps": 2, "final_weight": 5.0, "val_objects": 8}
# the smallest training (the defaults are the study's: 40 epochs, 200 validation objects)
ONE_EPOCH = {"epochs": 1, "val_objects": 0}
QUERY = {"query_context": 1, "query_frames": [0, 1, 4, 7]}
VARIANTS = {"calib": {"calib": True, **QUERY}, "nocalib": {"calib": False, **QUERY}}


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    d = tmp_path_factory.mktemp("synth")
    synth_split(d, "train", 48, False, 1)
    synth_split(d, "heldout_calib", 12, True, 2)
    synth_split(d, "heldout_nocalib", 14, True, 3)
    return d


def test_cli_train_rollout_section5(synth, tmp_path, tiny_table_path):
    d = synth
    assert main(["model", "readout", "--features", str(d / "train.npz"), "--clips", str(d / "train.csv"),
                 "--heldout", str(d / "heldout_calib.npz"), str(d / "heldout_calib.csv"), "--token-grid", "1", "2",
                 "-o", str(tmp_path / "readout.npz"), "--report", str(tmp_path / "readout.json")]) == 0  # fmt: skip
    r2 = json.loads((tmp_path / "readout.json").read_text())["heldout_r2_log"]["heldout_calib"]
    assert r2 > 0.8
    specs = []
    for variant, split, ctx in (("calib", "heldout_calib", "own,swap,none"), ("nocalib", "heldout_nocalib", "none")):
        for seed in (0, 1):
            out = tmp_path / variant / f"seed{seed}"
            assert main(["model", "train", "--features", str(d / "train.npz"), "--clips", str(d / "train.csv"),
                         "--preset-json", json.dumps(TINY), "--variant-json", json.dumps(VARIANTS[variant]),
                         "--train-json", json.dumps(TRAIN), "--seed", str(seed), "--threads", "1",
                         "--token-grid", "1", "2", "--readout", str(tmp_path / "readout.npz"),
                         "-o", str(out / "model.pt"), "--history", str(out / "training.json")]) == 0  # fmt: skip
            assert (out / "checkpoint.pt").exists()
            history = json.loads((out / "training.json").read_text())["history"]
            contexts = ("own", "swap") if variant == "calib" else ("none",)
            assert [h["epoch"] for h in history] == [1, 2]
            assert all(np.isfinite(h[f"{c}_{m}"]) for h in history for c in contexts for m in ("log_error", "track_r"))
            assert main(["model", "rollout", "--model", str(out / "model.pt"), "--features", str(d / f"{split}.npz"),
                         "--clips", str(d / f"{split}.csv"), "--readout", str(tmp_path / "readout.npz"),
                         "--contexts", ctx, "--derangement-seed", "4", "--threads", "1",
                         "-o", str(out / "rollouts.csv")]) == 0  # fmt: skip
            specs += ["--rollouts", f"{variant}:{seed}:{out / 'rollouts.csv'}"]
    histories = [str(tmp_path / v / f"seed{s}" / "training.json") for v in ("calib", "nocalib") for s in (0, 1)]
    assert main(["model", "plot", *histories, "-o", str(tmp_path / "training.png")]) == 0
    assert (tmp_path / "training.png").stat().st_size > 1000
    ro = pd.read_csv(tmp_path / "calib" / "seed0" / "rollouts.csv")
    assert set(ro["context"]) == {"own", "swap", "none"}
    assert len(ro[(ro.role == "rollout") & (ro.context == "own")]) == 12 * 5
    sw = ro[ro.context == "swap"]
    assert (sw["context_object"] != sw["object_id"]).all()
    score = json.dumps({"grid": 21, "readout_floor": 1e-4})
    metrics, part, paper = tmp_path / "s5" / "metrics.json", tmp_path / "parts" / "section5.json", tmp_path / "paper"
    args = ["section5", *specs, "--table", str(tiny_table_path), "--train-clips", str(d / "train.csv"),
            "--score-json", score, "--selection-seed", "1",
            "--metrics", str(metrics), "--per-object", str(tmp_path / "s5" / "per_object.csv")]  # fmt: skip
    assert main(args) == 0
    assert main(["paper", "part", "section5", str(metrics), "-o", str(part)]) == 0
    numbers = json.loads(part.read_text())["numbers"]
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
    assert numbers["vjNOne"] == 14 and numbers["vjNTwo"] == 12
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
    assert main(["paper", "tables", "--part", str(part), "--table3", str(paper / "table3.tex")]) == 0
    tex = (paper / "table3.tex").read_text()
    assert r"\toprule" in tex and tex.count(r"\\") >= 8 and "object-blind baseline" in tex
    assert main(["paper", "figure2", "--per-object", str(tmp_path / "s5" / "per_object.csv"),
                 "--pdf", str(paper / "figure2.pdf"), "--png", str(paper / "figure2.png")]) == 0  # fmt: skip
    assert (paper / "figure2.pdf").stat().st_size > 1000 and (paper / "figure2.png").exists()
    first = metrics.read_bytes()
    assert main(args) == 0
    assert metrics.read_bytes() == first


def test_cli_rejects_bad_options(synth, tmp_path, capsys):
    d = synth
    rc = main(["model", "train", "--features", str(d / "train.npz"), "--clips", str(d / "train.csv"),
               "--preset-json", json.dumps({**TINY, "widht": 3}), "--variant-json", json.dumps(VARIANTS["calib"]),
               "--train-json", json.dumps(ONE_EPOCH), "--seed", "0", "-o", str(tmp_path / "m.pt")])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and "widht" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "m.pt").exists()
    rc = main(["model", "train", "--features", str(d / "train.npz"), "--clips", str(d / "train.csv"),
               "--preset-json", json.dumps({**TINY, "heads": 3}), "--variant-json", json.dumps(VARIANTS["calib"]),
               "--train-json", json.dumps(ONE_EPOCH), "--seed", "0", "-o", str(tmp_path / "m.pt")])  # fmt: skip
    assert rc == 2 and "heads" in capsys.readouterr().err and not (tmp_path / "m.pt").exists()


def test_cli_rollout_refuses_a_readout_of_other_tokens(synth, tmp_path, capsys):
    d = synth
    assert main(["model", "readout", "--features", str(d / "train.npz"), "--clips", str(d / "train.csv"),
                 "-o", str(tmp_path / "readout.npz"), "--report", str(tmp_path / "readout.json")]) == 0  # fmt: skip
    assert main(["model", "train", "--features", str(d / "train.npz"), "--clips", str(d / "train.csv"),
                 "--preset-json", json.dumps(TINY), "--variant-json", json.dumps(VARIANTS["nocalib"]),
                 "--train-json", json.dumps(ONE_EPOCH), "--seed", "0", "--threads", "1", "--token-grid", "1", "2",
                 "-o", str(tmp_path / "m.pt")]) == 0  # fmt: skip
    capsys.readouterr()
    rc = main(["model", "rollout", "--model", str(tmp_path / "m.pt"), "--features", str(d / "heldout_nocalib.npz"),
               "--clips", str(d / "heldout_nocalib.csv"), "--readout", str(tmp_path / "readout.npz"),
               "--contexts", "none", "-o", str(tmp_path / "r.csv")])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and "--token-grid" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "r.csv").exists()
    rc = main(["model", "train", "--features", str(d / "train.npz"), "--clips", str(d / "train.csv"),
               "--preset-json", json.dumps(TINY), "--variant-json", json.dumps(VARIANTS["nocalib"]),
               "--train-json", json.dumps(ONE_EPOCH), "--seed", "0", "--token-grid", "3", "2",
               "-o", str(tmp_path / "m3.pt")])  # fmt: skip
    assert rc == 2 and "does not divide" in capsys.readouterr().err and not (tmp_path / "m3.pt").exists()


def test_cli_train_checks_every_output_before_training(synth, tmp_path, capsys):
    d = synth
    (tmp_path / "a_folder").mkdir()
    rc = main(["model", "train", "--features", str(d / "train.npz"), "--clips", str(d / "train.csv"),
               "--preset-json", json.dumps(TINY), "--variant-json", json.dumps(VARIANTS["nocalib"]),
               "--train-json", json.dumps(ONE_EPOCH), "--seed", "0", "--token-grid", "1", "2",
               "-o", str(tmp_path / "m.pt"), "--history", str(tmp_path / "a_folder")])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and "--history" in err and "folder" in err
    assert not (tmp_path / "m.pt").exists() and not (tmp_path / "checkpoint.pt").exists()
