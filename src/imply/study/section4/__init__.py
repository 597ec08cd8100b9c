"""The controlled validation (paper Section 4): stand-in world models whose failures are known.

Steps and their files (all under ``results/section4/``; config section ``section4``,
:mod:`~imply.study.section4.config`):

1. :mod:`~imply.study.section4.objects`: ``objects.csv`` (evaluation and training
   objects) and ``truth.csv`` (their true pushes);
2. :mod:`~imply.study.section4.standins`: ``rollouts.csv``, the four stand-ins' rollouts;
3. :mod:`~imply.study.section4.scoring`: ``scores.csv``, ``metrics.json`` (Table 1) and
   ``noise.json`` (Table 2, top);
4. :mod:`~imply.study.section4.selection`: ``selection.json`` (Table 2, bottom);
5. :mod:`~imply.study.section4.claims`: the paper's claims, checked on the numbers.

Seeds: ``section4.seed`` with a fixed stream per step (objects 1, jitter 2, noise 3,
selection 4), so changing one step's settings leaves the others' draws alone.
"""
