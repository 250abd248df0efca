"""A robot restricted to some of its joints (pneumatics.robot_subset): the locked bodies stay
where the home pose holds them and keep their mass; the model is saved and steps cleanly."""
import mujoco
import numpy as np
import pytest

import models
from pneumatics.errors import ConfigError, UnknownNameError
from pneumatics.params import load_fluid
from pneumatics.robot import assemble_robot, compile_mjcf, load_robot
from pneumatics.robot_subset import actuated_joints, restricted_robot
from pneumatics.sim import Simulation
from scenarios._humanoid_cases import SUBSETS


@pytest.fixture(scope="module")
def humanoid():
    return load_robot("humanoid38")


@pytest.fixture(scope="module")
def left_arm(humanoid):
    return restricted_robot(humanoid, SUBSETS["left_arm"], "left_arm")


def _home(robot):
    d = mujoco.MjData(robot.model)
    mujoco.mj_resetDataKeyframe(robot.model, d, robot.model.key("home").id)
    mujoco.mj_forward(robot.model, d)
    return d


def test_the_part_has_its_joints_and_their_actuators_alone(left_arm):
    assert left_arm.name == "humanoid38[left_arm]"
    assert left_arm.joint_names == list(SUBSETS["left_arm"])
    assert left_arm.actuator_names == list(SUBSETS["left_arm"])
    assert left_arm.tables.n_chambers == 16
    assert left_arm.model.nq == left_arm.model.nv == 8
    assert all(js == {a} for a, js in actuated_joints(left_arm).items())


def test_every_body_stands_where_the_home_pose_puts_it(humanoid, left_arm):
    """The locked joints' home angles (shoulders, elbows, hips and knees are bent there) are
    built into their bodies' frames: every body's world pose is the whole robot's."""
    full, part = _home(humanoid), _home(left_arm)
    for b in range(humanoid.model.nbody):
        name = humanoid.model.body(b).name
        k = left_arm.model.body(name).id
        assert np.allclose(part.xpos[k], full.xpos[b], atol=1e-12), name
        assert np.allclose(part.xmat[k], full.xmat[b], atol=1e-12), name


def test_the_kept_joints_carry_the_locked_bodies_masses(humanoid, left_arm):
    """Inverse dynamics at the home pose with the arm moving and every other joint still: the
    arm's joint torques are the whole robot's (same masses, same inertias, same gravity)."""
    rng = np.random.default_rng(0)
    full, part = _home(humanoid), _home(left_arm)
    dofs = humanoid.dof_index[[humanoid.joint_names.index(n) for n in left_arm.joint_names]]
    qd, qdd = rng.normal(0, 1.0, 8), rng.normal(0, 5.0, 8)
    full.qvel[:], full.qacc[:] = 0.0, 0.0
    full.qvel[dofs], full.qacc[dofs] = qd, qdd
    part.qvel[:], part.qacc[:] = qd, qdd
    mujoco.mj_inverse(humanoid.model, full)
    mujoco.mj_inverse(left_arm.model, part)
    assert np.allclose(part.qfrc_inverse, full.qfrc_inverse[dofs], rtol=1e-9, atol=1e-9)
    assert np.isclose(np.sum(left_arm.model.body_mass), np.sum(humanoid.model.body_mass))


def test_its_saved_mjcf_compiles_to_the_same_model(left_arm):
    again = compile_mjcf(left_arm.mjcf_path)
    assert left_arm.mjcf_path.name.startswith("humanoid38_left_arm-")
    for field in ("body_mass", "body_inertia", "body_pos", "body_quat", "jnt_range", "key_qpos", "dof_damping"):
        assert np.allclose(getattr(again, field), getattr(left_arm.model, field), atol=1e-12), field


def test_the_part_steps_without_warnings_and_its_valves_move_it(left_arm):
    sim = Simulation(left_arm)
    u = np.full(left_arm.tables.n_chambers, 5.0)
    u[0::2], u[1::2] = 7.0, 3.0  # every joint's chamber a filled, b vented
    q0 = sim.data.qpos.copy()
    sim.set_command(u)
    sim.step(300)
    assert not np.any(sim.data.warning.number)
    assert np.all(np.isfinite(sim.data.qpos)) and np.max(np.abs(sim.data.qpos - q0)) > 0.05


def test_an_unknown_joint_is_named_with_the_valid_ones(humanoid):
    with pytest.raises(UnknownNameError, match="unknown joint 'left_elbw'; did you mean 'left_elbow'"):
        restricted_robot(humanoid, ["left_elbw"], "typo")


def test_an_actuator_moving_a_locked_joint_too_is_refused(tmp_path):
    """arm2 with its elbow cylinder pulling a tendon over both joints: keeping the elbow alone
    would leave that cylinder driving a shoulder that is no longer there."""

    xml = models.mjcf_path("arm2").read_text().replace(
        '<motor class="arm2" name="elbow" joint="elbow" gear="0.025"/>',
        '<motor class="arm2" name="elbow" tendon="coupled"/>').replace(
        "<actuator>", '<tendon><fixed name="coupled"><joint joint="shoulder" coef="0.005"/>'
                      '<joint joint="elbow" coef="0.025"/></fixed></tendon>\n  <actuator>', 1)
    path = tmp_path / "arm2_coupled.xml"
    path.write_text(xml)
    robot = assemble_robot("arm2_coupled", compile_mjcf(path), load_fluid(models.fluid_path("arm2")), path)
    assert actuated_joints(robot)["elbow"] == {"shoulder", "elbow"}
    with pytest.raises(ConfigError, match=r"arm2_coupled\[elbow\]: actuator 'elbow' moves elbow, shoulder, "
                                          "not all of them kept"):
        restricted_robot(robot, ["elbow"], "elbow")
