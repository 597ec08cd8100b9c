"""Training the predictor: the rollout term, a falling loss, resuming from a checkpoint; the swap's derangement."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from test_ac_predictor import TINY, tiny_model

from imply.models.config import Layout, PredictorConfig, TrainConfig
from imply.models.examples import training_sequences
from imply.models.features import load_feature_split
from imply.models.train import load_model, losses, train
from imply.stats import derangement
from synthetic_features import synth_split

# tiny tensors: extra torch threads only contend with the rest of the suite
pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    d = tmp_path_factory.mktemp("synth")
    return {"train": synth_split(d, "train", 48, False, 1)}


def test_training_loss_falls(synth):
    split = load_feature_split(*synth["train"])
    layout = Layout(calib=True, query_context=2, query_frames=None)
    seqs = training_sequences(split, layout)
    assert len(seqs) == 48 and seqs.n_steps == 14 and seqs.n_context == 8
    cfg = TrainConfig(
        epochs=1, batch_size=48, lr=3e-3, start_lr=3e-3, warmup=0.0, anneal=0.0, rollout_steps=2, final_weight=1.0
    )
    model = tiny_model()
    opt = torch.optim.AdamW(model.parameters(), lr=3e-3)
    batch = seqs.batch(np.arange(48))
    weights = torch.as_tensor(
        layout.teacher_forcing_weights(final_weight=1.0, calib_targets=False), dtype=torch.float32
    )
    first = None
    for _ in range(25):
        tf, ar = losses(model, *batch, n_context=seqs.n_context, tf_weights=weights, cfg=cfg)
        loss = tf + ar
        first = first if first is not None else loss.item()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.7 * first


def test_resumed_run_matches_uninterrupted(synth, tmp_path):
    split = load_feature_split(*synth["train"])
    layout = Layout(calib=False, query_context=2, query_frames=None)
    seqs = training_sequences(split, layout)
    run = {
        "layout": layout,
        "predictor": PredictorConfig(embed_dim=8, grid=(2, 2), max_steps=8, **TINY),
        "config": TrainConfig(
            epochs=3,
            batch_size=16,
            lr=5e-4,
            start_lr=5e-5,
            final_lr=0.0,
            warmup=0.1,
            rollout_steps=2,
            final_weight=1.0,
        ),
    }
    full = train(seqs, **run, data_seed=7, out=tmp_path / "a.pt", checkpoint=tmp_path / "a.ckpt")
    stopped = train(seqs, **run, data_seed=7, out=tmp_path / "b.pt", checkpoint=tmp_path / "b.ckpt", stop_after_epoch=1)
    assert stopped is None and not (tmp_path / "b.pt").exists()
    assert torch.load(tmp_path / "b.ckpt", weights_only=True)["epoch"] == 1  # tensors and plain types only
    resumed = train(seqs, **run, data_seed=7, out=tmp_path / "b.pt", checkpoint=tmp_path / "b.ckpt")
    assert [h["epoch"] for h in resumed["history"]] == [1, 2, 3]
    for k, v in full["model"].items():
        assert torch.equal(v, resumed["model"][k]), k
    assert full["history"] == resumed["history"]
    # another data-order seed gives other weights
    other = train(seqs, **run, data_seed=8, out=tmp_path / "c.pt", checkpoint=tmp_path / "c.ckpt")
    assert not torch.equal(other["model"]["out.weight"], full["model"]["out.weight"])
    model, loaded_layout, payload = load_model(tmp_path / "a.pt")
    assert loaded_layout == layout and payload["history"] == full["history"]


def test_each_variant_trains_its_own_epochs():
    """context_free_epochs replaces epochs for a layout without calibration only, and the recipe a model records
    is the one it ran (no unused field)."""
    cfg = TrainConfig(epochs=40, context_free_epochs=15)
    blind, calibrated = Layout(calib=False), Layout(calib=True)
    assert cfg.for_layout(blind).epochs == 15 and cfg.for_layout(calibrated).epochs == 40
    assert cfg.for_layout(blind).context_free_epochs is None is cfg.for_layout(calibrated).context_free_epochs
    assert TrainConfig(epochs=40, context_free_epochs=None).for_layout(blind).epochs == 40
    # the calibrated recipe is the one it always was
    assert cfg.for_layout(calibrated) == TrainConfig(epochs=40, context_free_epochs=None)
    with pytest.raises(ValueError, match="context_free_epochs"):
        TrainConfig.from_dict({"context_free_epochs": 0})


class _RunsCode:
    """What a shared checkpoint could hold: an object whose unpickling calls a function."""

    def __reduce__(self):
        return (print, ("this ran while the file was read",))


def test_a_model_file_whose_pickle_would_run_code_is_refused(tmp_path, capsys):
    torch.save({"predictor": {}, "model": {}, "payload": _RunsCode()}, tmp_path / "shared.pt")
    with pytest.raises(ValueError, match=r"shared.pt: not a plain model file") as err:
        load_model(tmp_path / "shared.pt")
    assert "\n" not in str(err.value)
    assert "this ran" not in capsys.readouterr().out


def test_derangement_has_no_fixed_point():
    p = derangement(50, 3)
    assert sorted(p) == list(range(50)) and np.all(p != np.arange(50))
    assert np.array_equal(p, derangement(50, 3))


def test_teacher_forcing_targets_stay_within_a_clip_and_weigh_the_rest_frame():
    layout = Layout(calib=True, calib_frames=(0, 7), query_context=1, query_frames=(0, 4, 7))
    # steps: calib 1 (0, 7), calib 2 (0, 7), query (0, 4, 7); weights are of targets 1 .. 6
    query_only = layout.teacher_forcing_weights(final_weight=10.0, calib_targets=False)
    assert query_only.tolist() == [0, 0, 0, 0, 1, 10]
    with_calib = layout.teacher_forcing_weights(final_weight=10.0, calib_targets=True)
    assert with_calib.tolist() == [10, 0, 10, 0, 1, 10]
    blind = Layout(calib=False, query_context=1, query_frames=(0, 1, 4, 7))
    assert blind.teacher_forcing_weights(final_weight=3.0, calib_targets=True).tolist() == [1, 1, 3]


def test_with_one_rest_frame_per_calibration_push_the_second_is_predicted_from_the_first():
    layout = Layout(calib=True, calib_frames=(7,), query_context=1, query_frames=(0, 4, 7))
    # steps: calib 1 rest, calib 2 rest, query 0, 4, 7
    assert layout.teacher_forcing_weights(final_weight=10.0, calib_targets=True).tolist() == [10, 0, 1, 10]
    assert layout.teacher_forcing_weights(final_weight=10.0, calib_targets=False).tolist() == [0, 0, 1, 10]
