"""The compiled orifice law over arrays (pneumatics/orifice_arrays.py) against its numpy
reference (pneumatics.medium.orifice_flow): every regime (choked, subsonic, the linear branch
near equal pressures, reversed flow), broadcasting as the doctor's equation error uses it, and
random pressures and areas."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pneumatics.medium import GasCfg, orifice_flow
from pneumatics.orifice_arrays import orifice_flows

GAS = GasCfg()


def _close(fast, ref):
    """Flows equal to a few 1e-14 of the flow function (the compiled law's polynomial) in
    relative terms; derivatives to 1e-6 of their pair's size |d/dp_from| + |d/dp_to| (the
    polynomial's slope is less exact than its values, and d/dp_down passes through zero at the
    critical ratio, where the reference's formula cancels)."""
    assert fast[0].shape == np.shape(ref[0])
    np.testing.assert_allclose(fast[0], ref[0], rtol=1e-11, atol=1e-300)
    if ref[1] is None:
        assert fast[1] is None and fast[2] is None
        return
    size = np.abs(ref[1]) + np.abs(ref[2])
    for f, r in zip(fast[1:], ref[1:]):
        assert np.all(np.abs(f - r) <= 1e-6 * size + 1e-300)


def test_every_regime_and_its_sign():
    """Ratios across the critical and laminar ratios, both directions of flow."""
    p_up = 6.0e5
    ratios = np.concatenate([np.linspace(0.05, 1.0, 400), [GAS.critical_ratio, GAS.laminar_ratio]])
    p_down = ratios * p_up
    areas = np.linspace(1e-8, 1e-6, ratios.size)
    for p_from, p_to in ((p_up, p_down), (p_down, p_up)):
        fast = orifice_flows(areas, p_from, p_to, GAS)
        _close(fast, orifice_flow(areas, p_from, p_to, GAS))
    forward = orifice_flows(areas, p_up, p_down, GAS)[0]
    assert np.all(forward[ratios < 1.0] > 0) and np.all(forward[ratios == 1.0] == 0)


def test_broadcasting_as_the_equation_error_uses_it():
    """(F, C) areas and pressures against an (F, 1) supply, a scalar area or room pressure."""
    rng = np.random.default_rng(3)
    p = rng.uniform(1.0e5, 6.0e5, (50, 6))
    a = rng.uniform(0.0, 1e-6, (50, 6))
    ps = rng.uniform(5.5e5, 6.5e5, (50, 1))
    for args in ((a, ps, p), (1.0, ps, p), (a, p, 1.013e5), (1.0, p, p[:, ::-1])):
        _close(orifice_flows(*args, GAS), orifice_flow(*args, GAS))
        _close(orifice_flows(*args, GAS, derivatives=False), orifice_flow(*args, GAS, derivatives=False))


def test_more_than_two_dimensions_is_refused():
    with pytest.raises(ValueError, match="at most 2 dimensions"):
        orifice_flows(np.ones((2, 2, 2)), 6e5, 1e5, GAS)


@settings(max_examples=60, deadline=None)
@given(arrays(float, (7, 3), elements=st.floats(2.0e4, 1.0e6)), arrays(float, (7, 3), elements=st.floats(2.0e4, 1.0e6)),
       arrays(float, (7, 3), elements=st.floats(0.0, 1e-5)))
def test_random_pressures_and_areas(p_from, p_to, area):
    _close(orifice_flows(area, p_from, p_to, GAS), orifice_flow(area, p_from, p_to, GAS))
