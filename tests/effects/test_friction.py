"""The velocity-power viscous friction (pneumatics.effects.friction): a torque against the motion,
odd in the velocity, b |qd|^n above the linear band and continuous across its edge, and the
compiled simulator's law (kernel.write_friction) equal to the numpy one."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pneumatics.effects.friction import SMOOTH_RAD_S, friction_torque, velocity_power_shape
from pneumatics.kernel import write_friction

speeds = st.floats(-20.0, 20.0, allow_nan=False)
exponents = st.floats(0.2, 2.5)


@given(speeds, exponents, st.floats(0.0, 1.0))
@settings(max_examples=200, deadline=None)
def test_the_power_law_opposes_the_motion_and_is_odd(qd, n, b):
    tau = friction_torque(qd, power_viscous_nm=b, viscous_exponent=n)
    assert tau * qd <= 0.0
    assert friction_torque(-qd, power_viscous_nm=b, viscous_exponent=n) == -tau


@given(st.floats(SMOOTH_RAD_S, 20.0), exponents)
@settings(max_examples=200, deadline=None)
def test_above_the_linear_band_it_is_the_speed_to_the_power_n(qd, n):
    assert velocity_power_shape(qd, n) == np.float64(qd) ** n or np.isclose(velocity_power_shape(qd, n), qd ** n,
                                                                            rtol=1e-12)


def test_it_is_continuous_at_the_band_edge_and_linear_inside():
    for n in (0.4, 1.0, 1.8):
        edge = SMOOTH_RAD_S ** n
        assert np.isclose(velocity_power_shape(SMOOTH_RAD_S * (1 - 1e-9), n), edge, rtol=1e-8)
        inside = np.linspace(-SMOOTH_RAD_S, SMOOTH_RAD_S, 9)
        np.testing.assert_allclose(velocity_power_shape(inside, n), inside * SMOOTH_RAD_S ** (n - 1))


@given(st.lists(speeds, min_size=1, max_size=6), st.floats(0.0, 0.3), st.floats(0.0, 0.3), st.floats(0.01, 1.0),
       st.floats(0.0, 0.3), st.floats(0.0, 0.3), exponents)
@settings(max_examples=100, deadline=None)
def test_the_compiled_law_is_the_numpy_one(qvel, fc, fs, vs, b, bn, n):
    qvel = np.array(qvel)
    fric = np.array([[dof, fc, fs, vs, b, bn, n] for dof in range(qvel.size)], float)
    out = np.zeros_like(qvel)
    write_friction(qvel, out, fric)
    np.testing.assert_allclose(out, friction_torque(qvel, fc, fs, vs, b, bn, n), rtol=1e-12, atol=1e-15)
