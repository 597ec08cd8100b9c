"""Stage 4 of the diagnostic, the conclusion: the verdict as data, in words, and the next experiments.

In: the weighed hypotheses and the estimates of stage 3. Out: adequacy, identification, the causes stated and how
firmly (:mod:`~imply.diagnose.conclusion.verdict`), the verdict in words (:mod:`~imply.diagnose.conclusion.render`),
and the pushes or probe that would best tell the remaining contenders apart
(:mod:`~imply.diagnose.conclusion.next_pushes`, :mod:`~imply.diagnose.conclusion.next_probes`).
"""
