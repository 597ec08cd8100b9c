"""Learned models of the Section 5 study, one concern per module.

* ``encoder`` (the frozen frame encoder, cached features), ``vision_transformer``,
  ``masked_predictor``, ``pretrain`` (the CPU encoder and its JEPA pretraining);
* ``features`` (a split's cached tokens with its clip metadata; the one token pooling),
  ``examples`` (training examples, held-out objects, the swap's derangement),
  ``sequences`` (the sequence layout, rest state included, and the predictor's inputs);
* ``ac_predictor`` (the action-conditioned predictor), ``modules`` (its attention, 3D
  RoPE and blocks, shared with the encoder), ``train`` (the loss and the training run),
  ``validation`` (per-epoch validation);
* ``rollout`` (the one rollout loop, the held-out rollout table), ``latent_readout``
  (displacement from predicted tokens), ``object_blind`` (the object-blind baseline).
"""
