"""The yardsticks' fitted torques as torques on the link (hypotheses.Hypothesis.state_torque),
which the angle replay applies to judge a joint's unexplained entry (angle_replay.yardstick_angle):
the equation error's +theta f is the torque -theta f, the sign convention of the friction law."""
from types import SimpleNamespace

import numpy as np

from identification.doctor.valve_arm.hypotheses import angle_profile_yardstick, smooth_torque_yardstick
from identification.doctor.valve_arm.replay import MechMods
from pneumatics.effects.friction import coulomb_shape, friction_torque

ALL = SimpleNamespace(mask=lambda reg: reg)


def test_the_smooth_yardstick_at_friction_values_is_the_friction_law(arm2):
    h = smooth_torque_yardstick(arm2, 1)
    qd = np.linspace(-2.0, 2.0, 41)
    q = np.full_like(qd, 0.3)
    assert np.allclose(h.state_torque([0, 0, 0, 0.2, 0.05], q, qd), friction_torque(qd, 0.2, 0.0, 0.1, 0.05))
    # the angle's terms: a spring -(c1 q + c2 q^2) about 0 and a constant force error
    assert np.allclose(h.state_torque([0.1, 2.0, 3.0, 0, 0], q, qd), -(0.1 + 2.0 * 0.3 + 3.0 * 0.09))


def test_the_yardstick_torque_fits_the_residual_it_was_fitted_to(arm2):
    """Least squares of a residual made of the yardstick's own functions returns coefficients
    whose state torque is minus that residual: the torque the link lacked."""
    rng = np.random.default_rng(3)
    q, qd = rng.uniform(-1, 1, 500), rng.uniform(-2, 2, 500)
    exp = SimpleNamespace(q=np.column_stack([np.zeros_like(q), q]), qd=np.column_stack([np.zeros_like(qd), qd]))
    h = smooth_torque_yardstick(arm2, 1)
    A = h.regressor(exp, ALL)[:, 1]
    residual = 0.3 - 0.5 * q + 0.08 * coulomb_shape(qd)
    theta = np.linalg.lstsq(A, residual, rcond=None)[0]
    assert np.allclose(h.state_torque(theta, q, qd), -residual)


def test_the_angle_profile_torque_is_minus_its_bin_values(arm2):
    q = np.linspace(-0.5, 0.5, 2000)
    exp = SimpleNamespace(q_s=np.column_stack([q, np.zeros_like(q)]), qd=np.zeros((q.size, 2)))
    h = angle_profile_yardstick(arm2, 0, exp)
    values = np.arange(len(h.params), dtype=float)
    bins = h.regressor(exp, ALL)[:, 0].argmax(axis=1)
    assert np.array_equal(h.state_torque(values, q, np.zeros_like(q)), -values[bins])


def test_mech_mods_add_a_state_torque_at_its_joint_alone():
    mm = MechMods(viscous_nm_s=np.array([0.0, 0.1]))
    q, qd = np.array([[0.1, 0.2], [0.3, -0.4]]), np.array([[1.0, 2.0], [-1.0, -3.0]])
    base = mm.torque(q, qd)
    mm.state_torques = {0: lambda qj, qdj: 10 * qj}
    assert np.allclose(mm.torque(q, qd), base + np.column_stack([10 * q[:, 0], np.zeros(2)]))
    assert MechMods().torque(q, qd) is None
    assert np.allclose(MechMods(state_torques={1: lambda qj, qdj: -qdj}).torque(q, qd)[:, 1], -qd[:, 1])
