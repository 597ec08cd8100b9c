"""The Section 5 predictor: mask, rotary embeddings, training, resume, rollouts and scoring.

Everything runs on synthetic splits in issue 5's formats (clips CSV + features npz),
where the box position at each frame is encoded in the tokens by a fixed random map,
so the tests need neither rendering nor the encoder.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from imply.models.ac_predictor import (
    ACPredictor,
    PredictorConfig,
    Rope3D,
    block_causal_mask,
    rollout,
    rollout_cached,
    token_positions,
)
from imply.models.rollout import derangement, load_split, training_sequences
from imply.models.sequences import Layout
from imply.models.train import TrainConfig, losses, train

PROFILE = np.array([0.0, 0.15, 0.3, 0.5, 0.65, 0.8, 0.95, 1.0])
TIMES = [0.0, 0.03, 0.06, 0.1, 0.15, 0.25, 0.4]


def synth_split(path: Path, name: str, n_objects: int, heldout: bool, seed: int, grid=(2, 2), dim=8):
    """Write <path>/<name>.csv and <name>.npz like issue 5's clips and features."""
    rng = np.random.default_rng(seed)
    mass = np.exp(rng.uniform(np.log(0.2), np.log(2.0), n_objects))
    fric = np.exp(rng.uniform(np.log(0.1), np.log(0.6), n_objects))
    rows = []
    for i in range(n_objects):
        pushes = [("calibration_0", -1, 0.3), ("calibration_1", -1, 0.8)]
        if heldout:
            pushes += [("query", k, v) for k, v in enumerate([0.25, 0.4, 0.55, 0.7, 0.85])]
        else:
            pushes.append(("query", -1, float(rng.uniform(0.15, 1.05))))
        for role, k, v in pushes:
            d = np.exp(2 * np.log(v) - np.log(fric[i]) - 0.5 * np.log(mass[i]) * v - 3.0)
            row = {"object_id": f"{name}-{i:05d}", "episode": i, "role": role, "speed_index": k, "speed": v,
                   "displacement": d, "stop_time": 0.5 + d, "ok": 1, "mass": mass[i], "friction": fric[i]}  # fmt: skip
            row.update({f"t{j}": t for j, t in enumerate(TIMES)})
            row["t7"] = 0.5 + d
            rows.append(row)
    meta = pd.DataFrame(rows)
    meta.insert(0, "clip_id", np.arange(len(meta)))
    p = grid[0] * grid[1]
    w = np.random.default_rng(99).normal(size=(p, dim))
    pos = meta["displacement"].to_numpy()[:, None] * PROFILE[None, :] * 10.0  # (n, 8)
    tokens = np.sin(pos[:, :, None, None] * w[None, None] + np.arange(dim)[None, None, None, :] * 0.3)
    tokens += 0.01 * rng.normal(size=tokens.shape)
    meta.to_csv(path / f"{name}.csv", index=False)
    np.savez(path / f"{name}.npz", tokens=tokens.astype(np.float16), clip_id=meta["clip_id"].to_numpy(),
             grid=np.array(grid))  # fmt: skip
    return path / f"{name}.npz", path / f"{name}.csv"


TINY = {"width": 32, "depth": 2, "heads": 2}


@pytest.fixture(autouse=True)
def one_thread():
    # tiny tensors: extra threads only contend with the rest of the suite
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def tiny_model(grid=(2, 2), dim=8, steps=14) -> ACPredictor:
    torch.manual_seed(0)
    return ACPredictor(PredictorConfig(embed_dim=dim, grid=grid, max_steps=steps, **TINY))


def test_mask_is_block_causal():
    m = block_causal_mask(3, 4)
    step = np.arange(12) // 4
    assert np.array_equal(m.numpy(), step[None, :] <= step[:, None])
    # functional: a change at step 2 leaves outputs at steps 0-1 unchanged; a change at step 0 reaches step 2
    model = tiny_model().eval()
    x, a, s = torch.randn(1, 4, 4, 8), torch.randn(1, 4, 1), torch.randn(1, 4, 1)
    y = model(x, a, s)
    x2 = x.clone()
    x2[:, 2] += 1.0
    a2 = a.clone()
    a2[:, 3] += 1.0
    y2 = model(x2, a2, s)
    assert torch.allclose(y[:, :2], y2[:, :2], atol=1e-6)
    assert not torch.allclose(y[:, 2:], y2[:, 2:], atol=1e-4)
    x3 = x.clone()
    x3[:, 0] += 1.0
    assert not torch.allclose(model(x3, a, s)[:, 2], y[:, 2], atol=1e-4)


