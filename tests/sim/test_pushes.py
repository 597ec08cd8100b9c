"""The push scene and the batched simulator."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from imply.sim import SceneConfig, build_model, build_xml, simulate_pushes


def test_push_is_finite_settled_and_grows_with_speed(scene):
    speeds = np.linspace(0.15, 1.05, 7)
    res = simulate_pushes(speeds, 0.6, 0.3, scene=scene, nthread=1)
    assert res.ok.all()
    assert np.all(np.diff(res.displacement) > 0)
    assert np.all(res.tilt < 0.01)
    assert np.all(np.abs(res.lateral) < 1e-6)


def test_mass_and_friction_act_differently_across_speeds(scene):
    """The pitfall of a free elastic strike: log d = 2 log v + c(m, mu). Not here."""
    speeds = np.array([0.25, 0.85])
    light_rough = np.log(simulate_pushes(speeds, 0.3, 0.4, scene=scene).displacement)
    heavy_smooth = np.log(simulate_pushes(speeds, 1.6, 0.2, scene=scene).displacement)
    # if mass and friction entered as one constant, these speed slopes would match
    slope_a = light_rough[1] - light_rough[0]
    slope_b = heavy_smooth[1] - heavy_smooth[0]
    assert abs(slope_a - slope_b) > 0.1


def test_batch_mass_change_matches_a_model_compiled_with_that_mass(scene):
    """Per-simulation mass keeps the inertia of a uniform box (scaled with mass)."""
    mass, mu, v = 1.3, 0.25, 0.6
    batched = simulate_pushes([v], mass, mu, scene=scene).displacement[0]
    compiled = simulate_pushes([v], scene=scene, model=build_model(scene, mass=mass, friction=mu)).displacement[0]
    assert batched == pytest.approx(compiled, rel=1e-9, abs=1e-12)


def test_per_push_geometry_matches_shared_geometry(scene):
    he = (0.05, 0.05, 0.03)
    shared = simulate_pushes([0.4, 0.7], [0.5, 0.9], [0.2, 0.4], scene=scene).displacement
    per_push = simulate_pushes([0.4, 0.7], [0.5, 0.9], [0.2, 0.4], half_extents=[he, he], scene=scene).displacement
    np.testing.assert_allclose(per_push, shared, rtol=1e-9)
    # Coulomb friction does not depend on contact area: a wider box of the same mass
    # slides the same distance when pushed straight through its centre
    wide = simulate_pushes([0.4], [0.5], [0.2], half_extents=[(0.05, 0.07, 0.03)], scene=scene)
    assert wide.ok.all()
    assert wide.displacement[0] == pytest.approx(shared[0], rel=1e-3)


def test_user_mjcf_round_trip(scene, tmp_path):
    xml = build_xml(scene, mass=0.8, friction=0.35)
    path = tmp_path / "scene.xml"
    path.write_text(xml)
    model = mujoco.MjModel.from_xml_path(str(path))
    from_file = simulate_pushes([0.5], model=model).displacement[0]
    builtin = simulate_pushes([0.5], 0.8, 0.35, scene=scene).displacement[0]
    assert from_file == pytest.approx(builtin, rel=1e-9)


def test_user_mjcf_with_edited_physics_changes_the_push(scene):
    tilted = SceneConfig.from_dict({**scene.to_dict(), "option": {"gravity": "0.3 0 -9.81"}})
    flat = simulate_pushes([0.5], 0.5, 0.3, scene=scene).displacement[0]
    downhill = simulate_pushes([0.5], 0.5, 0.3, scene=tilted).displacement[0]
    assert downhill > flat * 1.05


def test_bad_inputs_are_refused(scene):
    with pytest.raises(ValueError, match="speeds"):
        simulate_pushes([0.0, 0.5], scene=scene)
    with pytest.raises(ValueError, match="masses"):
        simulate_pushes([0.5], -1.0, scene=scene)
    with pytest.raises(ValueError, match="half_extents"):
        simulate_pushes([0.5], model=build_model(scene), half_extents=(0.05, 0.05, 0.03))
    with pytest.raises(ValueError, match="unknown scene option"):
        SceneConfig.from_dict({"colour": "red"})


def test_offscreen_frame_renders(scene):
    try:
        model = build_model(scene)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        with mujoco.Renderer(model, 64, 64) as renderer:
            renderer.update_scene(data, camera="top")
            frame = renderer.render()
    except Exception as exc:  # no EGL on this machine
        pytest.skip(f"offscreen rendering unavailable: {exc}")
    assert frame.shape == (64, 64, 3) and frame.dtype == np.uint8
    assert frame.std() > 1.0


def test_a_push_that_cannot_finish_ends_at_max_time(scene):
    """A pusher too weak to move the box never reaches the stroke: the push stops, flagged."""
    from dataclasses import replace

    weak = replace(scene, pusher_force_limit=0.01, max_time=0.5)
    res = simulate_pushes([0.5], 1.0, 0.5, scene=weak, nthread=1)
    assert not res.ok[0]
    assert res.stop_time[0] == pytest.approx(0.5)


def test_models_that_cannot_be_stepped_are_refused(scene):
    model = build_model(scene)
    model.opt.timestep = 0.0
    with pytest.raises(ValueError, match="timestep must be positive"):
        simulate_pushes([0.5], model=model)
    no_box = build_xml(scene).replace('name="box"', 'name="crate"')
    with pytest.raises(ValueError, match="no body named 'box'"):
        simulate_pushes([0.5], 0.5, 0.3, model=mujoco.MjModel.from_xml_string(no_box))
    with pytest.raises(ValueError, match="no joint named 'push'"):
        simulate_pushes([0.5], model=mujoco.MjModel.from_xml_string(build_xml(scene).replace('"push"', '"slide"')))
    with pytest.raises(ValueError, match="timestep"):
        SceneConfig.from_dict({"timestep": -1.0})
    with pytest.raises(ValueError, match="substeps per push"):
        SceneConfig.from_dict({"timestep": 1e-9})


def test_clip_frames_show_the_travel_the_push_reports(scene):
    """The last frame's box position is the reported displacement (same stepping, same correction)."""
    from imply.sim.render import record_pushes

    he = [[0.05, 0.05, 0.03]] * 3
    rec = record_pushes([0.25, 0.6, 0.95], [0.4, 1.0, 1.7], [0.2, 0.4, 0.15], he, [0.0, 0.05, 0.1], scene=scene)
    plain = simulate_pushes([0.25, 0.6, 0.95], [0.4, 1.0, 1.7], [0.2, 0.4, 0.15], half_extents=he, scene=scene)
    np.testing.assert_allclose(rec.displacement, plain.displacement, rtol=1e-12)
    np.testing.assert_allclose(rec.box_qpos[:, -1, 0] - rec.box_qpos[:, 0, 0], rec.displacement, atol=1e-12)
    assert np.all(np.diff(rec.box_qpos[:, :, 0], axis=1) >= -1e-6)  # the box never moves backwards
