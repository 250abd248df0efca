"""The supply droop's law and its inverse (pneumatics.effects.supply_droop): the compiled
simulator keeps the drop in effect and recovers the filtered draw from it, so the inverse must
return the draw for every linear, quadratic or mixed droop, and grow with the drop."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pneumatics.effects.supply_droop import droop_pa, flow_of_droop, supply_pressure

#: physical ranges: a draw up to a few valves wide open; droops from a stiff supply line to a
#: regulator that loses bars (off, or 1e5-5e8 Pa/(kg/s), 1e7-5e12 Pa/(kg/s)^2)
draws = st.floats(0.0, 5e-3)
linear = st.one_of(st.just(0.0), st.floats(1e5, 5e8))
quadratic = st.one_of(st.just(0.0), st.floats(1e7, 5e12))


@given(draws, linear, quadratic)
@settings(max_examples=300, deadline=None)
def test_the_inverse_returns_the_draw(m, k, k2):
    if k == 0.0 and k2 == 0.0:
        return
    assert np.isclose(flow_of_droop(droop_pa(m, k, k2), k, k2), m, rtol=1e-9, atol=1e-15)


@given(st.floats(0.0, 1e5), st.floats(0.0, 1e5), linear, quadratic)
@settings(max_examples=200, deadline=None)
def test_a_larger_drop_stands_for_a_larger_draw(d1, d2, k, k2):
    if k == 0.0 and k2 == 0.0:
        return
    lo, hi = sorted((d1, d2))
    assert flow_of_droop(lo, k, k2) <= flow_of_droop(hi, k, k2)


def test_the_supply_falls_with_the_flow_squared_and_ignores_back_flow():
    flows = np.array([2e-4, 3e-4, -1e-4])  # a chamber venting into the supply line draws nothing
    assert supply_pressure(7e5, 0.0, flows, 1e11) == 7e5 - 1e11 * 5e-4 ** 2
    assert supply_pressure(7e5, 4e7, flows) == 7e5 - 4e7 * 5e-4