def test_rope_rotates_action_and_state_in_time_only():
    rope = Rope3D(head_dim=12)
    pos, spatial = token_positions(2, (2, 3))
    tps = 2 + 6
    assert not spatial[0] and not spatial[1] and spatial[2:tps].all()
    cos, sin = rope.angles(pos, spatial)
    x = torch.randn(1, 1, pos.shape[0], 12)
    y = rope.rotate(x, cos, sin)
    part = rope.part
    # action/state tokens: height and width channels untouched, time channels rotated at step 1
    for i in (tps, tps + 1):
        assert torch.allclose(y[0, 0, i, part:], x[0, 0, i, part:])
        assert not torch.allclose(y[0, 0, i, :part], x[0, 0, i, :part])
    # a patch token off the origin has its spatial channels rotated
    last = 2 * tps - 1
    assert not torch.allclose(y[0, 0, last, part : 3 * part], x[0, 0, last, part : 3 * part])
    # rotation preserves norms
    assert torch.allclose(y.norm(dim=-1), x.norm(dim=-1), atol=1e-5)


def test_rollout_keeps_context_and_matches_teacher_forcing_first_step():
    model = tiny_model().eval()
    x, a, s = torch.randn(2, 6, 4, 8), torch.randn(2, 6, 1), torch.randn(2, 6, 1)
    with torch.no_grad():
        r = rollout(model, x, a, s, 3)
        tf = model(x, a, s)
    assert torch.equal(r[:, :3], x[:, :3])
    assert torch.allclose(r[:, 3], tf[:, 2], atol=1e-5)
    # the key/value-cached inference rollout gives the same frames
    assert torch.allclose(rollout_cached(model, x, a, s, 3), r, atol=1e-5)
    assert torch.allclose(rollout_cached(model, x, a, s, 1), rollout(model, x, a, s, 1), atol=1e-5)


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    d = tmp_path_factory.mktemp("synth")
    return {
        "train": synth_split(d, "train", 48, False, 1),
        "heldout_calib": synth_split(d, "heldout_calib", 12, True, 2),
        "heldout_nocalib": synth_split(d, "heldout_nocalib", 14, True, 3),
        "dir": d,
    }


def test_training_rollout_term_matches_explicit_rollout():
    model = tiny_model().eval()
    x, a, s = torch.randn(2, 14, 4, 8), torch.randn(2, 14, 1), torch.randn(2, 14, 1)
    cfg = TrainConfig(rollout_steps=4)
    tf, ar = losses(model, x, a, s, 8, 6, cfg)
    r = rollout(model, x, a, s, 8)
    assert torch.allclose(ar, (r[:, 8:12] - x[:, 8:12]).abs().mean(), atol=1e-5)
    assert torch.allclose(tf, (model(x, a, s)[:, 6:-1] - x[:, 7:]).abs().mean(), atol=1e-6)


def test_training_loss_falls(synth):
    split = load_split(*synth["train"])
    layout = Layout(calib=True)
    seqs = training_sequences(split, layout, 1.0)
    assert len(seqs) == 48 and seqs.n_steps == 14 and seqs.n_context == 8
    cfg = TrainConfig(epochs=1, batch_size=48, lr=3e-3, start_lr=3e-3, warmup=0.0, anneal=0.0, rollout_steps=2)
    model = tiny_model()
    opt = torch.optim.AdamW(model.parameters(), lr=3e-3)
    batch = seqs.batch(np.arange(48))
    first = None
    for _ in range(25):
        tf, ar = losses(model, *batch, seqs.n_context, layout.n_calib_steps, cfg)
        loss = tf + ar
        first = first if first is not None else loss.item()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.7 * first


def test_resumed_run_matches_uninterrupted(synth, tmp_path):
    split = load_split(*synth["train"])
    layout = Layout(calib=False)
    seqs = training_sequences(split, layout, 1.0)
    pcfg = PredictorConfig(embed_dim=8, grid=(2, 2), max_steps=8, **TINY)
    cfg = TrainConfig(epochs=3, batch_size=16, rollout_steps=2)
    full = train(seqs, layout, pcfg, cfg, 7, tmp_path / "a.pt", tmp_path / "a.ckpt")
    assert train(seqs, layout, pcfg, cfg, 7, tmp_path / "b.pt", tmp_path / "b.ckpt", stop_after_epoch=1) == {}
    assert not (tmp_path / "b.pt").exists()
    assert torch.load(tmp_path / "b.ckpt", weights_only=False)["epoch"] == 1
    resumed = train(seqs, layout, pcfg, cfg, 7, tmp_path / "b.pt", tmp_path / "b.ckpt")
    assert [h["epoch"] for h in resumed["history"]] == [1, 2, 3]
    for k, v in full["model"].items():
        assert torch.equal(v, resumed["model"][k]), k
    assert full["history"] == resumed["history"]
    # another data-order seed gives other weights
    other = train(seqs, layout, pcfg, cfg, 8, tmp_path / "c.pt", tmp_path / "c.ckpt")
    assert not torch.equal(other["model"]["out.weight"], full["model"]["out.weight"])


