"""Paper 002 §VI-B, Fig. 8: the humanoid's left hand follows a target moving in 3-D.

The seven left-arm joints (shoulder pitch, roll, yaw, elbow, forearm roll, wrist pitch and
yaw; the paper's q in R^7) run the end-effector law of :mod:`controllers.end_effector`
(tau = J^T (x* - x) + null-space pull to mid-range, Jacobians from pytorch-kinematics), its
torques turned into valve commands through each actuator's moment arm and area; every other
joint holds its pose under PIDF.  All valves go through the per-valve linearising transform
from the orifice calibration.  The target starts at the hand, glides over 1 s onto a slow 3-D
Lissajous curve (8 cm each way, as an experimenter's hand would) centred a tenth of the way
from the hand towards the shoulder (targets up to 0.50 m from the shoulder, near the edge of
the workspace but within reach), and stops for the last seconds.
"""
from __future__ import annotations

import mujoco
import numpy as np

from controllers.end_effector import EndEffectorCfg, EndEffectorController
from controllers.linearize import Linearized
from pneumatics.runner import run as run_loop
from pneumatics.sim import Simulation

from ._humanoid import START_PRESSURE_PA, calibrated_linearizer, pidf_gains, range_test
from .common import main, plt

SUMMARY = "§VI-B: the humanoid's hand follows a moving 3-D target (J^T law + null space), Cartesian error"
FITTED_MODEL = "humanoid38"  # takes --fitted: a doctor's model.toml of humanoid38 (scenarios.common)
ARM = ["left_shoulder_pitch", "left_shoulder_roll", "left_shoulder_yaw", "left_elbow",
       "left_forearm_roll", "left_wrist_pitch", "left_wrist_yaw"]
HAND = "left_palm"
AMPLITUDE_M = np.array([0.08, 0.08, 0.08])
CENTRE_TOWARDS_SHOULDER = 0.1
FREQ_HZ = np.array([0.13, 0.19, 0.23])
LIMIT_MARGIN_DEG = 1.0


class MovingTarget:
    """x*(t): from ``start``, faded in over 1 s, a Lissajous curve about ``centre``; frozen
    after ``stop_s``."""

    def __init__(self, start, centre, stop_s: float):
        self.start, self.centre, self.stop_s = np.asarray(start, float), np.asarray(centre, float), stop_s

    def __call__(self, t: float) -> np.ndarray:
        t = min(t, self.stop_s)
        fade = min(t, 1.0) ** 2 * (3 - 2 * min(t, 1.0))
        return self.start + fade * (self.centre - self.start + AMPLITUDE_M * np.sin(2 * np.pi * FREQ_HZ * t))

    def velocity(self, t: float) -> np.ndarray:
        if t >= self.stop_s:
            return np.zeros(3)
        h = 1e-3
        return (self(t + h) - self(max(t - h, 0.0))) / (t + h - max(t - h, 0.0))


class Hold:
    """A constant joint reference (the pose to hold)."""

    def __init__(self, q):
        self.q = np.asarray(q, float)

    def reference(self, t: float) -> np.ndarray:
        return self.q


def run(ctx):
    duration = 6.0 if ctx.fast else 30.0
    stop_s = duration - (2.0 if ctx.fast else 5.0)
    robot = ctx.load_robot("humanoid38")
    lin, _, _ = calibrated_linearizer(robot, ctx.fast)
    gains = pidf_gains(range_test(robot, lin, one_at_a_time=False))
    sim = Simulation(robot)
    sim.reset(pressure_pa=START_PRESSURE_PA)
    q0 = sim.observe().q.copy()
    arm_idx = [robot.joint_names.index(j) for j in ARM]
    rng = robot.joint_range()
    q0[arm_idx] = rng[arm_idx].mean(axis=1)  # start at the mid-range posture
    sim.reset(qpos=q0, pressure_pa=START_PRESSURE_PA)
    hold = gains.build(Hold(q0), np.full(2 * len(robot.actuator_names), 5.0))
    cfg = EndEffectorCfg()
    ctrl = EndEffectorController(robot, HAND, ARM, None, cfg, hold)
    data = mujoco.MjData(robot.model)
    data.qpos[robot.qpos_index] = q0
    mujoco.mj_kinematics(robot.model, data)
    shoulder = data.xpos[robot.model.jnt_bodyid[robot.model.joint(ARM[0]).id]]
    start = ctrl.hand(q0)
    target = MovingTarget(start, start + CENTRE_TOWARDS_SHOULDER * (shoulder - start), stop_s)
    ctrl.target = target
    logger = ctx.rerun_logger(robot, "humanoid38 reach")
    rec = run_loop(sim, Linearized(ctrl, lin), duration, logger=logger, seed=3)
    if logger is not None:
        logger.close()
    q = rec.matrix("q", robot.joint_names)
    hand = np.array([ctrl.hand(qk) for qk in q])
    goal = np.array([target(t) for t in rec.time])
    err_mm = 1e3 * np.linalg.norm(hand - goal, axis=1)
    final = rec.time >= duration - 1.0
    margin_deg = np.degrees(np.minimum(q[:, arm_idx] - rng[arm_idx, 0], rng[arm_idx, 1] - q[:, arm_idx]))
    at_limit = np.any(margin_deg < LIMIT_MARGIN_DEG, axis=0)

    fig, axes = plt.subplots(2, 2, figsize=(12, 7))
    for k, name in enumerate("xyz"):
        axes[0, 0].plot(rec.time, goal[:, k], "k--", lw=1)
        axes[0, 0].plot(rec.time, hand[:, k], lw=1.2, label=f"hand {name}")
    axes[0, 0].set_ylabel("position [m] (target dashed)")
    axes[0, 0].legend(fontsize=8)
    axes[0, 1].plot(goal[:, 0], goal[:, 2], "k--", lw=1, label="target")
    axes[0, 1].plot(hand[:, 0], hand[:, 2], lw=1.2, label="hand")
    axes[0, 1].set_xlabel("x forward [m]")
    axes[0, 1].set_ylabel("z up [m]")
    axes[0, 1].set_aspect("equal", adjustable="datalim")
    axes[0, 1].legend(fontsize=8)
    axes[1, 0].plot(rec.time, err_mm)
    axes[1, 0].set_ylabel("Cartesian error [mm]")
    axes[1, 0].set_xlabel("time [s]")
    for k, j in enumerate(ARM):
        axes[1, 1].plot(rec.time, margin_deg[:, k], lw=1, label=j.replace("left_", ""))
    axes[1, 1].axhline(LIMIT_MARGIN_DEG, color="r", lw=0.8)
    axes[1, 1].set_ylabel("distance to nearest joint limit [deg]")
    axes[1, 1].set_xlabel("time [s]")
    axes[1, 1].legend(fontsize=7, ncol=2)
    fig.suptitle("humanoid38: left hand to a moving target, tau = J^T (x* - x) + null-space posture "
                 "(paper 002 §VI-B)")
    fig.tight_layout()
    ctx.savefig(fig, "reach.png")
    ctx.save_recording(rec, "reach.csv")
    return {
        "reach_err_mean_mm": float(err_mm.mean()),
        "reach_err_final_mm": float(err_mm[final].mean()),
        "reach_err_max_mm": float(err_mm.max()),
        "target_travel_mm": float(1e3 * np.ptp(goal, axis=0).max()),
        "arm_joints_at_limit": int(at_limit.sum()),
        "min_limit_margin_deg": float(margin_deg.min()),
        "duration_s": duration,
    }


if __name__ == "__main__":
    main(__name__)
