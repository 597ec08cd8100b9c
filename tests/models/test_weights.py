"""Released encoder weights: refused in one line when the workflow is read, and inputs of the encode rule."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
import yaml
from snakemake.utils import update_config

from conftest import tiny_workflow_config
from imply.models.config import ViTConfig
from imply.models.encoder import EncoderConfig, load_encoder
from imply.models.vision_transformer import VisionTransformer
from imply.models.weights import check_encoder_weights, encoder_weight_files
from workflow_helpers import copy_workflow, snakemake

TINY_ARCH = {"patch_size": 16, "tubelet_size": 2, "embed_dim": 16, "depth": 1, "num_heads": 2}


def _pt_section(path: Path, **extra) -> dict:
    return {"kind": "vjepa2_pt", "weights": str(path), "arch": TINY_ARCH, "input_size": [16, 64], **extra}


def _write_tiny_pt(path: Path, key: str = "target_encoder", arch: dict = TINY_ARCH, seed: int = 0) -> Path:
    torch.manual_seed(seed)
    state = VisionTransformer(ViTConfig.from_dict(arch)).state_dict()
    torch.save({key: {f"module.backbone.{k}": v for k, v in state.items()}, "epoch": 1}, path)
    return path


def test_a_tiny_checkpoint_passes_and_loads(tmp_path):
    section = _pt_section(_write_tiny_pt(tmp_path / "vitg.pt"))
    check_encoder_weights(section)
    # what the check lets through, the loader loads (strictly, into the same architecture)
    load_encoder(EncoderConfig.from_dict({**section, "device": "cpu"}))
    assert encoder_weight_files(section) == [str(tmp_path / "vitg.pt")]
    # the loader's fallback key passes too
    check_encoder_weights(_pt_section(_write_tiny_pt(tmp_path / "enc.pt", key="encoder")))


@pytest.mark.parametrize(
    "make, expected",
    [
        (lambda d: d / "missing.pt", "does not exist"),
        (lambda d: (d / "notes.pt").write_text("not a checkpoint") and d / "notes.pt", "does not load as"),
        (lambda d: torch.save([1, 2], d / "list.pt") or d / "list.pt", "is not a V-JEPA 2 .pt checkpoint"),
        (lambda d: _write_tiny_pt(d / "other.pt", key="predictor"), "has no 'target_encoder' state dict"),
        (lambda d: _write_tiny_pt(d / "deep.pt", arch={**TINY_ARCH, "depth": 2}), "does not fit encoder.arch"),
        (lambda d: _write_tiny_pt(d / "wide.pt", arch={**TINY_ARCH, "embed_dim": 32}), "of another shape"),
    ],
    ids=["missing", "not-a-checkpoint", "not-a-dict", "no-key", "wrong-depth", "wrong-width"],
)
def test_bad_pt_weights_are_refused_naming_the_key(tmp_path, make, expected):
    with pytest.raises(ValueError, match=expected) as err:
        check_encoder_weights(_pt_section(make(tmp_path)))
    assert str(err.value).startswith("encoder.weights: ") and "\n" not in str(err.value)


def test_hf_directory_checks(tmp_path):
    hf = tmp_path / "hf"
    section = {"kind": "vjepa2_hf", "weights": str(hf)}
    with pytest.raises(ValueError, match="is not a directory"):
        check_encoder_weights(section)
    hf.mkdir()
    with pytest.raises(ValueError, match="no config.json"):
        check_encoder_weights(section)
    (hf / "config.json").write_text(json.dumps({"model_type": "vit"}))
    with pytest.raises(ValueError, match="model_type 'vit', not 'vjepa2'"):
        check_encoder_weights(section)
    (hf / "config.json").write_text(json.dumps({"model_type": "vjepa2"}))
    with pytest.raises(ValueError, match="no weights file"):
        check_encoder_weights(section)
    (hf / "model.safetensors").write_bytes(b"")
    pytest.importorskip("transformers")
    check_encoder_weights(section)
    assert encoder_weight_files(section) == [str(hf / "config.json"), str(hf / "model.safetensors")]


def test_the_cpu_default_needs_no_weights():
    check_encoder_weights({"kind": "cpu", "weights": None})
    assert encoder_weight_files({"kind": "cpu", "weights": None}) == []


def _tiny_config(repo_root: Path, work: Path, encoder: dict) -> Path:
    cfg = tiny_workflow_config(repo_root / "tests/config/clips_tiny.yaml")
    update_config(cfg, {"encoder": encoder})
    path = work / "tiny.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def test_dry_run_refuses_the_shipped_placeholder_in_one_line(repo_root, tmp_path, forked_imply):
    """The cluster profile's vitg.yaml names a placeholder path: `snakemake -n` stops on it."""
    work = copy_workflow(tmp_path / "wf")
    proc = snakemake(work, "-n", "--configfile", str(repo_root / "profiles/slurm/vitg.yaml"), check=False)
    lines = [ln for ln in (proc.stdout + proc.stderr).splitlines() if "config error" in ln]
    assert proc.returncode != 0 and lines == [
        "config error: encoder.weights: /path/to/vjepa2/vitg.pt does not exist"
        " (a V-JEPA 2 .pt checkpoint; encoder.kind vjepa2_pt)"
    ], proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr


@pytest.mark.slow
def test_replacing_the_weights_reruns_the_features(repo_root, tmp_path, forked_imply):
    work = copy_workflow(tmp_path / "wf")
    weights = _write_tiny_pt(tmp_path / "vitg.pt")
    config = _tiny_config(repo_root, work, {**_pt_section(weights), "device": "cpu"})
    target = "results/features/heldout_calib.npz"
    run = snakemake(work, target, "--configfile", str(config), check=False, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    assert (work / target).is_file()
    assert "Nothing to be done" in snakemake(work, target, "-n", "--configfile", str(config)).stdout
    # other weights in place of the old ones: the features are out of date (Snakemake
    # compares checksums too, so the new file must differ, not merely be newer)
    _write_tiny_pt(weights, seed=1)
    rerun = snakemake(work, target, "-n", "--configfile", str(config)).stdout
    assert "encoder_encode" in rerun and "Nothing to be done" not in rerun
