"""Stage 3 of the diagnostic, the inference: fits, noise, where the gap lies, and how strongly the pushes prefer each
explanation.

In: a push log against the table (:class:`~imply.diagnose.inference.fit.Problem`, built from stage 1 and read
through stage 2's predictions). Out: the noise and outliers (:mod:`~imply.diagnose.inference.noise`), the model's
own error, the baseline's residual bands (:mod:`~imply.diagnose.inference.localisation`), what the pushes can tell
apart (:mod:`~imply.diagnose.inference.aliasing`), every hypothesis fitted and weighed by its evidence
(:mod:`~imply.diagnose.inference.hypotheses`, :mod:`~imply.diagnose.inference.screening`), the estimates, the
discrepancy described, how far the gap shrinks held out (:mod:`~imply.diagnose.inference.shrinkage`), and a log
with a reference session's standing gap taken out (:mod:`~imply.diagnose.inference.sessions`). Numbers, no words.
"""
