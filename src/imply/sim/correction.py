"""A push scene with stated causes written in: the corrected MJCF a diagnosis hands back.

Each cause is a ``mujoco.sysid`` :class:`~mujoco.sysid.Parameter` (value, bounds) whose
modifier writes it into an :class:`mujoco.MjSpec` of the scene with MuJoCo's own mechanism,
so the corrected scene is what ``mujoco.sysid`` itself would compile from the same
parameters (:func:`corrected_spec`), and a fit in the simulator moves the same parameters
(:mod:`imply.diagnose.conclusion.simulator_check`). Parameters are named by the cause
(the diagnostic's candidate names, :data:`CAUSES`):

- ``tilt`` (t_x, t_y): gravity tilted by the slope of the table frame, turned into the
  frame of a push in direction phi (the scene pushes along its +x);
- ``viscous``: damping of the box's free joint (a force -b v);
- ``air_drag``: the medium's density (MuJoCo's inertia-box fluid model);
- ``torsional``, ``rolling``: the box's friction triple, with ``condim`` 4 or 6;
- ``pusher_softness``: the pusher's ``solref`` time constant, lengthened;
- ``table_timeconst``, ``table_dampratio``: the box-table contact's ``solref`` (log factors);
- ``height``: the box's height (its body raised to stand on the table);
- ``speed_gain``: the servo's gain on its command (``gainprm``): it runs at v (1 + g);
- ``speed_offset``: a command mapping, ``<custom><numeric name="command_offset">``, which
  the simulator adds to every commanded speed (a bias on the servo would keep driving the
  pusher after its stroke);
- ``anisotropic`` (a_c, a_s): no MJCF form, as MuJoCo's sliding friction is isotropic per
  geom. It is kept as ``<custom><numeric name="friction_anisotropy">`` for the record and
  applied by the caller as each push's friction mu (1 + a_c cos 2 phi + a_s sin 2 phi).

A user's scene keeps every name it had: edits look bodies, geoms and actuators up by the
names the simulator needs (:class:`imply.sim.pushes.PushJoints`) and the box's free joint
as the body's first joint, whatever it is called.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import mujoco
import numpy as np

from imply.sim.effects import SPEC_EDITS
from imply.sim.scene import COMMAND_OFFSET

# a numeric a corrected scene carries beside its MJCF edits
ANISOTROPY = "friction_anisotropy"  # (a_c, a_s): the box's friction mu (1 + a_c cos 2 phi + a_s sin 2 phi)

# the causes a scene can take, by the diagnostic's candidate names, in a fixed order (a Parameter each; a tilt and an
# anisotropy are two-component: (t_x, t_y), (a_c, a_s))
CAUSES = (
    "torsional",
    "rolling",
    "viscous",
    "pusher_softness",
    "table_timeconst",
    "table_dampratio",
    "tilt",
    "air_drag",
    "height",
    "speed_gain",
    "speed_offset",
    "anisotropic",
)
TWO_COMPONENTS = frozenset({"tilt", "anisotropic"})
# how a cause is written, in words (the report's table)
MECHANISM = {
    "torsional": "the box's torsional friction (friction[1], condim 4)",
    "rolling": "the box's rolling friction (friction[2], condim 6)",
    "viscous": "damping of the box's free joint",
    "pusher_softness": "the pusher's solref time constant",
    "table_timeconst": "the box-table contact's solref time constant",
    "table_dampratio": "the box-table contact's solref damping ratio",
    "tilt": "gravity, tilted",
    "air_drag": "the medium's density (option density)",
    "height": "the box's height",
    "speed_gain": "the servo's gain on its command (gainprm)",
    "speed_offset": f"a command mapping (custom numeric {COMMAND_OFFSET})",
    "anisotropic": f"no MJCF form: kept as custom numeric {ANISOTROPY}, applied as each push's friction",
}
NO_MJCF_FORM = frozenset({"anisotropic"})


def _speed_gain(spec: mujoco.MjSpec, g: float) -> None:
    # a velocity servo's force is gainprm[0] ctrl + biasprm[2] qvel: scaling the gain on the command alone makes it
    # settle at (1 + g) times the command, with the same response and force limit
    servo = spec.actuator("servo")
    gain = np.array(servo.gainprm, float)
    gain[0] *= 1.0 + g
    servo.gainprm = gain


def _servo_gain(spec: mujoco.MjSpec) -> float:
    """The velocity servo's gain on its command over its damping (1 + g after a speed gain g; 1 as built). The
    diagnostic's pusher runs at v (1 + g) + c, so a command offset behind a gain is c / (1 + g)."""
    servo = spec.actuator("servo")
    kv = -float(servo.biasprm[2])
    return float(servo.gainprm[0]) / kv if kv > 0 else 1.0


