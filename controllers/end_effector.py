"""End-effector control of a pneumatic arm (paper 002 §VI-B): the hand to a moving 3-D target.

For the arm joints q (n,), hand position x = f(q) and translational Jacobian J(q) (3, n) from
pytorch-kinematics (:class:`controllers.kinematics.ArmKinematics`, built from our MJCF), the
joint torques are (002 §VI-B, with a Cartesian damping and optional terms named below)::

    tau = J^T (K_p (x* - x) + K_d (xd* - xd) + K_i int (x* - x) dt)       task: a spring to the target
        + N(q) (K_n (q_bar - q) - D_n qd)                                 null space: mid-range posture
        + g(q)                                                            gravity (optional, from MuJoCo)

with N = I - J^+ J (J^+ the damped pseudo-inverse), so the posture term does not move the hand
to first order.  The paper uses the spring and the null-space term; the damping, the small
integral and the gravity feed-forward are ours (the simulated arm has no friction to hide
behind, and the paper notes "two of the joints had more friction than a linear feedback
controller could handle well").

The torques become valve commands *through the actuators*: actuator j's force F*_j =
tau_j / r_j(q), with r_j the moment arm MuJoCo computes for its transmission (constant
gear, or the pin-to-pin tendon); its pressure difference error
(F*_j - F_j) / A_j, with F_j = A_a p_a - A_b p_b - (A_a - A_b) p_room from the measured pressures,
drives the two valves in antiphase around the canonical null, as PIDF's force loop (002 eq. 15)::

    u_a = 5 + k_F (F* - F) / (A 1e5 Pa),     u_b = 5 - k_F (F* - F) / (A 1e5 Pa)     [V]

The other joints of the robot are left to a posture controller (``hold``), e.g. a PIDF.
Commands are canonical (null 5 V): wrap the controller in :class:`controllers.linearize.Linearized`
for real valves.
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from pneumatics.config import spec
from pneumatics.errors import UnknownNameError

from .kinematics import ArmKinematics


@dataclass(frozen=True, kw_only=True)
class EndEffectorCfg:
    """Gains of the end-effector controller."""

    kp_n_per_m: float = spec(250.0, "task stiffness K_p", "N/m")
    kd_n_s_per_m: float = spec(3.0, "task damping K_d", "N s/m")
    ki_n_per_m_s: float = spec(200.0, "task integral K_i", "N/(m s)")
    integral_limit_n: float = spec(30.0, "clamp of the integral force", "N")
    null_kp_nm_per_rad: float = spec(1.0, "null-space posture stiffness K_n", "N m/rad")
    null_kd_nm_s_per_rad: float = spec(0.02, "null-space damping D_n", "N m s/rad")
    gravity_compensation: bool = spec(True, "add the model's gravity torques g(q)")
    kf_v_per_bar: float = spec(1.0, "force loop: volts per bar of pressure-difference error", "V/bar")
    damping_lambda_m: float = spec(0.02, "damping of the pseudo-inverse in the null-space projector", "m")
    deriv_filter_s: float = spec(0.02, "low-pass time constant of the differentiated joint angles", "s")
    rate_hz: float = spec(100.0, "control rate", "Hz")


def task_torque(J, x_err, xd_err, force_integral, cfg: EndEffectorCfg):
    """tau = J^T (K_p x_err + K_d xd_err + integral force): (n,) from J (3, n) and (3,) vectors."""
    f = cfg.kp_n_per_m * np.asarray(x_err) + cfg.kd_n_s_per_m * np.asarray(xd_err) + force_integral
    return np.asarray(J).T @ f


def null_space_torque(J, q_err, qd, cfg: EndEffectorCfg):
    """N(q) (K_n q_err - D_n qd), N = I - J^+ J with a damped pseudo-inverse: (n,)."""
    J = np.asarray(J)
    lam2 = cfg.damping_lambda_m ** 2
    j_pinv = J.T @ np.linalg.inv(J @ J.T + lam2 * np.eye(J.shape[0]))
    N = np.eye(J.shape[1]) - j_pinv @ J
    return N @ (cfg.null_kp_nm_per_rad * np.asarray(q_err) - cfg.null_kd_nm_s_per_rad * np.asarray(qd))


class EndEffectorController:
    """Hand of a robot to ``target(t) -> (3,)`` world position [m].

    Args:
      robot: :class:`pneumatics.robot.Robot`.
      end_site: site (or body) of the hand, e.g. ``"left_palm"``.
      arm_joints: names of the controlled joints (a sub-chain from the root to ``end_site``).
      target: callable t -> (3,) target position, with optional ``velocity(t) -> (3,)``.
      posture: (n_arm,) default posture q_bar [rad] (default: the middle of each joint's range).
      hold: controller giving canonical commands (n_ch,) for all joints (e.g. a PIDF holding a
        pose); its commands for the arm's actuators are replaced.
    """

    def __init__(self, robot, end_site: str, arm_joints, target, cfg: EndEffectorCfg, hold, posture=None):
        self.robot, self.cfg, self.target, self.hold = robot, cfg, target, hold
        self.kin = ArmKinematics(robot.model, end_site)
        for j in arm_joints:
            if j not in self.kin.joint_names:
                raise UnknownNameError(f"joint on the chain to {end_site!r}", j, self.kin.joint_names)
        self.arm_joints = list(arm_joints)
        self.chain_in_robot = np.array([robot.joint_names.index(j) for j in self.kin.joint_names])
        self.arm_in_chain = np.array([self.kin.joint_names.index(j) for j in arm_joints])
        self.arm_in_robot = np.array([robot.joint_names.index(j) for j in arm_joints])
        act = robot.actuator_names
        missing = [j for j in arm_joints if j not in act]
        if missing:
            raise UnknownNameError("actuator (named after its joint)", missing[0], act)
        self.arm_act = np.array([act.index(j) for j in arm_joints])
        rng = robot.joint_range()[self.arm_in_robot]
        self.posture = rng.mean(axis=1) if posture is None else np.asarray(posture, float)
        self.model = robot.model
        self.data = mujoco.MjData(robot.model)
        self._moment = np.zeros((robot.model.nu, robot.model.nv))
        tab = robot.tables
        self.area_a, self.area_b, self.room_pa = tab.area_a[self.arm_act], tab.area_b[self.arm_act], tab.room_pa
        self.reset()

    def reset(self):
        self.hold.reset()
        self._last_q = None
        self._qd = np.zeros(len(self.arm_joints))
        self._integral = np.zeros(3)
        self.last = {}

    def reference(self, t: float) -> np.ndarray:
        return self.hold.reference(t) if hasattr(self.hold, "reference") else np.zeros(len(self.robot.joint_names))

    def hand(self, q_robot) -> np.ndarray:
        """(3,) hand position from the robot's joint angles (pytorch-kinematics)."""
        return self.kin.fk(np.asarray(q_robot)[self.chain_in_robot])

    def _model_terms(self, q_robot):
        """Moment arms r_j (n_arm,) [m or 1] and gravity torques (n_arm,) [N m] at q, from the
        MuJoCo model."""
        m, d = self.model, self.data
        d.qpos[self.robot.qpos_index] = q_robot
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)
        mujoco.mju_sparse2dense(self._moment, d.actuator_moment, d.moment_rownnz, d.moment_rowadr, d.moment_colind)
        dof = self.robot.dof_index[self.arm_in_robot]
        ids = self.robot.actuator_ids[self.arm_act]
        return self._moment[ids, dof], d.qfrc_bias[dof].copy()

    def __call__(self, t: float, obs) -> np.ndarray:
        c = self.cfg
        dt = 1.0 / c.rate_hz
        u = np.array(self.hold(t, obs), float)
        q_chain = obs.q[self.chain_in_robot]
        q_arm = obs.q[self.arm_in_robot]
        if self._last_q is None:
            self._last_q = q_arm.copy()
        alpha = dt / (c.deriv_filter_s + dt)
        self._qd += alpha * ((q_arm - self._last_q) / dt - self._qd)
        self._last_q = q_arm.copy()
        x = self.kin.fk(q_chain)
        J = self.kin.jacobian(q_chain, position_only=True)[:, self.arm_in_chain]
        x_star = np.asarray(self.target(t), float)
        xd_star = np.asarray(self.target.velocity(t), float) if hasattr(self.target, "velocity") else np.zeros(3)
        x_err = x_star - x
        self._integral = np.clip(self._integral + c.ki_n_per_m_s * x_err * dt, -c.integral_limit_n, c.integral_limit_n)
        tau = task_torque(J, x_err, xd_star - J @ self._qd, self._integral, c)
        r, g = self._model_terms(obs.q)
        tau += null_space_torque(J, self.posture - q_arm, self._qd, c)
        if c.gravity_compensation:
            tau += g
        force_star = tau / r
        pa, pb = obs.p_a[self.arm_act], obs.p_b[self.arm_act]
        force = self.area_a * pa - self.area_b * pb - (self.area_a - self.area_b) * self.room_pa
        e = c.kf_v_per_bar * (force_star - force) / (0.5 * (self.area_a + self.area_b) * 1e5)
        u[2 * self.arm_act] = 5.0 + e
        u[2 * self.arm_act + 1] = 5.0 - e
        self.last = {"x": x, "x_star": x_star, "tau": tau}
        return np.clip(u, 0.0, 10.0)
