"""A robot restricted to some of its joints: the others locked where they stand at the robot's
``home`` pose (their joints removed from the MJCF, their bodies turned to that pose, so they
ride rigidly on their parents, masses and all), without the actuators that moved them.

What it is for: a robot of the same build with fewer joints and chambers (humanoid38's left arm
alone, its arms, its upper body), to measure how a tool's cost grows with the number of places
(scenarios/doctor_benchmark_humanoid38.py's doctor time against chambers).  Built with MuJoCo's
model editing (``mujoco.MjSpec``: the MJCF loaded, elements deleted, compiled again).
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import re
import tempfile
from pathlib import Path

import mujoco
import numpy as np

from .errors import ConfigError, UnknownNameError
from .io import atomic_write_text
from .robot import Robot, actuator_moment_arms, assemble_robot


def actuated_joints(robot: Robot, qpos=None) -> dict[str, set[str]]:
    """Fluid actuator -> the names of the joints it moves at the pose ``qpos`` (default qpos0):
    those with a nonzero moment arm (pneumatics.robot.actuator_moment_arms)."""
    return {name: {j for j, arm in arms.items() if arm > 1e-12}
            for name, arms in actuator_moment_arms(robot, qpos).items()}


def restricted_robot(robot: Robot, joints, label: str) -> Robot:
    """``robot`` with only ``joints`` (names) free and the fluid actuators that move them alone;
    named ``<robot>[<label>]``.  Built from its MJCF file and fluid parameters: a change made to
    ``robot.model`` in memory is not carried (restrict first, then perturb).  Not a model
    ``load_robot`` knows by name (a fitted model.toml of it cannot be loaded back).  An actuator
    that moves a kept joint and a locked one as well is a ConfigError (it would drive a joint
    that is not there)."""
    keep = list(dict.fromkeys(joints))
    unknown = [j for j in keep if j not in robot.joint_names]
    if unknown:
        raise UnknownNameError("joint", unknown[0], robot.joint_names)
    if robot.mjcf_path is None:
        raise ConfigError(f"{robot.name}: no MJCF file to restrict (a robot built in memory)")
    m = robot.model
    home = m.key("home").qpos if "home" in [m.key(i).name for i in range(m.nkey)] else m.qpos0
    moved = actuated_joints(robot, home)
    acts = [a for a, js in moved.items() if js & set(keep)]
    straddle = [a for a in acts if not moved[a] <= set(keep)]
    if straddle:
        raise ConfigError(f"{robot.name}[{label}]: actuator {straddle[0]!r} moves "
                          f"{', '.join(sorted(moved[straddle[0]]))}, not all of them kept")
    spec = mujoco.MjSpec.from_file(str(robot.mjcf_path))
    for a in list(spec.actuators):
        if a.name not in acts:
            spec.delete(a)
    for sensor in list(spec.sensors):
        if sensor.objtype == mujoco.mjtObj.mjOBJ_JOINT and sensor.objname not in keep:
            spec.delete(sensor)
    for joint in [j for j in spec.joints if j.name not in keep]:
        if joint.type not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            raise ConfigError(f"{robot.name}[{label}]: joint {joint.name!r} is a {joint.type.name} joint; only hinge "
                              "and slide joints can be locked")
        _lock(spec, m, joint.name, float(home[m.jnt_qposadr[m.joint(joint.name).id]]))
        spec.delete(joint)
    kept = [n for n in robot.joint_names if n in keep]  # in the model's order
    for i, k in enumerate(spec.keys):  # each keyframe's kept joints (hinges and slides: one qpos, one dof each)
        k.qpos = [float(m.key_qpos[i][m.jnt_qposadr[m.joint(n).id]]) for n in kept]
        k.qvel = [float(m.key_qvel[i][m.jnt_dofadr[m.joint(n).id]]) for n in kept] if len(k.qvel) else []
        k.ctrl = [float(m.key_ctrl[i][m.actuator(a).id]) for a in acts] if len(k.ctrl) else []
    name = f"{robot.name}[{label}]"
    fluid = dataclasses.replace(robot.fluid, actuators=tuple(a for a in robot.fluid.actuators if a.name in acts))
    return assemble_robot(name, spec.compile(), fluid, _saved_mjcf(spec, name, Path(robot.mjcf_path).parent))


def _saved_mjcf(spec, name: str, source_dir: Path) -> Path:
    """The compiled ``spec`` as an MJCF file named by its contents, under the user's cache
    (``$XDG_CACHE_HOME``, else ``~/.cache``; the system's temporary folder if that cannot be
    written): the tools that edit a robot's model again (the orifice calibration's brace,
    backlash, the fitted MJCF) start from its file."""
    for kind in ("meshdir", "texturedir"):  # assets stay where the original model's are
        setattr(spec, kind, str(source_dir / (getattr(spec, kind) or "")))
    text = spec.to_xml()
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    stem = re.sub(r"[^\w.-]+", "_", name).strip("_")
    for parent in (Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "pneumasim" / "models",
                   Path(tempfile.gettempdir()) / "pneumasim-models"):
        path = parent / f"{stem}-{digest}.xml"
        try:
            if not path.is_file():
                parent.mkdir(parents=True, exist_ok=True)
                atomic_write_text(path, text)
            return path
        except OSError:
            continue
    raise ConfigError(f"{name}: nowhere to write its MJCF (the user's cache and the temporary folder refused)")


def _lock(spec, m, joint: str, angle: float) -> None:
    """Move the body of hinge or slide ``joint`` to where ``angle`` puts it, in its parent's
    frame (the rotation about the joint's axis through its anchor, or the slide along it)."""
    jid = m.joint(joint).id
    body = spec.body(m.body(int(m.jnt_bodyid[jid])).name)
    quat, pos = np.asarray(body.quat, float), np.asarray(body.pos, float)
    axis, anchor = m.jnt_axis[jid], m.jnt_pos[jid]
    frame = np.empty(9)
    mujoco.mju_quat2Mat(frame, quat / np.linalg.norm(quat))
    frame = frame.reshape(3, 3)
    if int(m.jnt_type[jid]) == int(mujoco.mjtJoint.mjJNT_SLIDE):
        body.pos = pos + frame @ (axis * angle)
        return
    turn, moved = np.empty(4), np.empty(3)
    mujoco.mju_axisAngle2Quat(turn, axis, angle)
    mujoco.mju_rotVecQuat(moved, anchor, turn)
    new = np.empty(4)
    mujoco.mju_mulQuat(new, quat, turn)
    body.quat = new
    body.pos = pos + frame @ (anchor - moved)
