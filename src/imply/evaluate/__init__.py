"""``imply evaluate``: point IMPLY at a world model and score its rollouts against the world.

The pieces, bottom up:

* :mod:`~imply.evaluate.suite` -- the frozen evaluation suite (a workflow target under
  ``results/suite/``): per held-out object its two calibration clips and the context
  frames of its query pushes, the fixed partner whose calibration is shown in the
  other-object condition, real training clips for the readouts, a sealed truth file and a
  manifest with checksums.
* :mod:`~imply.evaluate.interface` -- what a model is asked (:class:`RolloutRequest`) and
  what it returns (frames, latent tokens with its own ``encode``, or displacements).
* :mod:`~imply.evaluate.readouts` -- one readout per output kind, fitted on the suite's
  real clips, never on the outputs it reads.
* :mod:`~imply.evaluate.harness` -- runs a model in process (cached batches, progress) or
  reads a rollouts file (:mod:`~imply.evaluate.rollouts_file`) into readings.
* :mod:`~imply.evaluate.metrics` -- the scores, with bootstrap intervals over objects.
* :mod:`~imply.evaluate.report` -- ``results.json``, ``report.md`` and figures for one or
  several models.
"""
