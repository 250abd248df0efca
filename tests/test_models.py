"""Every shipped model compiles, steps under random valid commands without a MuJoCo warning,
and obeys the sign convention: chamber a turns its joint positive."""
import mujoco
import numpy as np
import pytest

from pneumatics.robot import load_robot
from pneumatics.sim import Simulation

import models

ALL = models.available()
NAMES = models.available(models.VALVE_ARM)  # the Kokoro-valve robots load_robot builds


def test_the_shipped_models():
    assert {"arm2", "humanoid38"} <= set(NAMES)


@pytest.mark.parametrize("name", ALL)
def test_model_folder_follows_menagerie_conventions(name):
    folder = models.folder(name)
    for f in (f"{name}.xml", "scene.xml", "fluid.toml", "README.md"):
        assert (folder / f).is_file(), f
    scene = mujoco.MjModel.from_xml_path(str(folder / "scene.xml"))
    assert scene.key("home") is not None


@pytest.mark.parametrize("name", NAMES)
def test_model_steps_under_random_commands_without_warnings(name, rng):
    sim = Simulation(load_robot(name))
    sim.reset(pressure_pa=4e5)
    for _ in range(200):  # 2 s, commands changing at 100 Hz
        sim.set_command(rng.uniform(0, 10, sim.tables.n_chambers))
        sim.step(10)
    assert [w.number for w in sim.data.warning] == [0] * len(sim.data.warning)
    assert np.all(np.isfinite(sim.pressure)) and np.all(sim.pressure > 0)
    assert np.all(np.isfinite(sim.data.qpos))


@pytest.mark.parametrize("name", NAMES)
def test_chamber_a_pushes_its_joint_positive(name):
    """Pressurise one chamber a, vent everything else, zero gravity: that joint accelerates
    positive (DESIGN.md: chamber a extends / positive joint direction)."""
    robot = load_robot(name)
    sim = Simulation(robot)
    sim.model.opt.gravity[:] = 0
    tab = sim.tables
    for j, act in enumerate(robot.actuator_names[:12]):
        p = np.full(tab.n_chambers, tab.room_pa)
        p[2 * j] = 5e5
        sim.reset(pressure_pa=p)
        assert sim.forces()[j] > 0
        mujoco.mj_forward(sim.model, sim.data)
        joint = sim.robot.joint_names.index(act) if act in sim.robot.joint_names else None
        assert joint is not None, f"actuator {act} is named after no joint"
        qacc = sim.data.qacc[sim.robot.dof_index[joint]]
        assert qacc > 0, f"{name}: chamber a of {act} accelerates its joint negative"
