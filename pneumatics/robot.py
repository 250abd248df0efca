"""A pneumatic robot: its MuJoCo model and its fluid-power parameters, checked against each other."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

import models

from .effects.effect_set import EffectSet
from .errors import ConfigError, UnknownNameError
from .params import FluidCfg, load_fluid
from .tables import FluidTables


@dataclass
class Robot:
    """A loaded model.

    Attributes:
      name: model name (folder name under ``models/``).
      model: compiled ``mujoco.MjModel``.
      fluid: validated fluid-power parameters.
      joint_names: (n_joint,) recorded joints (every hinge and slide joint).
      actuator_ids: (n_act,) MuJoCo actuator id of each fluid actuator, in TOML order.
      tables: flat arrays for the fluid update.
      effects: effects a :class:`~pneumatics.sim.Simulation` of this robot switches on when
        given none of its own (a fitted model's, see ``load_robot(fitted=...)``); None: none.
      fitted: the fitted model (pneumatics.fitted_model.FittedModel) it was loaded with, or None.
    """

    name: str
    model: mujoco.MjModel
    fluid: FluidCfg
    joint_names: list[str]
    actuator_ids: np.ndarray
    tables: FluidTables
    mjcf_path: Path | None = None
    effects: EffectSet | None = None
    fitted: object = None

    @property
    def actuator_names(self) -> list[str]:
        return self.fluid.actuator_names

    @property
    def chamber_names(self) -> list[tuple[str, str]]:
        """(actuator, 'a'|'b') for each chamber, in state order a0, b0, a1, b1, ..."""
        return [(a, c) for a in self.actuator_names for c in ("a", "b")]

    @property
    def qpos_index(self) -> np.ndarray:
        return np.array([self.model.jnt_qposadr[self.model.joint(n).id] for n in self.joint_names], int)

    @property
    def dof_index(self) -> np.ndarray:
        return np.array([self.model.jnt_dofadr[self.model.joint(n).id] for n in self.joint_names], int)

    def joint_range(self) -> np.ndarray:
        """(n_joint, 2) joint limits [rad or m]."""
        return np.array([self.model.jnt_range[self.model.joint(n).id] for n in self.joint_names])

    def with_fluid(self, fluid: FluidCfg) -> "Robot":
        """The same MuJoCo model with other fluid parameters (perturbations, fitted values)."""
        out = assemble_robot(self.name, self.model, fluid, self.mjcf_path)
        out.effects, out.fitted = self.effects, self.fitted
        return out


def compile_mjcf(path: Path) -> mujoco.MjModel:
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as e:  # MuJoCo's XML and compile errors
        msg = " ".join(str(e).split())
        raise ConfigError(f"{path}: MJCF does not compile: {msg}") from None


def load_robot(name: str, *, fluid: FluidCfg | None = None, scene: bool = False, fitted=None) -> Robot:
    """Load model ``name`` (``models.available()`` lists them).

    ``fluid`` replaces the TOML parameters; ``scene`` loads ``scene.xml`` (floor, lights).
    ``fitted``: a model.toml that ``pneumasim doctor`` wrote (path or FittedModel): the robot
    gets its calibration (valve areas, dead volumes, masses, damping, armature) and carries its
    effects (``robot.effects``, which a Simulation switches on).  A file fitted to another
    model is a ConfigError; an entry the simulator applies only approximately or not at all
    (an end stop's stiffness, a load-cell offset, a residual the doctor could not name) is a
    :class:`pneumatics.effects.from_finding.FittedModelWarning` naming it.
    """
    try:
        path = models.mjcf_path(name, scene=scene)
    except models.UnknownModelError:
        raise UnknownNameError("model", name, models.available()) from None
    model = compile_mjcf(path)
    fluid = fluid or load_fluid(models.fluid_path(name))
    robot = assemble_robot(name, model, fluid, path)
    return robot if fitted is None else _with_fitted(robot, fitted)


def _with_fitted(robot: Robot, fitted) -> Robot:
    """``robot`` calibrated and carrying the effects of the fitted model ``fitted``."""
    from .effects.from_finding import effect_set, warn_notes
    from .fitted_model import FittedModel, calibrated_robot, read_fitted

    fm = fitted if isinstance(fitted, FittedModel) else read_fitted(fitted)
    src = str(fm.path or "fitted model")
    if fm.model != robot.name:
        raise ConfigError(f"{src}: fitted to model {fm.model!r}, not {robot.name!r}")
    out = calibrated_robot(robot, fm)
    out.effects, notes = effect_set(fm.effects, out, src)
    notes += [f"{src} [[unexplained]] #{i + 1}: the doctor found a residual it could not name at "
              + " ".join(f"{k} {v}" for k, v in u.get("where", {}).items())
              + f" ({u.get('regime', '')}); this model does not hold it" for i, u in enumerate(fm.unexplained)]
    warn_notes(notes)
    out.fitted = fm
    return out


def assemble_robot(name, model, fluid, path) -> Robot:
    """The Robot of a compiled MJCF ``model`` and its fluid parameters, each fluid actuator
    matched to the MJCF's plain force actuator of that name (ConfigError otherwise)."""
    ids = []
    mj_names = [model.actuator(i).name for i in range(model.nu)]
    for act in fluid.actuators:
        if act.name not in mj_names:
            raise ConfigError(f"{name}: fluid actuator {act.name!r} has no MJCF actuator of that name; "
                              f"MJCF actuators: {', '.join(mj_names) or 'none'}")
        i = mj_names.index(act.name)
        if (int(model.actuator_dyntype[i]) != int(mujoco.mjtDyn.mjDYN_NONE)
                or int(model.actuator_biastype[i]) != int(mujoco.mjtBias.mjBIAS_NONE)
                or model.actuator_gainprm[i, 0] != 1.0):
            raise ConfigError(f"{name}: MJCF actuator {act.name!r} must be a plain force actuator "
                              "(<motor> or <general> with gain 1, no bias, no dynamics)")
        if model.actuator_ctrllimited[i]:
            raise ConfigError(f"{name}: MJCF actuator {act.name!r} must not be ctrllimited: its ctrl is "
                              "the cylinder force computed by the fluid layer")
        ids.append(i)
    joints = [model.joint(j).name for j in range(model.njnt)
              if int(model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))]
    # piston position x = L - L_zero; at qpos0 the piston sits at position_at_zero
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    length0 = data.actuator_length[ids]
    length_zero = np.array([l0 - a.zero_position for l0, a in zip(length0, fluid.actuators)])
    _check_travel(name, model, fluid, ids, length_zero)
    return Robot(name, model, fluid, joints, np.array(ids, int), FluidTables.build(fluid, length_zero), path)


def _check_travel(name, model, fluid, ids, length_zero, samples: int = 400):
    """The joint ranges must keep every piston inside its stroke.

    Joint transmissions are checked exactly from the range; tendon and site transmissions
    (angle-dependent moment arms) on ``samples`` random poses inside the joint ranges plus
    every joint at each of its limits with the others at zero.
    """
    others = []
    for a, i, lz in zip(fluid.actuators, ids, length_zero):
        if int(model.actuator_trntype[i]) != int(mujoco.mjtTrn.mjTRN_JOINT):
            others.append((a, i, lz))
            continue
        j = model.actuator_trnid[i, 0]
        if not model.jnt_limited[j]:
            continue
        gear = model.actuator_gear[i, 0]
        lengths = gear * model.jnt_range[j] - lz
        if lengths.min() < -1e-9 or lengths.max() > a.stroke + 1e-9:
            raise ConfigError(f"{name}: joint {model.joint(j).name!r} range moves actuator {a.name!r} "
                              f"to {lengths.min():.4g}..{lengths.max():.4g}, outside its stroke [0, {a.stroke:.4g}]")
    if not others:
        return
    limited = [j for j in range(model.njnt) if model.jnt_limited[j]
               and int(model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))]
    adr = model.jnt_qposadr[limited]
    lo, hi = model.jnt_range[limited, 0], model.jnt_range[limited, 1]
    rng = np.random.default_rng(0)
    poses = [lo + (hi - lo) * rng.random(len(limited)) for _ in range(samples)]
    for k in range(len(limited)):
        for end in (lo, hi):
            q = np.clip(np.zeros(len(limited)), lo, hi)
            q[k] = end[k]
            poses.append(q)
    data = mujoco.MjData(model)
    for q in poses:
        data.qpos[adr] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_tendon(model, data)
        mujoco.mj_transmission(model, data)
        for a, i, lz in others:
            x = data.actuator_length[i] - lz
            if x < -1e-6 or x > a.stroke + 1e-6:
                raise ConfigError(f"{name}: actuator {a.name!r} reaches piston position {x:.4g} (stroke "
                                  f"[0, {a.stroke:.4g}]) at a pose inside the joint ranges")


