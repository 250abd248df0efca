"""End-effector control (paper 002 §VI-B): Jacobians vs MuJoCo, signs of the J^T law, the
null-space term, torques through the actuators; the humanoid scenarios' --fast runs (slow)."""
import mujoco
import numpy as np
import pytest

from controllers.end_effector import (
    EndEffectorCfg,
    EndEffectorController,
    null_space_torque,
    task_torque,
)
from pneumatics.robot import load_robot
from pneumatics.sim import Observation
from scenarios.common import run_scenario
from scenarios.humanoid38_reach import ARM, HAND, Hold

CFG = EndEffectorCfg()


@pytest.fixture(scope="module")
def humanoid():
    return load_robot("humanoid38")


class _Null:
    """A posture controller that leaves every valve at the canonical null."""

    def reset(self):
        pass

    def __call__(self, t, obs):
        return np.full(76, 5.0)


def make(humanoid, target=(0.3, 0.2, 0.9)):
    return EndEffectorController(humanoid, HAND, ARM, lambda t: np.asarray(target), CFG, _Null())


def random_q(robot, rng):
    lo, hi = robot.joint_range().T
    return rng.uniform(lo, hi)


def test_jacobian_matches_mj_jacSite(humanoid, rng):
    ctrl = make(humanoid)
    m, d = humanoid.model, mujoco.MjData(humanoid.model)
    site = m.site(HAND).id
    for _ in range(5):
        q = random_q(humanoid, rng)
        d.qpos[humanoid.qpos_index] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        jacp = np.zeros((3, m.nv))
        mujoco.mj_jacSite(m, d, jacp, None, site)
        J = ctrl.kin.jacobian(q[ctrl.chain_in_robot], position_only=True)
        assert np.allclose(J, jacp[:, humanoid.dof_index[ctrl.chain_in_robot]], atol=1e-9)
        assert np.allclose(ctrl.hand(q), d.site_xpos[site], atol=1e-9)


def test_transpose_law_pulls_the_hand_towards_the_target(humanoid, rng):
    """Apply tau = J^T K (x* - x) as joint torques on the bare rigid body (no gravity, no air):
    the hand's acceleration J M^-1 J^T K (x* - x) points towards the target."""
    m = humanoid.model
    d = mujoco.MjData(m)
    ctrl = make(humanoid)
    m_opt_gravity = m.opt.gravity.copy()
    m.opt.gravity[:] = 0
    try:
        for _ in range(3):
            q = random_q(humanoid, rng)
            lo, hi = humanoid.joint_range().T
            q = np.clip(q, lo + 0.3 * (hi - lo), hi - 0.3 * (hi - lo))  # away from the limits
            x = ctrl.hand(q)
            goal = x + np.array([0.05, -0.03, 0.04])
            J = ctrl.kin.jacobian(q[ctrl.chain_in_robot], position_only=True)[:, ctrl.arm_in_chain]
            tau = task_torque(J, goal - x, np.zeros(3), np.zeros(3), CFG)
            mujoco.mj_resetData(m, d)
            d.qpos[humanoid.qpos_index] = q
            d.qfrc_applied[humanoid.dof_index[ctrl.arm_in_robot]] = tau
            for _ in range(20):
                mujoco.mj_step(m, d)
            moved = ctrl.hand(d.qpos[humanoid.qpos_index]) - x
            assert moved @ (goal - x) > 0.5 * np.linalg.norm(moved) * np.linalg.norm(goal - x)
    finally:
        m.opt.gravity[:] = m_opt_gravity


def test_null_space_term_does_not_push_the_hand(humanoid, rng):
    ctrl = make(humanoid)
    q = random_q(humanoid, rng)
    J = ctrl.kin.jacobian(q[ctrl.chain_in_robot], position_only=True)[:, ctrl.arm_in_chain]
    tau = null_space_torque(J, rng.normal(size=7), np.zeros(7), CFG)
    # N = I - J^+ J is symmetric, so J^+^T tau = task force of the posture term ~ 0
    force = np.linalg.pinv(J).T @ tau
    assert np.linalg.norm(force) < 0.02 * np.linalg.norm(tau) / np.linalg.norm(J, 2)
    assert np.linalg.norm(tau) > 0


def test_torques_become_antiphase_valve_commands_through_the_actuators(humanoid):
    ctrl = make(humanoid)
    q = np.zeros(len(humanoid.joint_names))
    q[ctrl.arm_in_robot] = ctrl.posture
    ctrl.reset()
    p = np.full(76, 4e5)
    obs = Observation(0.0, q, np.zeros_like(q), p)
    u = ctrl(0.0, obs)
    tau = ctrl.last["tau"]
    e = u[2 * ctrl.arm_act] - 5.0
    assert np.allclose(u[2 * ctrl.arm_act + 1] - 5.0, -e)
    # equal pressures: a single-rod cylinder already pushes (A_a - A_b)(p - p_room) > 0, so the
    # command is positive where the torque asked for exceeds that push
    r, _ = ctrl._model_terms(q)
    tab = humanoid.tables
    push = (tab.area_a - tab.area_b)[ctrl.arm_act] * (4e5 - tab.room_pa) * r
    assert np.all(np.sign(e) == np.sign(tau - push))
    others = np.setdiff1d(np.arange(76), np.r_[2 * ctrl.arm_act, 2 * ctrl.arm_act + 1])
    assert np.all(u[others] == 5.0)


def test_hold_reference_is_exposed(humanoid):
    ctrl = EndEffectorController(humanoid, HAND, ARM, lambda t: np.zeros(3), CFG, _Null())
    assert ctrl.reference(0.0).shape == (38,)
    assert np.allclose(Hold(np.ones(3)).reference(1.0), 1.0)


def test_reach_fast_scenario(tmp_path):
    m = run_scenario("humanoid38_reach", tmp_path, fast=True, quiet=True)
    assert m["reach_err_final_mm"] < 15.0 and m["reach_err_mean_mm"] < 30.0  # measured 5.5, 9.8
    assert m["arm_joints_at_limit"] == 0
    assert (tmp_path / "reach.png").stat().st_size > 10_000


def test_tracking_fast_scenario(tmp_path):
    m = run_scenario("humanoid38_tracking", tmp_path, fast=True, quiet=True)
    assert m["median_err_pct_range"] < 4.0 and 0 <= m["lag_ms"] <= 150     # measured 2.3 %, 30 ms
    assert m["median_err_pct_range_pidf"] < 8.0                                # measured 4.7 %
    assert m["calib_area_rel_error_median"] < 0.05
    assert m["predicted_lag_ms_tubes"] > m["lag_ms_refined_pidf"]              # tubes add lag (paper §VI-A)
    assert (tmp_path / "tracking.png").stat().st_size > 10_000
