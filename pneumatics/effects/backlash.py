"""Backlash: a play of total width ``gap_rad`` between a cylinder and the link it turns.

Dead-zone model (Nordin & Gutman, "Controlling mechanical systems with backlash — a survey",
Automatica 38 (2002) 1633-1649, §2.1, eq. (2)): drive (motor) side angle q_d and load side
angle q_l transmit no torque while |q_d - q_l| < gap/2 and a stiff, damped contact torque
beyond.  It is built into MuJoCo itself, not computed in Python each step:

* each joint J with backlash gets a sibling body ``J_drive`` (same parent, pose and hinge
  axis/anchor as J's link body), with a hinge ``J_drive`` that carries the cylinder;
* the fluid actuator that drove J now drives ``J_drive`` (same gear), so
  ``actuator_length`` = gear · q_drive and the chamber volumes follow the piston side;
* a fixed tendon ``J_backlash`` = q_drive − q_link, limited to [−gap/2, +gap/2]: MuJoCo's
  tendon limit is the contact of the play, critically damped.  Only the piston's inertia
  (~4e-5 kg m² on arm2) is behind the contact, so MuJoCo's default impedance (d = 0.9-0.95)
  and the end stops' 5 ms would let it sink ~0.1 rad under full pressure, more than the gap:
  the contact uses d = 0.99-0.999 (``BACKLASH_SOLIMP``) and a time constant of 2 physics steps
  (MuJoCo's minimum; 2 ms on arm2).  Measured on the arm2 elbow (tests/test_backlash.py): 0.7 mrad
  held at 3 N m; at impacts ~ relative speed x 2 ms (4.5 mrad on ±0.5 V reversals, ~11 mrad when
  the piston slams across the gap at full pressure).

The drive body is a point mass 1e-6 kg / 1e-9 kg m² without geoms; the rotor (piston, rod)
inertia, which the MJCF gives as J's ``armature`` (piston mass × moment arm²), sits on the
cylinder side of the play and moves to ``J_drive``.  J keeps ``LINK_ARMATURE`` (1e-7 kg m², far
below any link's inertia) only to keep the mass matrix well conditioned.  Joint limits stay on
J; the drive is unlimited (the play keeps it within gap/2 of J).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from ..errors import PneumasimError, UnknownNameError
from .family import Family, param

BACKLASH_STEPS = 2  # contact time constant in physics steps (MuJoCo asks for >= 2)
BACKLASH_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)  # impedance dmin, dmax, width [rad], midpoint, power
DRIVE_MASS_KG, DRIVE_INERTIA_KGM2 = 1e-6, 1e-9
LINK_ARMATURE = 1e-7
_HINGE_SLIDE = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


def backlash_model(robot, gaps: Mapping[str, float | Mapping[str, float]]) -> mujoco.MjModel:
    """A new MjModel of ``robot`` with a play of ``gaps[joint]`` [rad] (a number or
    ``{"gap_rad": g}``) between each named joint and its cylinder.

    Physical parameters of ``robot.model`` that may have been changed after loading (body
    masses and inertias, joint damping, ranges, timestep, gravity, active equalities, gears)
    are carried over (every original element keeps its relative order in the new model).
    """
    if robot.mjcf_path is None:
        raise PneumasimError(f"backlash: robot {robot.name!r} has no MJCF file (mjcf_path is None); "
                             "the backlash model is rebuilt from it")
    old = robot.model
    gaps = {j: _gap(j, g) for j, g in gaps.items()}
    spec = mujoco.MjSpec.from_file(str(robot.mjcf_path))
    for joint, gap in gaps.items():
        if joint not in robot.joint_names:
            raise UnknownNameError("joint", joint, robot.joint_names)
        if not (math.isfinite(gap) and gap > 0):
            raise PneumasimError(f"backlash: gap_rad of joint {joint!r} must be finite and > 0, got {gap!r}")
        j = old.joint(joint).id
        acts = [a for a in spec.actuators if int(a.trntype) == int(mujoco.mjtTrn.mjTRN_JOINT) and a.target == joint]
        if not acts:
            raise PneumasimError(f"backlash: joint {joint!r} is not driven by a joint-transmission actuator")
        link = old.jnt_bodyid[j]
        parent_name = old.body(int(old.body_parentid[link])).name
        if not parent_name:
            raise PneumasimError(f"backlash: the body holding joint {joint!r}'s link has no name in {robot.mjcf_path}")
        parent = spec.body(parent_name)
        drive = parent.add_body(name=f"{joint}_drive", pos=old.body_pos[link], quat=old.body_quat[link],
                                mass=DRIVE_MASS_KG, inertia=[DRIVE_INERTIA_KGM2] * 3, explicitinertial=True)
        drive.add_joint(name=f"{joint}_drive", type=mujoco.mjtJoint(int(old.jnt_type[j])),
                        axis=old.jnt_axis[j], pos=old.jnt_pos[j], limited=mujoco.mjtLimited.mjLIMITED_FALSE,
                        armature=float(old.dof_armature[old.jnt_dofadr[j]]))
        spec.joint(joint).armature = LINK_ARMATURE
        for a in acts:
            a.target = f"{joint}_drive"
        tendon = spec.add_tendon(name=f"{joint}_backlash", limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                                 range=[-gap / 2, gap / 2], solimp_limit=BACKLASH_SOLIMP,
                                 solref_limit=[BACKLASH_STEPS * old.opt.timestep, 1.0])
        tendon.wrap_joint(f"{joint}_drive", 1.0)
        tendon.wrap_joint(joint, -1.0)
    for key in spec.keys:  # sizes change: filled in on the compiled model below
        key.qpos, key.qvel = [], []
    try:
        model = spec.compile()
    except ValueError as e:
        raise PneumasimError(f"backlash: {robot.mjcf_path}: model does not compile: {' '.join(str(e).split())}") from None
    _carry_over(old, model, gaps)
    return model


def _gap(joint, value) -> float:
    try:
        return float(value["gap_rad"] if isinstance(value, Mapping) else value)
    except (KeyError, TypeError, ValueError):
        raise PneumasimError(f"backlash: joint {joint!r}: expected {{'gap_rad': total play [rad]}}, "
                             f"got {value!r}") from None


def _carry_over(old, new, gaps):
    """Copy parameters that a caller may have changed on the loaded model; remap keyframes."""
    new.opt.timestep, new.opt.gravity[:] = old.opt.timestep, old.opt.gravity
    drives = {f"{j}_drive" for j in gaps}
    # the drive bodies and joints are inserted; every other one keeps its relative order
    bodies = [b for b in range(new.nbody) if new.body(b).name not in drives]
    joints = [j for j in range(new.njnt) if new.joint(j).name not in drives]
    for b in range(old.nbody):
        n = bodies[b]
        new.body_mass[n], new.body_inertia[n] = old.body_mass[b], old.body_inertia[b]
        new.body_ipos[n], new.body_iquat[n] = old.body_ipos[b], old.body_iquat[b]
    for j in range(old.njnt):
        n = joints[j]
        new.jnt_range[n], new.jnt_limited[n], new.jnt_solref[n] = old.jnt_range[j], old.jnt_limited[j], old.jnt_solref[j]
        if int(old.jnt_type[j]) in _HINGE_SLIDE:
            do, dn = old.jnt_dofadr[j], new.jnt_dofadr[n]
            new.dof_damping[dn], new.dof_frictionloss[dn] = old.dof_damping[do], old.dof_frictionloss[do]
    for k in range(old.nkey):
        qpos, qvel = old.key_qpos[k], old.key_qvel[k]
        for j in range(old.njnt):
            name, n = old.joint(j).name, joints[j]
            size_q = {0: 7, 1: 4}.get(int(old.jnt_type[j]), 1)
            size_v = {0: 6, 1: 3}.get(int(old.jnt_type[j]), 1)
            qs = qpos[old.jnt_qposadr[j]:old.jnt_qposadr[j] + size_q]
            vs = qvel[old.jnt_dofadr[j]:old.jnt_dofadr[j] + size_v]
            targets = [n] + ([new.joint(f"{name}_drive").id] if name in gaps else [])
            for t in targets:  # the drive starts at the link's angle, centred in the play
                new.key_qpos[k, new.jnt_qposadr[t]:new.jnt_qposadr[t] + size_q] = qs
                new.key_qvel[k, new.jnt_dofadr[t]:new.jnt_dofadr[t] + size_v] = vs
    new.eq_active0[:] = old.eq_active0  # equalities and actuators keep their order
    new.actuator_gear[:] = old.actuator_gear


def backlash_joints(model) -> dict[str, float]:
    """joint -> total gap [rad] of every play built into ``model`` (empty for a plain model)."""
    out = {}
    for t in range(model.ntendon):
        name = model.tendon(t).name
        if name.endswith("_backlash"):
            out[name[:-len("_backlash")]] = float(model.tendon_range[t, 1] - model.tendon_range[t, 0])
    return out


def link_joint_names(model) -> list[str]:
    """Hinge and slide joints of ``model`` other than the drive joints, in model order (for a
    backlash model of a robot, ``robot.joint_names``)."""
    drives = {f"{j}_drive" for j in backlash_joints(model)}
    return [model.joint(j).name for j in range(model.njnt)
            if int(model.jnt_type[j]) in _HINGE_SLIDE and model.joint(j).name not in drives]


def addresses(model, joint_names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """(qpos addresses, dof addresses), each (len(joint_names),), of the named joints."""
    valid = [model.joint(j).name for j in range(model.njnt)]
    for n in joint_names:
        if n not in valid:
            raise UnknownNameError("joint", n, valid)
    ids = [model.joint(n).id for n in joint_names]
    return np.asarray(model.jnt_qposadr[ids], int), np.asarray(model.jnt_dofadr[ids], int)


def drive_pairs(model, joint_names: Sequence[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(k, gap, drive qpos address, drive dof address) for each joint ``joint_names[k]`` with a play."""
    gaps = backlash_joints(model)
    k = [i for i, n in enumerate(joint_names) if n in gaps]
    qadr, dadr = addresses(model, [f"{joint_names[i]}_drive" for i in k])
    return np.asarray(k, int), np.array([gaps[joint_names[i]] for i in k]), qadr, dadr


