"""The scaling study's synthetic model is a working pneumatic robot: a bank of arm2 shoulder
cylinders, each turning its own pendulum, with the sign convention of every model (chamber a
drives the joint positive) and no MuJoCo warnings."""

from pneumasim.bench_scaling import cylinder_bank
from pneumatics.sim import Simulation


def test_a_cylinder_bank_steps_and_each_cylinder_drives_its_own_joint():
    robot = cylinder_bank(3)
    assert robot.tables.n_chambers == 6 and robot.joint_names == ["cyl0", "cyl1", "cyl2"]
    sim = Simulation(robot)
    sim.reset(pressure_pa=4e5)
    sim.set_command([10.0, 0.0, 5.0, 5.0, 0.0, 10.0])  # cyl0 extends, cyl1 holds, cyl2 retracts
    sim.step(300)
    q = sim.observe().q
    assert q[0] > 0.2 and q[2] < -0.2 and abs(q[1]) < 0.5 * min(q[0], -q[2])
    assert sim.pressure[0] > sim.pressure[1] and sim.pressure[5] > sim.pressure[4]
    assert not any(w.number for w in sim.data.warning)
