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

from __future__ import annotations

import importlib
from typing import Any

# the names a user's script needs, loaded on first use: the command line imports this
# package for its settings and must not pay for the readouts' scikit-learn or the renderer
_EXPORTS = {
    "RolloutRequest": "imply.evaluate.interface",
    "WorldModel": "imply.evaluate.interface",
    "evaluate": "imply.evaluate.harness",
    "EvaluateConfig": "imply.evaluate.config",
    "load_suite": "imply.evaluate.suite",
    "write_report": "imply.evaluate.report",
    "write_rollouts_file": "imply.evaluate.rollouts_file",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'imply.evaluate' has no attribute {name!r}")
    return getattr(importlib.import_module(_EXPORTS[name]), name)