def set_drive_state(model, data, q_link, qd_link, torque_sign, joint_names: Sequence[str] | None = None):
    """Put links at ``q_link`` / ``qd_link`` and each drive at q + gap/2 · sign(torque), i.e.
    in contact on the side the cylinder pushes (centred where the sign is 0).

    Args:
      data: one ``MjData`` with arrays of shape (J,), or a sequence of W ``MjData`` with (W, J).
      q_link, qd_link, torque_sign: link angles [rad], velocities [rad/s], cylinder torque signs,
        columns in the order of ``joint_names`` (default :func:`link_joint_names`).
    """
    names = link_joint_names(model) if joint_names is None else list(joint_names)
    qadr, dadr = addresses(model, names)
    k, gap, dq, dd = drive_pairs(model, names)
    many = not isinstance(data, mujoco.MjData)
    datas = list(data) if many else [data]
    q, qd, s = (np.atleast_2d(np.asarray(x, float)) for x in (q_link, qd_link, torque_sign))
    if q.shape != (len(datas), len(names)) or qd.shape != q.shape or s.shape != q.shape:
        raise PneumasimError(f"set_drive_state: expected q_link, qd_link, torque_sign of shape "
                             f"{(len(datas), len(names))}, got {q.shape}, {qd.shape}, {s.shape}")
    for w, d in enumerate(datas):
        d.qpos[qadr], d.qvel[dadr] = q[w], qd[w]
        d.qpos[dq] = q[w, k] + 0.5 * gap * np.sign(s[w, k])
        d.qvel[dd] = qd[w, k]


