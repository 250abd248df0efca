"""The bench's anchor is right: MuJoCo's C loop and a Python loop of mj_step, given the ctrl
sequence a fluid-layer run produced, make the same trajectory — and that trajectory is the
fluid-layer run's own (the forces, not the fluid layer, move the arm)."""
import mujoco
import numpy as np
from mujoco import rollout

from pneumasim.bench_paths import PERIOD, recorded_inputs, reset_bench_state, shipped_controller
from pneumatics.robot import load_robot
from pneumatics.sim import Simulation


def test_c_and_python_stepping_of_the_recorded_forces_follow_the_simulation():
    sim = Simulation(load_robot("arm2"))
    commands, ctrl, state0 = recorded_inputs(sim, 0.5)
    assert commands.shape == (50, 4) and ctrl.shape == (500, sim.model.nu)
    assert np.ptp(commands, axis=0).max() > 0.5          # the PIDF moved the valves
    reset_bench_state(sim)
    for u in commands:
        sim.set_command(u)
        sim.step(PERIOD)
    looped = sim.data.qpos.copy()
    reset_bench_state(sim)
    played = sim.play(commands, PERIOD)  # the bench's open loop
    np.testing.assert_array_equal(played.qpos[-1], looped)
    m = sim.model
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    states, _ = rollout.rollout(m, mujoco.MjData(m), state0[None], ctrl[None],
                                control_spec=int(mujoco.mjtState.mjSTATE_CTRL))
    d = mujoco.MjData(m)
    mujoco.mj_setState(m, d, state0, spec)
    for row in ctrl:
        d.ctrl[:] = row
        mujoco.mj_step(m, d)
    q_c = states[0, -1, 1:1 + m.nq]                      # FULLPHYSICS: time, qpos, ...
    np.testing.assert_allclose(q_c, d.qpos, atol=1e-12)
    np.testing.assert_allclose(d.qpos, sim.data.qpos, atol=1e-9)


def test_the_humanoid_has_a_shipped_closed_loop_controller():
    robot = load_robot("humanoid38")
    ctrl = shipped_controller(robot, 1.0)
    assert ctrl.reference(0.5).shape == (len(robot.joint_names),)
