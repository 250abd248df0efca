"""Orifice flow (paper 002 eqs. 6-8): branches, continuity, signs, derivatives."""
import numpy as np
from hypothesis import given, settings, strategies as st

from pneumatics.medium import GasCfg, orifice_flow, unit_flow

GAS = GasCfg()


def test_critical_ratio_of_air():
    assert abs(GAS.critical_ratio - 0.5283) < 1e-4


def test_flow_is_continuous_at_the_critical_and_laminar_ratios():
    for r in (GAS.critical_ratio, GAS.laminar_ratio):
        below, _, _ = unit_flow(7e5, 7e5 * r * (1 - 1e-12), GAS)
        above, _, _ = unit_flow(7e5, 7e5 * r * (1 + 1e-12), GAS)
        assert abs(below - above) <= 1e-9 * below


def test_choked_flow_does_not_depend_on_downstream_pressure():
    f = unit_flow(7e5, np.array([0.5e5, 1e5, 2e5, 3.6e5]), GAS)[0]
    assert np.allclose(f, f[0], rtol=1e-12)
    # textbook value: A p sqrt(k/RT) (2/(k+1))^((k+1)/(2(k-1))) = 0.0404 p / sqrt(T) per m^2
    assert abs(f[0] / (7e5 / np.sqrt(GAS.temperature_k)) - 0.0404) < 2e-4


def test_flow_vanishes_at_equal_pressures_and_reverses():
    m, _, _ = orifice_flow(1e-6, 5e5, 5e5, GAS)
    assert m == 0.0
    fwd, _, _ = orifice_flow(1e-6, 5e5, 3e5, GAS)
    back, _, _ = orifice_flow(1e-6, 3e5, 5e5, GAS)
    assert fwd > 0 and back == -fwd


@settings(max_examples=200, deadline=None)
@given(st.floats(0.3e5, 20e5), st.floats(0.3e5, 20e5))
def test_derivatives_match_finite_differences(p_from, p_to):
    h = 1e-3 * max(p_from, p_to) * 1e-3
    m, d_from, d_to = orifice_flow(1e-6, p_from, p_to, GAS)
    fd_from = (orifice_flow(1e-6, p_from + h, p_to, GAS)[0] - orifice_flow(1e-6, p_from - h, p_to, GAS)[0]) / (2 * h)
    fd_to = (orifice_flow(1e-6, p_from, p_to + h, GAS)[0] - orifice_flow(1e-6, p_from, p_to - h, GAS)[0]) / (2 * h)
    r = min(p_from, p_to) / max(p_from, p_to)
    # skip kinks (branch switches) within the finite-difference step
    if min(abs(r - GAS.critical_ratio), abs(r - GAS.laminar_ratio)) < 1e-5:
        return
    scale = abs(d_from) + abs(d_to) + 1e-18
    assert abs(d_from - fd_from) <= 1e-4 * scale
    assert abs(d_to - fd_to) <= 1e-4 * scale


@settings(max_examples=200, deadline=None)
@given(st.floats(1e5, 7e5), st.floats(0.0, 1.0))
def test_flow_decreases_monotonically_with_downstream_pressure(p_up, r):
    lo = unit_flow(p_up, p_up * r * 0.999 + 1.0, GAS)[0]
    hi = unit_flow(p_up, p_up * min(1.0, r * 0.999 + 0.001), GAS)[0]
    assert lo >= hi - 1e-12


@given(st.lists(st.floats(0.3e5, 20e5), min_size=1, max_size=20), st.lists(st.floats(0.3e5, 20e5), min_size=1, max_size=20))
@settings(max_examples=100)
def test_the_flow_without_derivatives_is_the_same_flow(p_from, p_to):
    """derivatives=False (the doctor's mass-flow inputs on large arrays) skips the derivatives
    and returns the very same flow, to the bit."""
    n = min(len(p_from), len(p_to))
    a, b = np.array(p_from[:n]), np.array(p_to[:n])
    m, d_from, d_to = orifice_flow(2e-7, a, b, GAS)
    m2, none_from, none_to = orifice_flow(2e-7, a, b, GAS, derivatives=False)
    assert np.array_equal(m, m2) and none_from is None and none_to is None
    assert np.array_equal(unit_flow(np.maximum(a, b), np.minimum(a, b), GAS, derivatives=False)[0],
                          unit_flow(np.maximum(a, b), np.minimum(a, b), GAS)[0])