def _numeric(spec: mujoco.MjSpec, name: str, data: list[float]) -> None:
    existing = spec.numeric(name)
    if existing is not None:
        existing.data = data
    else:
        spec.add_numeric(name=name, data=data)


def _tilt(spec: mujoco.MjSpec, slope: np.ndarray, direction: float) -> None:
    # slope (t_x, t_y) in the table frame: a slope of |t| rad, downhill toward atan2(t_y, t_x). The scene pushes
    # along its +x, so a push in direction phi sees the downhill direction turned by -phi
    a = float(np.hypot(*slope))
    g = float(np.linalg.norm(np.array(spec.option.gravity, float)))
    if a == 0.0:
        return
    psi = float(np.arctan2(slope[1], slope[0])) - direction
    spec.option.gravity = [g * np.sin(a) * np.cos(psi), g * np.sin(a) * np.sin(psi), -g * np.cos(a)]


def _modifier(cause: str, direction: float) -> Callable[[mujoco.MjSpec, object], None]:
    """The modifier writing ``cause`` (a ``mujoco.sysid.Parameter``'s value) into a scene's MjSpec for a push in
    ``direction`` (radians, table frame)."""
    if cause == "tilt":
        return lambda spec, p: _tilt(spec, np.asarray(p.value, float), direction)
    if cause == "anisotropic":
        return lambda spec, p: _numeric(spec, ANISOTROPY, [float(x) for x in p.value])
    if cause == "speed_offset":
        return lambda spec, p: _numeric(spec, COMMAND_OFFSET, [float(p.value[0]) / _servo_gain(spec)])
    edit = _speed_gain if cause == "speed_gain" else SPEC_EDITS[cause]

    def write(spec: mujoco.MjSpec, p) -> None:
        if p.value[0] != 0.0:  # the scene's own value is the cause at 0
            edit(spec, float(p.value[0]))

    return write


def cause_parameters(
    values: Mapping[str, float | np.ndarray],
    *,
    bounds: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
    direction: float = 0.0,
):
    """A ``mujoco.sysid.ParameterDict`` of the causes ``values`` (cause -> value: a number, or the two components
    of a tilt or an anisotropy; names of :data:`CAUSES`), each with its bounds (default: the value itself) and a
    modifier that writes it into a scene's MjSpec for a push in ``direction`` (radians, table frame)."""
    from mujoco import sysid

    unknown = sorted(set(values) - set(CAUSES))
    if unknown:
        raise ValueError(f"no MJCF edit for causes {unknown}; known: {', '.join(CAUSES)}")
    bounds = bounds or {}
    params = sysid.ParameterDict()
    for name in CAUSES:
        if name not in values:
            continue
        v = np.atleast_1d(np.asarray(values[name], float))
        if v.size != (2 if name in TWO_COMPONENTS else 1):
            raise ValueError(f"cause {name} takes {2 if name in TWO_COMPONENTS else 1} numbers, not {v.size}")
        lo, hi = (np.atleast_1d(np.asarray(b, float)) for b in bounds.get(name, (v, v)))
        params.add(sysid.Parameter(name, v, np.minimum(lo, v), np.maximum(hi, v), modifier=_modifier(name, direction)))
    return params


def corrected_spec(xml: str, params, *, model_dir: str | None = None) -> mujoco.MjSpec:
    """An MjSpec of the scene ``xml`` with ``params`` (:func:`cause_parameters`) written in by ``mujoco.sysid``'s
    own :func:`~mujoco.sysid.apply_param_modifiers_spec`. ``model_dir``: where the scene's relative asset paths
    are read from (a user's file)."""
    from mujoco import sysid

    spec = mujoco.MjSpec.from_string(xml)
    if model_dir is not None:
        spec.modelfiledir = model_dir
    return sysid.apply_param_modifiers_spec(params, spec)


def friction_factor(values: Mapping[str, float | np.ndarray], direction) -> np.ndarray:
    """The factor on the box's friction of pushes in ``direction`` (radians; array) under the anisotropy (a_c, a_s)
    of ``values`` (1 without one)."""
    phi = np.asarray(direction, float)
    a_c, a_s = (float(x) for x in np.atleast_1d(values.get("anisotropic", (0.0, 0.0))))
    return 1.0 + a_c * np.cos(2 * phi) + a_s * np.sin(2 * phi)
