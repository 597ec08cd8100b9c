"""IMPLY: physically anchored consistency scores for world-model rollouts.

The package turns displacements of pushed objects into the mass and friction they
imply (by inverting a MuJoCo table f(v, m, mu) -> log d) and scores a set of
rollouts by how well one object explains all of them, anchored to observed pushes.
"""

__version__ = "0.2.0"
