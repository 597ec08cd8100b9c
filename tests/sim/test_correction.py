"""The stated causes written into a push scene (imply.sim.correction): each with MuJoCo's own mechanism, checked
against a second code path where one exists (a servo gain against a faster command, a tilt against its mirror)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from imply.sim.correction import ANISOTROPY, CAUSES, cause_parameters, corrected_spec, friction_factor
from imply.sim.pushes import simulate_pushes
from imply.sim.scene import COMMAND_OFFSET, SceneConfig, build_xml

XML = build_xml(SceneConfig())


def corrected(values: dict, direction: float = 0.0, xml: str = XML) -> mujoco.MjModel:
    return corrected_spec(xml, cause_parameters(values, direction=direction)).compile()


def test_each_cause_lands_in_its_mujoco_field():
    plain = corrected({})
    box = plain.geom("box").id
    dof = plain.jnt_dofadr[plain.body("box").jntadr[0]]
    assert corrected({"viscous": 0.4}).dof_damping[dof] == pytest.approx(0.4)
    assert corrected({"air_drag": 150.0}).opt.density == pytest.approx(150.0)
    assert corrected({"torsional": 0.02}).geom_condim[box] == 4
    assert corrected({"rolling": 0.01}).geom_friction[box, 2] == pytest.approx(0.01)
    assert corrected({"table_timeconst": 0.8}).geom_solref[box, 0] == pytest.approx(
        plain.geom_solref[box, 0] * np.exp(0.8)
    )
    assert corrected({"pusher_softness": 0.03}).geom_solref[plain.geom("pusher").id, 0] == pytest.approx(
        plain.geom_solref[plain.geom("pusher").id, 0] + 0.03
    )
    servo = plain.actuator("servo").id
    assert corrected({"speed_gain": 0.1}).actuator_gainprm[servo, 0] == pytest.approx(
        plain.actuator_gainprm[servo, 0] * 1.1
    )
    assert corrected({"speed_offset": -0.03}).numeric(COMMAND_OFFSET).data[0] == pytest.approx(-0.03)
    assert list(corrected({"anisotropic": (0.1, -0.05)}).numeric(ANISOTROPY).data) == pytest.approx([0.1, -0.05])
    g = corrected({"tilt": (0.0, 0.02)}).opt.gravity  # downhill toward the table's +y
    assert g[0] == pytest.approx(0.0, abs=1e-12) and g[1] == pytest.approx(9.81 * np.sin(0.02))
    assert np.linalg.norm(g) == pytest.approx(9.81)
    # a push toward +y sees that slope along itself
    g = corrected({"tilt": (0.0, 0.02)}, direction=np.pi / 2).opt.gravity
    assert g[0] == pytest.approx(9.81 * np.sin(0.02)) and g[1] == pytest.approx(0.0, abs=1e-12)


def test_a_servo_gain_and_a_command_offset_run_as_a_faster_command():
    """Two code paths: the servo's gain (gainprm) and the command mapping against the plain scene told v (1 + g) + c.
    (Speeds away from slow_push_speed: the simulator halves the step of pushes commanded below it, and the two
    paths command different speeds.)"""
    speeds = np.array([0.5, 0.7])
    plain = mujoco.MjModel.from_xml_string(XML)
    faster = simulate_pushes(speeds * 1.1 + 0.02, 0.5, 0.3, model=plain, nthread=1).displacement
    both = simulate_pushes(speeds, 0.5, 0.3, model=corrected({"speed_gain": 0.1, "speed_offset": 0.02}), nthread=1)
    np.testing.assert_allclose(both.displacement, faster, rtol=1e-9)


def test_a_tilt_downhill_against_the_push_is_the_mirror_slope():
    speeds = np.array([0.4])
    back = simulate_pushes(speeds, 0.5, 0.3, model=corrected({"tilt": (0.015, 0.0)}, direction=np.pi), nthread=1)
    mirror = simulate_pushes(speeds, 0.5, 0.3, model=corrected({"tilt": (-0.015, 0.0)}), nthread=1)
    np.testing.assert_allclose(back.displacement, mirror.displacement, rtol=1e-6)
    assert back.displacement[0] < simulate_pushes(speeds, 0.5, 0.3, model=corrected({}), nthread=1).displacement[0]


def test_a_user_scene_keeps_its_names_and_loads_from_file(tmp_path):
    """A user's free joint has its own name and the scene an extra body: both survive, and the file loads plainly."""
    xml = XML.replace('<freejoint name="box"/>', '<freejoint name="crate_free"/>').replace(
        "<worldbody>",
        '<worldbody>\n    <body name="lamp" pos="0 1 1"><geom name="bulb" type="sphere" size="0.05"/></body>',
    )
    spec = corrected_spec(xml, cause_parameters({"viscous": 0.3, "tilt": (0.01, 0.0)}))
    path = tmp_path / "corrected.xml"
    path.write_text(spec.to_xml())
    model = mujoco.MjModel.from_xml_path(str(path))
    for kind, name in (("joint", "crate_free"), ("body", "lamp"), ("geom", "bulb"), ("actuator", "servo")):
        getattr(model, kind)(name)
    assert model.dof_damping[model.joint("crate_free").dofadr[0]] == pytest.approx(0.3)


def test_unknown_or_misshapen_causes_are_refused():
    with pytest.raises(ValueError, match="no MJCF edit for causes"):
        cause_parameters({"wobble": 1.0})
    with pytest.raises(ValueError, match="tilt takes 2 numbers"):
        cause_parameters({"tilt": 0.01})
    assert set(CAUSES) >= {"tilt", "viscous", "speed_gain", "anisotropic"}


def test_the_anisotropy_is_each_push_s_friction_factor():
    np.testing.assert_allclose(friction_factor({"anisotropic": (0.2, 0.0)}, [0.0, np.pi / 2]), [1.2, 0.8])
    np.testing.assert_allclose(friction_factor({}, [0.3]), [1.0])
