"""valve_leak's clearance form (pneumatics.effects.valve_leak): an overlapped spool's lands
seal by a radial clearance, each passing a laminar flow inversely as the length it still
covers (Merritt 1967 ch. 5).  Its law; the simulator's chamber settling where the two laminar
flows balance is in tests/test_effects.py."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pneumatics.effects.valve_leak import COVER_MIN, clearance_conductances, clearance_flows

ROOM = 1.013e5
commands = st.floats(0.0, 10.0)
widths = st.floats(0.1, 2.0)


@given(commands, commands, widths)
@settings(max_examples=200, deadline=None)
def test_the_spool_shortens_one_lands_seal_as_it_lengthens_the_others(u1, u2, w):
    """Moving the spool towards the supply (a larger command) opens the supply land's clearance
    and closes the exhaust land's; each land's conductance stays between G / (1 + stroke / w)
    and G / COVER_MIN."""
    g = 2e-11
    lo, hi = sorted((u1, u2))
    (s_lo, e_lo), (s_hi, e_hi) = (clearance_conductances(u, 5.0, g, w) for u in (lo, hi))
    assert s_lo <= s_hi and e_lo >= e_hi
    for c in (s_lo, e_lo, s_hi, e_hi):
        assert g / (1.0 + 5.0 / w) - 1e-24 <= c <= g / COVER_MIN + 1e-24


def test_at_null_both_lands_pass_the_same_conductance():
    s, e = clearance_conductances(np.array([4.2]), 4.2, 3e-11, 0.6)
    assert s[0] == e[0] == 3e-11


@given(st.floats(ROOM, 7e5), st.floats(1e-12, 1e-10))
@settings(max_examples=200, deadline=None)
def test_the_flow_is_laminar_in_the_squares_and_its_slope_is_exact(p, g):
    """m = G ((p_s^2 - p^2) - (p^2 - p_room^2)) / (2 p_room) at null, and dm/dp its derivative."""
    m, dm = clearance_flows(g, g, p, 7e5, ROOM)
    assert np.isclose(m, g * (7e5 ** 2 + ROOM ** 2 - 2 * p * p) / (2 * ROOM), rtol=1e-12)
    h = 1.0
    slope = (clearance_flows(g, g, p + h, 7e5, ROOM)[0] - clearance_flows(g, g, p - h, 7e5, ROOM)[0]) / (2 * h)
    assert np.isclose(dm, slope, rtol=1e-6)
