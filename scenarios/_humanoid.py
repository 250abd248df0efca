"""humanoid38 set-ups shared by the tracking and reaching scenarios (paper 002 §VI): the
per-valve calibration and linearising transform, the sinusoid range test that sets each
joint's gain scaling, and the PIDF gains built from it."""
from __future__ import annotations

import numpy as np

from controllers.linearize import Linearized, ValveLinearizer
from controllers.pid import PIDFCfg
from identification.orifice import (
    DEFAULT_COMMANDS_V,
    calibrate_robot,
    calibration_errors,
)
from pneumatics.errors import ConfigError
from pneumatics.runner import OpenLoop
from pneumatics.runner import run as run_loop
from pneumatics.sim import Simulation

#: master gains, tuned by hand on the 60 s reference as the paper did (§VI-A); multiplied per
#: joint by the gain scaling 1 / (range per volt) of the sinusoid test
MASTER = {"kp": 3.0, "kd": 0.1, "ki": 2.0, "kf_v_per_bar": 0.5}
RANGE_TEST_AMPLITUDE_V = 1.0
RANGE_TEST_HZ = 1.0
START_PRESSURE_PA = 5.0e5
FAST_COMMANDS_V = np.array([0.0, 2.0, 4.0, 4.5, 4.7, 4.8, 4.9, 5.0, 5.1, 5.2, 5.3, 5.5, 6.0, 8.0, 10.0])


def calibrated_linearizer(robot, fast: bool, seed: int = 0):
    """Orifice calibration of every valve (static volume, all chambers at once) and the
    linearising transform built from it; returns (linearizer, calibration, error arrays)."""
    commands = FAST_COMMANDS_V if fast else DEFAULT_COMMANDS_V
    cal = calibrate_robot(robot, commands, seed=seed, duration_scale=0.4 if fast else 1.0)
    return ValveLinearizer.from_calibration(cal), cal, calibration_errors(cal, robot.tables.valve)


def range_test(robot, linearizer, joints=None, *, one_at_a_time: bool = True, cycles: int = 2):
    """Paper 002 §VI-A: a sinusoidal command to each joint, the others at their (canonical)
    null; the range of motion per volt of amplitude [rad/V] of each joint.

    The range is twice the amplitude of the response's Fourier component at the test
    frequency over whole cycles (lock-in), so the slow sag of a joint left at null does not
    count.  ``one_at_a_time=False`` drives all joints together at distinct frequencies
    (0.8-1.6 Hz, separated by the lock-in): one run instead of 38 (the ``--fast`` version).
    """
    n = len(robot.joint_names)
    joints = list(range(n)) if joints is None else list(joints)
    sim = Simulation(robot)
    gain = np.full(n, np.nan)
    groups = [[j] for j in joints] if one_at_a_time else [joints]
    for group in groups:
        freq = np.full(n, RANGE_TEST_HZ)
        if len(group) > 1:
            freq[group] = np.linspace(0.8, 1.6, len(group))[np.random.default_rng(0).permutation(len(group))]
        duration = cycles / freq[group].min()

        def commands(t, group=group, freq=freq):
            e = np.zeros(n)
            e[group] = RANGE_TEST_AMPLITUDE_V * np.sin(2 * np.pi * freq[group] * t)
            u = np.empty(2 * n)
            u[0::2], u[1::2] = 5.0 + e, 5.0 - e
            return linearizer(u)

        sim.reset(pressure_pa=START_PRESSURE_PA)
        rec = run_loop(sim, OpenLoop(commands), duration, noise=False)
        for j in group:
            q = rec[f"q.{robot.joint_names[j]}"]
            t = rec.time
            m = t < cycles / freq[j]
            z = np.sum((q[m] - q[m].mean()) * np.exp(-2j * np.pi * freq[j] * t[m])) * 2 / m.sum()
            gain[j] = 2 * abs(z) / (2 * RANGE_TEST_AMPLITUDE_V)
    return gain


