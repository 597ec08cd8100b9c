"""Interrupting the workflow mid-training: nothing partial is left, and the next run resumes.

Through Snakemake, on planted synthetic features: Ctrl-C (SIGINT to the process group,
as a terminal sends it) during `imply study model train`, then a plain rerun that is killed
hard (SIGKILL, as a crash or the OOM killer would), then `--unlock` and
`--rerun-incomplete` as docs/how-to/resume.md says. Each run picks up at the last finished epoch.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch
import yaml

from synthetic_features import synth_split
from workflow_helpers import ROOT, copy_workflow, plant_table, snakemake_command

pytestmark = pytest.mark.slow

TARGET = "results/model/calib/seed0/model.pt"
EPOCHS = 12


def _plant(work: Path, tiny_table_path: Path) -> None:
    """The training run's upstream outputs, oldest first, so nothing upstream reruns."""
    plant_table(work, tiny_table_path)
    clips, feats, enc = work / "results/clips", work / "results/features", work / "results/encoder"
    for d in (clips, feats, enc):
        d.mkdir()
    # enough objects that an epoch outlasts the poll and the signal (a tiny model trains fast)
    _, csv = synth_split(feats, "train", 240, False, seed=3)
    shutil.move(csv, clips / "train.csv")
    # the held-out splits (the latent readout's report covers them) and the validation split
    for split, n in (("heldout_calib", 8), ("heldout_nocalib", 8), ("validation", 8)):
        _, csv = synth_split(feats, split, n, True, seed=len(split))
        shutil.move(csv, clips / f"{split}.csv")
    for name in ("train.npz", "heldout_calib.npz", "heldout_nocalib.npz", "validation.npz", "pretrain.npz"):
        (clips / name).write_bytes(b"planted")
    (clips / "pretrain.csv").write_text("planted\n")
    (enc / "encoder.pt").write_bytes(b"planted")
    now = time.time()
    order = [work / "results/table/table.npz", *sorted(clips.iterdir()), enc / "encoder.pt", *feats.iterdir()]
    for i, path in enumerate(order):
        os.utime(path, (now - 1000 + i, now - 1000 + i))


def _command(work: Path, *extra: str, signalled: bool = True) -> list[str]:
    # options that take several values go last, with "--" before the target; a run the test signals is a Snakemake
    # process of its own (not the fork server's), whose process group gets the signal as from a terminal
    return [
        *([sys.executable, "-m", "snakemake"] if signalled else snakemake_command()),
        "--cores",
        "1",
        "--directory",
        str(work),
        "--snakefile",
        str(work / "Snakefile"),
        *extra,
        "--configfile",
        str(work / "config.yaml"),
        str(work / "small.yaml"),
        "--rerun-triggers",
        "mtime",
        "--",
        TARGET,
    ]


def _epoch(checkpoint: Path) -> int:
    try:
        return int(torch.load(checkpoint, map_location="cpu", weights_only=False)["epoch"])
    except (OSError, EOFError, RuntimeError, KeyError):
        return 0  # not there yet


def _default_sigint() -> None:
    # a shell starts background jobs with SIGINT ignored, and exec keeps it ignored; a
    # terminal's Ctrl-C reaches a foreground run, so give the run the default handling
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _run_until(work: Path, checkpoint: Path, past_epoch: int, sig: int, log: Path) -> int:
    """Start the workflow in its own process group; signal the group once the checkpoint passes an epoch."""
    with open(log, "w") as out:
        proc = subprocess.Popen(
            _command(work), stdout=out, stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=_default_sigint
        )
        deadline = time.monotonic() + 240
        try:
            while _epoch(checkpoint) <= past_epoch:
                assert proc.poll() is None, f"the run ended before it could be interrupted:\n{log.read_text()[-3000:]}"
                assert time.monotonic() < deadline, "training made no progress"
                time.sleep(0.05)
            os.killpg(proc.pid, sig)
            return proc.wait(timeout=120)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()


def _leftovers(folder: Path) -> list[str]:
    """Temporary files of atomic writes (".name.XXXX.suffix") left in a results folder."""
    return [p.name for p in folder.iterdir() if p.name.startswith(".")]


def test_interrupted_training_resumes_through_snakemake(tmp_path, tiny_table_path, forked_imply):
    """The training job through the fork server's client (tests/forkserver.py), which forwards SIGINT to its fork and,
    killed hard, takes the fork with it: what the signals do to a job of its own."""
    work = copy_workflow(tmp_path / "wf")
    small = yaml.safe_load((ROOT / "tests/config/model_small.yaml").read_text())
    small["model"]["train"]["epochs"] = EPOCHS
    (work / "small.yaml").write_text(yaml.safe_dump(small))
    _plant(work, tiny_table_path)
    model_dir = work / "results/model/calib/seed0"
    checkpoint = model_dir / "checkpoint.pt"
    train_log = work / "results/logs/model_train_calib_seed0.log"

    # Ctrl-C after the first epoch: no model, no temporary file, the checkpoint kept
    code = _run_until(work, checkpoint, 0, signal.SIGINT, tmp_path / "run1.log")
    assert code != 0
    first = _epoch(checkpoint)
    assert 1 <= first < EPOCHS
    assert not (work / TARGET).exists()
    assert _leftovers(model_dir) == []

    # a plain rerun resumes; killed hard a few epochs later
    _run_until(work, checkpoint, first + 1, signal.SIGKILL, tmp_path / "run2.log")
    assert f"after epoch {first}" in train_log.read_text()
    second = _epoch(checkpoint)
    assert first < second < EPOCHS, (first, second)
    assert not (work / TARGET).exists()

    # after a hard kill: unlock, then rerun (marking incomplete outputs for rerun)
    subprocess.run(_command(work, "--unlock", signalled=False), check=True, capture_output=True)
    done = subprocess.run(
        _command(work, "--rerun-incomplete", signalled=False), capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert f"after epoch {second}" in train_log.read_text()
    payload = torch.load(work / TARGET, map_location="cpu", weights_only=False)
    assert [h["epoch"] for h in payload["history"]] == list(range(1, EPOCHS + 1))