def actuator_moment_arms(robot: Robot, qpos=None) -> dict[str, dict[str, float]]:
    """Fluid actuator -> {joint name: |moment arm|} at the pose ``qpos`` (the model's whole
    qpos; default qpos0): the joints each actuator moves whatever its transmission (a joint, a
    tendon across pins), read from MuJoCo's sparse actuator_moment rows after mj_forward
    (moment arms in m for a linear cylinder on a hinge, 1 for a vane on its own joint)."""
    m = robot.model
    d = mujoco.MjData(m)
    if qpos is not None:
        d.qpos[:] = qpos
    mujoco.mj_forward(m, d)
    out = {}
    for name, a in zip(robot.actuator_names, robot.actuator_ids):
        lo = d.moment_rowadr[int(a)]
        row = slice(lo, lo + d.moment_rownnz[int(a)])
        out[name] = {m.joint(int(m.dof_jntid[c])).name: float(abs(v))
                     for c, v in zip(d.moment_colind[row], d.actuator_moment[row])}
    return out


def joint_index(robot: Robot, joint: str) -> int:
    if joint not in robot.joint_names:
        raise UnknownNameError("joint", joint, robot.joint_names)
    return robot.joint_names.index(joint)


def actuator_index(robot: Robot, actuator: str) -> int:
    if actuator not in robot.actuator_names:
        raise UnknownNameError("actuator", actuator, robot.actuator_names)
    return robot.actuator_names.index(actuator)