def pidf_gains(range_per_volt: np.ndarray, master: dict | None = None) -> PIDFCfg:
    """PIDF gains: master gains times each joint's scaling factor 1 / (range per volt)."""
    m = {**MASTER, **(master or {})}
    scale = 1.0 / np.maximum(range_per_volt, 1e-3)
    return PIDFCfg(kp_v_per_rad=tuple(m["kp"] * scale), kd_v_s_per_rad=tuple(m["kd"] * scale),
                   ki_v_per_rad_s=tuple(m["ki"] * scale), kf_v_per_bar=(m["kf_v_per_bar"],),
                   integral_limit_v=4.0)


def linearized_pidf(cfg: PIDFCfg, reference, linearizer):
    """PIDF on canonical valves (null 5 V), through the linearising transform."""
    return Linearized(cfg.build(reference, np.full(linearizer.n_chambers, 5.0)), linearizer)


class ModelFeedforward:
    """Model-based PIDF (paper 002 eqs. 16-17) for the humanoid, with the rigid-body model in
    MuJoCo instead of a regression: the joint torques the reference needs (``mj_inverse`` at
    q*, qd*, qdd* from the reference's smoothing spline) become, through each actuator's moment
    arm and areas, a pressure-difference target d^ [bar] that is fed forward as k_F d^ on top of
    the PIDF's canonical commands (u+ = 5 + e - k_F (d - d^)).  ``lead_s`` evaluates d^ a
    little ahead to cover the air's lag."""

    def __init__(self, inner, robot, reference, kf_v_per_bar, lead_s: float = 0.03):
        import mujoco

        self.inner, self.robot, self.lead_s = inner, robot, lead_s
        self.kf = np.broadcast_to(np.asarray(kf_v_per_bar, float), (len(robot.joint_names),))
        self.reference = inner.reference
        m = robot.model
        d = mujoco.MjData(m)
        self.time = reference.time
        q, qd, qdd = reference.derivatives(self.time)
        moment = np.zeros((m.nu, m.nv))
        dof, ids = robot.dof_index, robot.actuator_ids  # actuator k drives joint k (named after it)
        if [m.actuator(i).name for i in ids] != list(robot.joint_names):
            raise ConfigError(f"{robot.name}: ModelFeedforward needs one actuator per joint, named after it, in joint order")
        self.force = np.empty((self.time.size, len(robot.joint_names)))
        for k in range(self.time.size):
            d.qpos[robot.qpos_index], d.qvel[dof], d.qacc[dof] = q[k], qd[k], qdd[k]
            mujoco.mj_inverse(m, d)
            mujoco.mju_sparse2dense(moment, d.actuator_moment, d.moment_rownnz, d.moment_rowadr, d.moment_colind)
            self.force[k] = d.qfrc_inverse[dof] / moment[ids, dof]
        tab = robot.tables
        self.area_a, self.area_b, self.room_pa = tab.area_a, tab.area_b, tab.room_pa

    def reset(self):
        self.inner.reset()

    def __call__(self, t: float, obs) -> np.ndarray:
        u = np.array(self.inner(t, obs), float)
        tt = min(t + self.lead_s, self.time[-1])
        force = np.array([np.interp(tt, self.time, self.force[:, j]) for j in range(self.force.shape[1])])
        # F = A_b d + (A_a - A_b)(p_a - p_room): the d that gives the force at the measured p_a
        d_hat = (force - (self.area_a - self.area_b) * (obs.p_a - self.room_pa)) / self.area_b / 1e5
        u[0::2] += self.kf * d_hat
        u[1::2] -= self.kf * d_hat
        return np.clip(u, 0.0, 10.0)


def linearized_model_pidf(cfg: PIDFCfg, reference, linearizer, robot, lead_s: float = 0.03):
    """:class:`ModelFeedforward` on the PIDF, on canonical valves through the linearising transform."""
    inner = cfg.build(reference, np.full(linearizer.n_chambers, 5.0))
    return Linearized(ModelFeedforward(inner, robot, reference, cfg.kf_v_per_bar, lead_s), linearizer)
