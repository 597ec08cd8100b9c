"""MuJoCo push simulation: the scene, batched pushes, and (later) rendering and effects."""

from imply.sim.pushes import PushResult, simulate_pushes
from imply.sim.scene import SceneConfig, build_model, build_xml

__all__ = ["PushResult", "SceneConfig", "build_model", "build_xml", "simulate_pushes"]