# -- the family ------------------------------------------------------------------------------

@dataclass(frozen=True)
class DeadZone:
    """A play between cylinder and link."""

    gap_rad: float = param(0.0, "total play (the drive moves gap/2 either way of the link freely)", "rad", 0.0, 1.0)


def _driving(robot, joint: str) -> list[int]:
    """Indices into ``robot.actuator_ids`` of the joint-transmission actuators turning ``joint``."""
    m, jid = robot.model, robot.model.joint(joint).id
    return [k for k, i in enumerate(robot.actuator_ids)
            if int(m.actuator_trntype[i]) == int(mujoco.mjtTrn.mjTRN_JOINT) and int(m.actuator_trnid[i, 0]) == jid]


class Backlash(Family):
    name = "backlash"
    place_kind = "joint"
    forms = {"dead_zone": DeadZone}
    physics = "dead zone of width gap between cylinder and link; stiff damped contact beyond"
    sources = "Nordin & Gutman, Automatica 38 (2002) eq. 2"
    simulator = "drive hinge + limited fixed tendon in MuJoCo (backlash_model)"
    doctor = "pressure_replay"  # the piston leads the link by gap/2 on the side it pushes

    def effect_set_entry(self, params):
        return {"backlash": {"gap_rad": params.gap_rad}}

    def places(self, robot) -> list[str]:
        """The joints a joint-transmission actuator drives: backlash_model splits such a joint
        into a drive hinge and the link; a cylinder on pins pulling a spatial tendon (13 of
        humanoid38's joints) has no drive-side hinge to put a play on."""
        return [j for j in robot.joint_names if _driving(robot, j)]

    def apply_to_mods(self, mods, robot, place, params):
        """PneumaticMods.backlash_rad, per actuator: the one that turns joint ``place``."""
        if place not in robot.joint_names:
            raise UnknownNameError("joint", place, robot.joint_names)
        driving = _driving(robot, place)
        if not driving:
            raise PneumasimError(f"backlash: joint {place!r} is driven by no joint-transmission actuator")
        arr = np.zeros(len(robot.actuator_ids)) if mods.backlash_rad is None else np.array(mods.backlash_rad, float)
        arr[driving[0]] = params.gap_rad
        return mods.copy(backlash_rad=arr)

    def draw(self, rng):
        # a play of 0.3-1 deg between cylinder and link (worn clevis pins and rod-end bearings)
        return DeadZone(rng.uniform(0.006, 0.018))
