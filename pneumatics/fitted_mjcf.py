"""``fitted.xml``: a fitted model for users of plain MuJoCo.

Starts from the model's own MJCF (``models/<name>/<name>.xml``, through ``mujoco.MjSpec``) and
puts in what MuJoCo has natively:

* each body's mass and inertia tensor times its calibrated ``mass_scale`` (bodies whose
  inertia MuJoCo infers from their geoms: those geoms' density and mass instead);
* each joint's damping times ``damping_scale`` plus a fitted viscous friction (both a torque
  -b qd: MuJoCo's joint damping); its armature times ``armature_scale``;
* a fitted Coulomb level (``coulomb_friction``, and ``stiction``'s Coulomb part) as the joint's
  ``frictionloss`` (MuJoCo's dry friction, a constraint bounded by it);
* an end stop as the joint's limit moved to the fitted stop angle, with the simulator's bumper
  time constant (pneumatics.effects.effect_set.END_STOP_TIMECONST_S).

The fluid-power layer is not MuJoCo's: the actuators stay force motors (ctrl = cylinder force
[N]), and everything else the model holds (chamber calibration, pneumatic effects, sensor
offsets, stiction's breakaway excess) is listed in the file's comment header, so a plain-MuJoCo
user sees what this file leaves out.
"""
from __future__ import annotations

from pathlib import Path

import mujoco

from .effects.effect_set import END_STOP_TIMECONST_S
from .errors import ConfigError
from .fitted_model import FittedModel

#: the effects (family) whose native part fitted.xml carries, and what of them it leaves out
NATIVE = {"coulomb_friction": "", "viscous_friction": "", "end_stop": "its fitted stiffness and damping",
          "stiction": "its breakaway excess (breakaway_extra_nm)"}
#: forms of those families MuJoCo has nothing for (its joint damping is linear in the velocity)
NOT_NATIVE_FORMS = {("viscous_friction", "velocity_power")}


def _native(e) -> bool:
    return e.family in NATIVE and (e.family, e.form) not in NOT_NATIVE_FORMS


def fitted_mjcf(robot, fm: FittedModel) -> str:
    """The MJCF text of ``robot``'s model (as loaded without a fitted model) with ``fm``'s
    inertias and native joint effects."""
    if robot.mjcf_path is None:
        raise ConfigError(f"{robot.name}: no MJCF file to start fitted.xml from")
    spec = mujoco.MjSpec.from_file(str(robot.mjcf_path))
    for body, s in fm.scales("mass_scale").items():
        _scale_body(spec, body, s)
    for joint, s in fm.scales("damping_scale").items():
        _joint(spec, joint).damping[0] *= s
    for joint, s in fm.scales("armature_scale").items():
        _joint(spec, joint).armature *= s
    for e in fm.effects:
        if not _native(e):
            continue
        j = _joint(spec, e.place)
        if e.family in ("coulomb_friction", "stiction"):
            j.frictionloss += e.value("coulomb_nm")
        elif e.family == "viscous_friction":
            j.damping[0] += e.value("viscous_nm_s_per_rad")
        else:
            _end_stop(spec, j, robot, e)
    spec.compile()  # what MuJoCo would refuse is refused here, not when the user loads it
    return _header(fm) + spec.to_xml()


def write_fitted_mjcf(robot, fm: FittedModel, path) -> Path:
    from .io import atomic_write_text

    path = Path(path)
    atomic_write_text(path, fitted_mjcf(robot, fm))
    return path


def _joint(spec, name):
    j = spec.joint(name)
    if j is None:
        raise ConfigError(f"fitted.xml: the MJCF has no joint {name!r}")
    return j


def _scale_body(spec, name: str, s: float):
    b = spec.body(name)
    if b is None:
        raise ConfigError(f"fitted.xml: the MJCF has no body {name!r}")
    if b.explicitinertial:
        b.mass *= s
        b.inertia *= s
        b.fullinertia *= s  # NaN unless the file gave a full tensor
    else:  # inertia from the body's own geoms
        for g in b.geoms:
            g.density *= s
            if g.mass == g.mass:  # a given geom mass (NaN: from density)
                g.mass *= s


def _end_stop(spec, joint, robot, e):
    """The joint's limit at the fitted stop, on the side it was found."""
    stop, upper = e.value("stop_rad"), e.value("side_sign") > 0
    if spec.compiler.degree and robot.model.jnt_type[robot.model.joint(e.place).id] == mujoco.mjtJoint.mjJNT_HINGE:
        stop = stop * 180.0 / 3.141592653589793
    lo, hi = joint.range
    joint.range = (lo, min(hi, stop)) if upper else (max(lo, stop), hi)
    joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    joint.solref_limit = (END_STOP_TIMECONST_S, 1.0)


def _header(fm: FittedModel) -> str:
    """A comment: where the file came from and what of the fitted model it does not hold."""
    left = [f"  {e.family} at {e.place}" + (f": {NATIVE[e.family]}" if _native(e) else
                                            f" (its {e.form} form)" if e.family in NATIVE else "")
            for e in fm.effects if not _native(e) or NATIVE[e.family]]
    chambers = sorted({k for k in fm.calibration if k.split(".")[0] in
                       ("supply_area_scale", "exhaust_area_scale", "dead_volume_scale")})
    lines = [f"<!-- {fm.model} as pneumasim doctor fitted it (pneumasim {fm.pneumasim_version}), for plain MuJoCo.",
             "  Calibrated: body masses and inertias (mass_scale), joint damping and armature; native",
             "  effects: viscous friction in joint damping, Coulomb friction as frictionloss, end stops",
             "  as joint limits.  Actuators are force motors: ctrl = cylinder force [N].",
             "  Not in this file (the fluid-power layer; load model.toml with pneumasim for them):"]
    lines += [f"  chamber calibration: {len(chambers)} valve-area and dead-volume scales"] if chambers else []
    lines += left or ["  nothing else"]
    return "\n".join(lines) + "\n-->\n"
