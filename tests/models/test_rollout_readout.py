"""The model's own readout (an ablation only): fit on its rollouts of the training objects, it reads them better
than the real-token one, which is why it must never measure the model (it is shaped by what it reads)."""

from __future__ import annotations

import numpy as np
import pytest

from imply.models.config import Layout, PredictorPreset, TrainConfig
from imply.models.examples import training_objects, training_sequences
from imply.models.features import load_feature_split
from imply.models.latent_readout import fit_latent_readout, fit_rollout_readout
from imply.models.rollout import final_tokens
from imply.models.train import load_model, train_variant
from synthetic_features import synth_split

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def test_rollout_readout_reads_the_models_predictions(tmp_path):
    split = load_feature_split(*synth_split(tmp_path, "train", 60, False, 1))
    layout = Layout(calib=True, query_context=1, query_frames=(0, 1, 4, 7))
    config = TrainConfig(epochs=2, batch_size=16, rollout_steps=3, final_weight=5.0)
    real = fit_latent_readout(split)
    payload = train_variant(
        split,
        preset=PredictorPreset(width=32, depth=1, heads=2, residual=True),
        layout=layout,
        config=config,
        data_seed=0,
        out=tmp_path / "m.pt",
        checkpoint=tmp_path / "c.pt",
    )
    assert [h["epoch"] for h in payload["history"]] == [1, 2]
    model, _, _ = load_model(tmp_path / "m.pt")
    objects = training_objects(split)
    seqs = training_sequences(split, layout, objects)
    truth = np.log(split.meta["displacement"].to_numpy()[objects.query])
    own = fit_rollout_readout(model, seqs, np.exp(truth))
    tokens = final_tokens(model, seqs, batch_size=64)
    err_own = np.mean((own.predict_log(tokens) - truth) ** 2)
    err_real = np.mean((real.predict_log(tokens) - truth) ** 2)
    assert err_own < err_real
