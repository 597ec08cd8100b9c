"""Learned models of the Section 5 study: the frozen encoder, the action-conditioned predictor, training and rollouts."""
