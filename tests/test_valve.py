"""The Kokoro proportional valve map (reference/arm2.md, paper 002 Fig. 2A)."""
import numpy as np

from pneumatics.valve import ValveCfg

V = ValveCfg(supply_area_max_m2=6e-7, exhaust_area_max_m2=7e-7)


def test_full_opening_and_null():
    a_s, a_e = V.areas([0.0, 5.0, 10.0])
    # as in reference/arm2.md the main port adds (1 - f) of the full area to the null leak
    assert np.isclose(a_s[2], 0.98 * 6e-7) and np.isclose(a_e[0], 0.98 * 7e-7)
    # near null both ports are slightly open (the leak behind the intermediate asymptote)
    assert np.isclose(a_s[1], 0.02 * 6e-7) and np.isclose(a_e[1], 0.02 * 7e-7)
    assert a_s[0] < 1e-20 and a_e[2] < 1e-20


def test_supply_area_grows_and_exhaust_area_shrinks_with_command():
    u = np.linspace(0, 10, 401)
    a_s, a_e = V.areas(u)
    # beyond the deadband the main port opens monotonically (inside it the null leak closes)
    assert np.all(np.diff(a_s[u >= 5.15]) >= 0) and np.all(np.diff(a_e[u <= 4.85]) <= 0)
    assert np.all(a_s[u > 5.5] > a_s[u == 5.0]) and np.all(a_e[u < 4.5] > a_e[u == 5.0])
    assert np.all(a_s >= 0) and np.all(a_e >= 0)


def test_commands_beyond_the_range_saturate():
    a_s, a_e = V.areas([-3.0, 0.0, 10.0, 14.0])
    assert a_s[2] == a_s[3] and a_e[0] == a_e[1]