def test_derangement_has_no_fixed_point():
    p = derangement(50, 3)
    assert sorted(p) == list(range(50)) and np.all(p != np.arange(50))
    assert np.array_equal(p, derangement(50, 3))


def test_cli_train_rollout_section5(synth, tmp_path, tiny_table_path):
    from imply.cli import main

    d = synth["dir"]
    model_cfg = {
        "preset": "tiny",
        "presets": {"tiny": TINY},
        "variants": {"calib": {"calib": True}, "nocalib": {"calib": False}},
        "train": {"epochs": 2, "batch_size": 16, "rollout_steps": 2},
        "rest_state": 1.0,
    }
    mj = json.dumps(model_cfg)
    assert main(["model", "readout", "--features", str(d / "train.npz"), "--clips", str(d / "train.csv"),
                 "--heldout", str(d / "heldout_calib.npz"), str(d / "heldout_calib.csv"),
                 "-o", str(tmp_path / "readout.npz")]) == 0  # fmt: skip
    r2 = json.loads((tmp_path / "readout.json").read_text())["heldout_r2_log"]["heldout_calib"]
    assert r2 > 0.8
    specs = []
    for variant, split, ctx in (("calib", "heldout_calib", "own,swap,none"), ("nocalib", "heldout_nocalib", "none")):
        for seed in (0, 1):
            out = tmp_path / variant / f"seed{seed}"
            assert main(["model", "train", "--features", str(d / "train.npz"), "--clips", str(d / "train.csv"),
                         "--model-json", mj, "--variant", variant, "--seed", str(seed), "--threads", "1",
                         "-o", str(out / "model.pt")]) == 0  # fmt: skip
            assert (out / "checkpoint.pt").exists()
            assert main(["model", "rollout", "--model", str(out / "model.pt"), "--features", str(d / f"{split}.npz"),
                         "--clips", str(d / f"{split}.csv"), "--readout", str(tmp_path / "readout.npz"),
                         "--contexts", ctx, "--derangement-seed", "4", "--threads", "1",
                         "-o", str(out / "rollouts.csv")]) == 0  # fmt: skip
            specs += ["--rollouts", f"{variant}:{seed}:{out / 'rollouts.csv'}"]
    ro = pd.read_csv(tmp_path / "calib" / "seed0" / "rollouts.csv")
    assert set(ro["context"]) == {"own", "swap", "none"}
    assert len(ro[(ro.role == "rollout") & (ro.context == "own")]) == 12 * 5
    sw = ro[ro.context == "swap"]
    assert (sw["context_object"] != sw["object_id"]).all()
    score = {"grid": 21, "readout_floor": 1e-4, "query_speeds": [0.25, 0.4, 0.55, 0.7, 0.85],
             "calibration_speeds": [0.3, 0.8]}  # fmt: skip
    paper = tmp_path / "paper"
    args = ["section5", *specs, "--table", str(tiny_table_path), "--score-json", json.dumps(score),
            "--selection-seed", "1", "--out-dir", str(tmp_path / "s5"), "--part", str(paper / "parts/section5.json"),
            "--table-tex", str(paper / "tables/table3.tex"), "--figure", str(paper / "figures/figure2")]  # fmt: skip
    assert main(args) == 0
    part = json.loads((paper / "parts/section5.json").read_text())
    for name in ("vjNOne", "vjNTwo", "vjQTrack", "vjCAnch", "vjSelAnchOwn", "vjSOneSCorrAnch", "vjSelfOwnLtSwap"):
        assert name in part["numbers"]
    assert part["numbers"]["vjNOne"]["value"] == 14 and part["numbers"]["vjNTwo"]["value"] == 12
    assert {c["id"] for c in part["claims"]} >= {"s5-self-chance", "s5-anchored-prefers-own", "s5-second-seed"}
    assert all(isinstance(c["holds"], bool) for c in part["claims"])
    tex = (paper / "tables/table3.tex").read_text()
    assert r"\toprule" in tex and tex.count(r"\\") >= 7
    assert (paper / "figures/figure2.pdf").stat().st_size > 1000 and (paper / "figures/figure2.png").exists()
    first = (paper / "parts/section5.json").read_bytes()
    assert main(args) == 0
    assert (paper / "parts/section5.json").read_bytes() == first


def test_cli_rejects_bad_options(synth, tmp_path, capsys):
    from imply.cli import main

    d = synth["dir"]
    mj = json.dumps({"preset": "huge", "presets": {"tiny": TINY}, "variants": {"calib": {"calib": True}}})
    rc = main(["model", "train", "--features", str(d / "train.npz"), "--clips", str(d / "train.csv"),
               "--model-json", mj, "--variant", "calib", "--seed", "0", "-o", str(tmp_path / "m.pt")])  # fmt: skip
    assert rc == 2 and "preset" in capsys.readouterr().err
    assert not (tmp_path / "m.pt").exists()
