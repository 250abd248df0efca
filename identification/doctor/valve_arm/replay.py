"""Coupled short replays: MuJoCo and the (modified) chamber model together, restarted from
the measured state every ``horizon_s`` and driven by the recorded valve commands — the
simulation error of DESIGN.md's doctor, step 3.  (Without its controller the arm has no
restoring force: a free run of a whole recording drifts away whatever the model, so runs of
about a second are restarted from the measured state.)
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import mujoco
import numpy as np

from pneumatics.chamber import actuator_force
from pneumatics.effects.angle_sensor_offset import reading_error, true_angle
from pneumatics.effects.backlash import addresses, backlash_model, set_drive_state
from pneumatics.effects.end_stop import penetration
from pneumatics.effects.friction import friction_torque

from .data import FINE_DT, Experiment
from .pneumatic import (
    ChamberModel,
    PneumaticMods,
    Windows,
    effective_commands,
    initial_pressure,
)
from .thermal import gas_temperatures


@dataclass
class MechMods:
    """Rigid-body calibration and mechanical effects; arrays per joint (J,)."""

    mass_scale: dict = field(default_factory=dict)      # body name -> relative change (0 = nominal)
    damping_scale: dict = field(default_factory=dict)   # joint -> relative change
    armature_scale: dict = field(default_factory=dict)
    coulomb_nm: np.ndarray = None
    stiction_extra_nm: np.ndarray = None
    viscous_nm_s: np.ndarray = None
    viscous_power_nm: np.ndarray = None                # b_n of a velocity-power viscous friction
    viscous_exponents: dict = field(default_factory=dict)  # joint index -> its exponent n
    angle_offset_rad: np.ndarray = None
    angle_scale_error: np.ndarray = None               # the angle sensor's gain error (offset_and_scale form)
    end_stop_nm_per_rad: np.ndarray = None             # stiffness of an end stop (end_stop)
    end_stop_nm_s_per_rad: np.ndarray = None           # its damping while in contact
    end_stops: dict = field(default_factory=dict)      # joint index -> (stop_rad, side +1/-1)
    state_torques: dict = field(default_factory=dict)  # joint index -> f(q (W,), qd (W,)) -> torque (W,) [N m]:
                                                       # a yardstick's fitted torque (angle_replay.yardstick_angle)

    @classmethod
    def from_fit(cls, fit, joint_names, extra_terms=()) -> "MechMods":
        m = cls()
        J = len(joint_names)
        for name, v in zip(fit.names, fit.values):
            kind, _, where = name.partition(".")
            if kind == "mass_scale":
                m.mass_scale[where] = float(v)
            elif kind == "damping_scale":
                m.damping_scale[where] = float(v)
            elif kind == "armature_scale":
                m.armature_scale[where] = float(v)
        m.add([(attr, j, v) for (attr, j), v in zip(extra_terms, fit.values[len(fit.values) - len(extra_terms):])], J)
        return m

    def add(self, terms, n_joints: int) -> None:
        """Add ``terms`` [(attribute, joint, value)] in place; terms of several findings at one
        joint add up, and an attribute of None (a term acting on the chambers, a pressure-sensor
        offset) is not the body's."""
        for attr, j, v in terms:
            if attr is None:
                continue
            arr = getattr(self, attr)
            arr = np.zeros(n_joints) if arr is None else arr
            arr[j] += v
            setattr(self, attr, arr)

    def model(self, base: mujoco.MjModel) -> mujoco.MjModel:
        m = copy.copy(base)
        for body, s in self.mass_scale.items():
            b = m.body(body).id
            m.body_mass[b] *= 1 + s
            m.body_inertia[b] *= 1 + s
        for joint, s in self.damping_scale.items():
            m.dof_damping[m.joint(joint).dofadr[0]] *= 1 + s
        for joint, s in self.armature_scale.items():
            m.dof_armature[m.joint(joint).dofadr[0]] *= 1 + s
        return m

    def torque(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray | None:
        """(W, J) friction and end-stop torques at joint angles q and velocities qd (W, J)."""
        stops = self.end_stop_nm_per_rad is not None and self.end_stops
        if (self.coulomb_nm is None and self.stiction_extra_nm is None and self.viscous_nm_s is None
                and self.viscous_power_nm is None and not stops and not self.state_torques):
            return None
        z = np.zeros_like(qd)
        exponents = np.ones(qd.shape[1])
        exponents[list(self.viscous_exponents)] = list(self.viscous_exponents.values())
        tau = friction_torque(qd, z + (0 if self.coulomb_nm is None else self.coulomb_nm),
                              z + (0 if self.stiction_extra_nm is None else self.stiction_extra_nm),
                              0.1, z + (0 if self.viscous_nm_s is None else self.viscous_nm_s),
                              z + (0 if self.viscous_power_nm is None else self.viscous_power_nm), exponents)
        if stops:
            for j, (stop, side) in self.end_stops.items():
                pen = penetration(q[:, j], stop, side)
                b = 0.0 if self.end_stop_nm_s_per_rad is None else self.end_stop_nm_s_per_rad[j]
                tau[:, j] -= np.where(pen != 0, self.end_stop_nm_per_rad[j] * pen + b * qd[:, j], 0.0)
        for j, f in self.state_torques.items():
            tau[:, j] += f(q[:, j], qd[:, j])
        return tau


@dataclass
class ReplayResult:
    """Predicted vs measured DAQ samples over all windows: dicts channel -> (M,) arrays;
    ``times`` (M,) and ``index`` (M,), each replayed sample's time and row in the experiment."""

    predicted: dict
    measured: dict
    times: np.ndarray
    index: np.ndarray = None
    horizon: int = None     # samples per replay window (each restarted from the measured state)

    def nrmse(self, rows: np.ndarray | None = None) -> dict:
        """Per channel: RMS error over the replayed samples (those whose experiment row is
        True in ``rows``, (N,) bool, if given) / the s.d. of the measured channel over all of
        them, so an NRMSE inside a regime is on the same scale as the overall one."""
        m = slice(None) if rows is None else rows[self.index]
        return {c: float(np.sqrt(np.mean((self.predicted[c][m] - self.measured[c][m]) ** 2))
                         / max(np.std(self.measured[c]), 1e-12)) for c in self.predicted}

    def window_rms(self, channel: str) -> np.ndarray:
        """(W,) the RMS error of ``channel`` in each replay window."""
        e = self.predicted[channel] - self.measured[channel]
        return np.sqrt(np.mean(e.reshape(-1, self.horizon) ** 2, axis=1))

    def r2(self) -> dict:
        return {c: 1.0 - v ** 2 for c, v in self.nrmse().items()}


def typical_window_ratio(before: ReplayResult, after: ReplayResult, channel: str) -> float | None:
    """The median over the replay windows of ``channel``'s RMS error in ``after`` over that in
    ``before`` (the same windows of the same data): how a change does in the typical window.
    One window of an open-loop replay that runs away (a 1 s coupled replay of humanoid38 whose
    waist swings out, 130-190 mrad off where its others are 2-40) carries most of an NRMSE, and
    a change that moves it decides the whole ratio.  None when the windows differ."""
    if before.horizon is None or before.horizon != after.horizon or before.index.shape != after.index.shape:
        return None
    b, a = before.window_rms(channel), after.window_rms(channel)
    return float(np.median(a / np.maximum(b, 1e-300)))


def backlash_gaps(robot, pmods: PneumaticMods) -> dict:
    """joint -> the backlash [rad] of the actuator driving it (``pmods.backlash_rad``; only > 0)."""
    if pmods.backlash_rad is None:
        return {}
    return {robot.model.joint(int(robot.model.actuator_trnid[robot.actuator_ids[j], 0])).name: float(g)
            for j, g in enumerate(pmods.backlash_rad) if g > 0}


def drive_signs(robot, pmods: PneumaticMods, forces: np.ndarray) -> np.ndarray:
    """(W, J) the side each backlash's drive starts in contact on: the sign of the torque its
    cylinder pushes with (``forces`` (W, n_act) at the windows' starts); 0 without backlash."""
    sign = np.zeros((forces.shape[0], len(robot.joint_names)))
    ids = robot.actuator_ids
    for j, g in enumerate([] if pmods.backlash_rad is None else pmods.backlash_rad):
        if g > 0:
            joint = robot.model.joint(int(robot.model.actuator_trnid[ids[j], 0])).name
            sign[:, robot.joint_names.index(joint)] = np.sign(robot.model.actuator_gear[ids[j], 0] * forces[:, j])
    return sign


def start_state(exp: Experiment, starts: np.ndarray, mmods: MechMods) -> tuple:
    """(offset, scale error (J,), true angles, velocities (W, J)) at the windows' ``starts``: the
    lightly smoothed angles read back through ``mmods``'s angle-sensor law."""
    J = len(exp.robot.joint_names)
    offset = mmods.angle_offset_rad if mmods.angle_offset_rad is not None else np.zeros(J)
    scale = mmods.angle_scale_error if mmods.angle_scale_error is not None else np.zeros(J)
    f0, fq = starts * exp.n_sub, exp.fine_q
    q0 = true_angle(fq[f0], offset, scale)
    qd0 = (fq[f0 + 1] - fq[f0 - 1]) / (2 * FINE_DT) / (1.0 + scale)
    return offset, scale, q0, qd0


def replay_model(robot, pmods: PneumaticMods, mmods: MechMods):
    """The MjModel a replay steps: ``mmods``'s rigid body, with the backlash of ``pmods``
    carried by MuJoCo (pneumatics.effects.backlash; the chambers follow the drive)."""
    gaps = backlash_gaps(robot, pmods)
    return mmods.model(backlash_model(robot, gaps) if gaps else robot.model)


def window_starts(exp: Experiment, horizon_s: float) -> tuple[np.ndarray, int]:
    """(starts, H): the recording's rows where each replay window of ``horizon_s`` begins (tiled
    between the recording's breaks), and a window's length in rows."""
    H = max(1, int(round(horizon_s * exp.rate_hz)))
    return Windows.tile(len(exp.t), H, breaks=exp.breaks).starts, H


def step_windows(model, datas, ids, forces: np.ndarray, mmods: MechMods, qadr, dadr) -> None:
    """One physics step of every window's rigid body: the cylinders' ``forces`` (W, n_act) on
    actuators ``ids`` and ``mmods``'s torques at the windows' joints."""
    tau = mmods.torque(np.array([d.qpos[qadr] for d in datas]), np.array([d.qvel[dadr] for d in datas]))
    for w, d in enumerate(datas):
        d.ctrl[ids] = forces[w]
        if tau is not None:
            d.qfrc_applied[dadr] = tau[w]
        mujoco.mj_step(model, d)


def coupled_replay(exp: Experiment, pmods: PneumaticMods, mmods: MechMods, horizon_s: float = 1.0) -> ReplayResult:
    robot = exp.robot
    model = replay_model(robot, pmods, mmods)
    S = exp.n_sub
    starts, H = window_starts(exp, horizon_s)
    W = starts.size
    J = len(robot.joint_names)
    qadr, dadr = addresses(model, robot.joint_names)
    ids = robot.actuator_ids
    datas = [mujoco.MjData(model) for _ in range(W)]
    offset, scale, q0, qd0 = start_state(exp, starts, mmods)
    p = initial_pressure(exp, starts, pmods)
    set_drive_state(model, datas, q0, qd0, drive_signs(robot, pmods, actuator_force(robot.tables, p)), robot.joint_names)
    for d in datas:
        mujoco.mj_forward(model, d)
    chambers = ChamberModel(robot, pmods, W)
    u_f = effective_commands(exp, pmods)
    if chambers.thermal.size:
        chambers.T = gas_temperatures(exp, pmods, u_f)[starts * S]
    receiver = chambers.start_supply(exp, u_f, starts * S)
    chambers.start_tubes(exp, u_f, starts * S)
    lengths = np.array([d.actuator_length[ids] for d in datas])
    travel0 = chambers.travel(lengths)
    tab = robot.tables
    out_q = np.zeros((W, H, J))
    out_p = np.zeros((W, H, tab.n_chambers))
    acc_q = np.zeros((W, J))
    acc_p = np.zeros_like(p)
    for step in range(H * S):
        f = starts * S + step
        step_windows(model, datas, ids, actuator_force(tab, p), mmods, qadr, dadr)
        # lengths after the step (joint transmissions: gear * q; others need kinematics)
        for w, d in enumerate(datas):
            mujoco.mj_kinematics(model, d)
            mujoco.mj_comPos(model, d)
            mujoco.mj_tendon(model, d)
            mujoco.mj_transmission(model, d)
            lengths[w] = d.actuator_length[ids]
        travel1 = chambers.travel(lengths)
        chambers.follow_supply(receiver, f)
        p = chambers.step(p, u_f[f], travel0, travel1)
        travel0 = travel1
        acc_p += p
        acc_q += np.array([d.qpos[qadr] for d in datas])
        if (step + 1) % S == 0:
            h = (step + 1) // S - 1
            out_p[:, h] = acc_p / S if exp.averaged else p
            out_q[:, h] = acc_q / S if exp.averaged else acc_q
            acc_p[:] = 0
            acc_q[:] = 0
    out_q[:] = out_q + reading_error(out_q, offset, scale)  # what the angle sensor reads
    idx = starts[:, None] + 1 + np.arange(H)[None]
    offset = pmods.sensor_offsets(exp.clock_at()[idx])
    if offset is not None:
        out_p += offset
    pred, meas = {}, {}
    for j, name in enumerate(robot.joint_names):
        pred[f"q.{name}"], meas[f"q.{name}"] = out_q[:, :, j].ravel(), exp.q[idx, j].ravel()
    for c, (a, ch) in enumerate(robot.chamber_names):
        pred[f"p_{ch}.{a}"], meas[f"p_{ch}.{a}"] = out_p[:, :, c].ravel(), exp.p[idx, c].ravel()
    return ReplayResult(pred, meas, exp.t[idx].ravel(), idx.ravel(), H)
