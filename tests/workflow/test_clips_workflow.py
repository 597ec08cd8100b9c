"""The clips stage's rules on a tiny config: render -> pretrain -> encode -> readout, via snakemake."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import tiny_workflow_config
from imply.data.clips import load_clips
from imply.models.encoder import load_features
from imply.readout import load_readout
from workflow_helpers import copy_workflow, snakemake


@pytest.mark.slow
def test_clips_rules_on_tiny_config(repo_root: Path, tmp_path: Path, forked_imply):
    copy_workflow(tmp_path)
    cfg = tiny_workflow_config(repo_root / "tests/config/clips_tiny.yaml")
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(cfg))
    # targets go before --configfile, which takes every value after it
    targets = ("results/readout/ridge.npz", "results/paper/parts/clips.json")
    run = snakemake(tmp_path, *targets, "--configfile", str(tmp_path / "config.yaml"), check=False, timeout=300)
    logs = "\n".join(p.read_text() for p in sorted((tmp_path / "results/logs").glob("*.log")))
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-3000:] + logs[-3000:]

    frames, meta = load_clips(tmp_path / "results/clips/train.npz")
    assert frames.shape == (12, 3, 16, 64, 3) and len(meta) == 12
    feats = load_features(tmp_path / "results/features/heldout_calib.npz")
    assert feats["tokens"].shape == (1 * (2 + 5), 3, 4, 16) and feats["tokens"].dtype == np.float16
    readout = load_readout(tmp_path / "results/readout/ridge.npz")
    assert readout.predict(feats["tokens"][:, -1]).shape == (7,)
    part = json.loads((tmp_path / "results/paper/parts/clips.json").read_text())
    assert part["numbers"]["nTrainClips"] == 12
    assert {c["id"] for c in part["claims"]} == {"s5-ridge-readout", "s5-framediff-readout"}
    metrics = json.loads((tmp_path / "results/readout/metrics.json").read_text())["result"]
    assert set(metrics["heldout"]) == {"heldout_calib", "heldout_nocalib"}
