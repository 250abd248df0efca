"""Backlash (pneumatics/effects/backlash.py): a play between cylinder and link, in MuJoCo."""
import dataclasses

import mujoco
import numpy as np
import pytest

from pneumatics.effects.backlash import backlash_model, drive_pairs, set_drive_state
from pneumatics.effects.effect_set import EffectSet
from pneumatics.errors import PneumasimError, UnknownNameError
from workflow.rerun_log import RerunLogger
from pneumatics.robot import load_robot
from pneumatics.sim import Simulation

GAP = 0.03  # total play [rad]


@pytest.fixture(scope="module")
def arm2():
    return load_robot("arm2")


def backlash(gap=GAP, **more):
    return EffectSet(backlash={"elbow": {"gap_rad": gap}}, **more)


def command(k, amplitude=0.5):
    """Valve commands for control period k (10 ms): the elbow's valves reverse every 0.2 s,
    the shoulder's follow a slow sine; amplitude 0.5 V keeps the elbow inside its range."""
    s = 1.0 if (k // 20) % 2 == 0 else -1.0
    return [5 + 0.6 * np.sin(0.05 * k), 5 - 0.6 * np.sin(0.05 * k), 5 + amplitude * s, 5 - amplitude * s]


def run(sim, periods=200):
    """(periods, 2) link angles and (periods,) q_drive - q_link of the elbow (0 without play)."""
    k, _, dq, _ = drive_pairs(sim.model, sim.robot.joint_names)
    q, rel = [], []
    for i in range(periods):
        sim.set_command(command(i))
        sim.step(10)
        q.append(sim.observe().q)
        rel.append(sim.data.qpos[dq].sum() - sim.data.qpos[sim._qadr[k]].sum())
    return np.array(q), np.array(rel)


def test_play_is_kept_within_half_the_gap_and_the_cylinder_sees_the_drive(arm2):
    sim = Simulation(arm2, effects=backlash())
    _, rel = run(sim)
    # both contacts of the play are used on the reversals ...
    assert rel.max() > GAP / 2 - 1e-3 and rel.min() < -GAP / 2 + 1e-3
    # ... and the drive sinks into them only by the soft contact's give at impact: relative
    # speed x ~2 ms contact time constant (measured 4.5 mrad)
    assert np.abs(rel).max() - GAP / 2 < 8e-3
    # the chamber volumes follow the piston side: actuator_length = gear * q_drive
    k, _, dq, _ = drive_pairs(sim.model, arm2.joint_names)
    act = sim.model.actuator("elbow").id
    gear = sim.model.actuator_gear[act, 0]
    assert sim.data.actuator_length[act] == pytest.approx(gear * sim.data.qpos[dq[0]], abs=1e-15)
    # held against the joint limit at full pressure (3 N m): a static give below 1.5 mrad (measured 0.73)
    sim.set_command([5, 5, 9, 1])
    sim.step(400)
    static = sim.data.qpos[dq[0]] - sim.data.qpos[sim._qadr[k[0]]] - GAP / 2
    assert 0 < static < 1.5e-3


def test_link_stands_still_while_the_drive_crosses_the_dead_zone():
    """Nordin & Gutman's dead zone: after a force reversal the drive crosses the whole gap
    before the link moves; with no gravity and the shoulder braced nothing else acts on it."""
    arm2 = load_robot("arm2")  # its own: the plain simulation changes the robot's model
    sims = []
    for eff in (backlash(), EffectSet()):
        sim = Simulation(arm2, kernel="reference", effects=eff)
        sim.model.opt.gravity[:] = 0
        sim.model.eq_active0[sim.model.equality("brace_shoulder").id] = 1
        sim.reset()
        sims.append(sim)
    sim, plain = sims
    k, _, dq, _ = drive_pairs(sim.model, arm2.joint_names)
    set_drive_state(sim.model, sim.data, [0.0, 0.0], [0.0, 0.0], [0.0, 1.0])  # drive at +gap/2
    sim.sync()
    assert sim.data.qpos[dq[0]] == pytest.approx(GAP / 2)
    link = sim._qadr[k[0]]
    for s in sims:
        s.set_command([5, 5, 1, 9])  # reverse: the elbow cylinder now pushes towards negative q
    n = 0
    while sim.data.qpos[dq[0]] - sim.data.qpos[link] > -GAP / 2 and n < 200:
        sim.step(1)
        plain.step(1)
        assert sim.data.qpos[link] == 0.0  # the link does not move while the play is open
        n += 1
    assert 0 < n < 200
    for s in sims:
        s.step(50 - n)
    # after the contact the link follows, the drive ahead of it by the whole gap
    q_link, q_drive = sim.data.qpos[link], sim.data.qpos[dq[0]]
    assert q_link < -1e-3
    assert (q_drive - GAP / 2) - q_link == pytest.approx(-GAP, abs=1.5e-3)
    assert q_link > plain.data.qpos[1]  # and lags the arm without play


def test_tiny_gap_matches_the_model_without_backlash(arm2):
    """gap 1e-6 rad: the only differences left are the contact's compliance (~1 mrad under
    the elbow's torques, measured |q_drive - q_link| <= 0.5 mrad) and where the piston
    inertia sits; over 2 s they may not shift the links by more than 5 mrad (0.3 deg)."""
    q0, _ = run(Simulation(arm2))
    q1, rel = run(Simulation(arm2, effects=backlash(1e-6)))
    assert np.abs(rel).max() < 2e-3
    assert np.abs(q1 - q0).max() < 5e-3
    assert np.sqrt(np.mean((q1 - q0) ** 2)) < 1e-3
    assert np.ptp(q0[:, 1]) > 0.3  # the run does move the elbow


def test_both_kernels_agree_with_backlash(arm2):
    fast = Simulation(arm2, kernel="fast", effects=backlash())
    ref = Simulation(arm2, kernel="reference", effects=backlash())
    qf, rf = run(fast, 40)
    qr, rr_ = run(ref, 40)
    np.testing.assert_allclose(qf, qr, atol=1e-9)
    np.testing.assert_allclose(rf, rr_, atol=1e-9)
    np.testing.assert_allclose(fast.pressure, ref.pressure, rtol=1e-9)


def test_end_stop_friction_and_reset_work_on_top_of_backlash(arm2):
    eff = backlash(end_stop={"elbow": {"upper_intrusion_rad": 0.2}}, friction={"elbow": {"coulomb_nm": 0.05}})
    sim = Simulation(arm2, effects=eff)
    elbow = sim.model.joint("elbow").id
    assert sim.model.jnt_range[elbow, 1] == pytest.approx(arm2.joint_range()[1, 1] - 0.2)
    assert not sim.model.jnt_limited[sim.model.joint("elbow_drive").id]
    assert sim._fric[0, 0] == sim.model.jnt_dofadr[elbow]  # friction acts on the link
    sim.reset(qpos=[0.1, 0.4])
    _, _, dq, _ = drive_pairs(sim.model, arm2.joint_names)
    np.testing.assert_allclose(sim.observe().q, [0.1, 0.4])
    assert sim.data.qpos[dq[0]] == 0.4
    sim.set_command([5, 5, 9, 1])
    sim.step(600)
    assert sim.observe().q[1] == pytest.approx(arm2.joint_range()[1, 1] - 0.2, abs=0.03)


def test_keyframes_stay_valid_and_batches_of_states_can_be_set():
    robot = load_robot("humanoid38")
    model = backlash_model(robot, {"left_wrist_pitch": 0.02, "waist_yaw": {"gap_rad": 0.01}})
    assert model.nq == robot.model.nq + 2
    key = model.key("home").id
    qadr = [model.jnt_qposadr[model.joint(j).id] for j in robot.joint_names]
    np.testing.assert_array_equal(model.key_qpos[key, qadr], robot.model.key_qpos[key, robot.qpos_index])
    k, gap, dq, _ = drive_pairs(model, robot.joint_names)
    np.testing.assert_array_equal(model.key_qpos[key, dq], model.key_qpos[key, np.array(qadr)[k]])
    datas = [mujoco.MjData(model) for _ in range(2)]
    n = len(robot.joint_names)
    q, sign = np.full((2, n), 0.1), np.zeros((2, n))
    sign[0, k], sign[1, k] = 1.0, -1.0
    set_drive_state(model, datas, q, np.zeros((2, n)), sign)
    np.testing.assert_allclose(datas[0].qpos[dq], 0.1 + gap / 2)
    np.testing.assert_allclose(datas[1].qpos[dq], 0.1 - gap / 2)


@pytest.mark.parametrize("gap", [0.0, -0.01, float("nan"), float("inf")])
def test_bad_gap_names_joint_and_value(arm2, gap):
    with pytest.raises(PneumasimError, match=r"elbow.*gap_rad|gap_rad.*elbow"):
        Simulation(arm2, effects=backlash(gap))


def test_bad_names_and_models_give_clear_errors(arm2):
    with pytest.raises(UnknownNameError, match="shoulder"):
        Simulation(arm2, effects=EffectSet(backlash={"elbw": {"gap_rad": GAP}}))
    with pytest.raises(PneumasimError, match="gap_rad"):
        Simulation(arm2, effects=EffectSet(backlash={"elbow": {"gap": GAP}}))
    with pytest.raises(PneumasimError, match="mjcf_path"):
        backlash_model(dataclasses.replace(arm2, mjcf_path=None), {"elbow": GAP})
    with pytest.raises(PneumasimError, match="joint-transmission"):
        backlash_model(load_robot("humanoid38"), {"left_knee": 0.01})
    sim = Simulation(arm2, effects=backlash())
    with pytest.raises(PneumasimError, match="shape"):
        set_drive_state(sim.model, sim.data, [0.0], [0.0], [1.0])


def test_rerun_logger_records_the_link_angles_of_a_backlash_simulation(arm2):
    sim = Simulation(arm2, effects=backlash())
    sim.set_command([5, 5, 9, 1])
    with RerunLogger(arm2) as logger:
        sim.step(50)
        logger.log_frame(sim)
        np.testing.assert_array_equal(logger._qpos[0, logger._qadr], sim.observe().q)
        logger.flush()
