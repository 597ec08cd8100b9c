"""The push on a rigid contact, in closed form: what an engine without soft contacts or margins should give."""

from __future__ import annotations


def rigid_push(u: float, m: float, mu: float, scene, g: float = 9.81) -> float:
    """Travel of a box pushed by a rigid pusher over the stroke (servo law, fine Euler), then sliding to rest."""
    x = v = 0.0
    h = 1e-6
    while x < scene.stroke:
        v += h * (scene.pusher_kv * (u - v) - mu * m * g) / (m + scene.pusher_mass)
        x += h * v
    return scene.stroke + v * v / (2 * mu * g)
