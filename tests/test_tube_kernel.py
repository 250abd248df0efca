"""The lumped line (line_dynamics, lumped_rc): its physics (mass conserved between tube and
chamber, the tube's time constant, the settled state) and its compiled twin
(pneumatics.tube_kernel) against the numpy reference (effects.line_dynamics) to round-off."""
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from pneumatics.effects.line_dynamics import rc_line_step, tube_conductance, tube_quasi_steady, valve_into_tube
from pneumatics.kernel import pack_glob
from pneumatics.robot import load_robot
from pneumatics.tube_kernel import (PINNED_VOLUME_M3, rc_line_step_compiled, tube_quasi_steady_compiled,
                                    warm_tubes_compiled)

TAB = load_robot("arm2").tables
GAS = TAB.gas
RT, N = GAS.gas_constant_j_per_kg_k * GAS.temperature_k, GAS.polytropic_exponent
GLOB = pack_glob(GAS, TAB.supply_pa, TAB.room_pa, 1e-3, 0.0)
ROOM, SUPPLY = TAB.room_pa, TAB.supply_pa


def valve(a_s, a_e, g_s=0.0, g_e=0.0):
    """The numpy valve flow into a tube at q: (mdot, d mdot / d q)."""
    return valve_into_tube(a_s, a_e, g_s, g_e, SUPPLY, ROOM, GAS)


@settings(max_examples=60, deadline=None)
@given(st.floats(ROOM, SUPPLY), st.floats(ROOM, SUPPLY), st.floats(0.0, 2e-6), st.floats(0.0, 2e-6),
       st.floats(1e-7, 5e-6), st.floats(1e-3, 0.1), st.floats(-1e-4, 1e-4), st.floats(0.0, 4e-11))
@example(369798.0, 1e5, 4.86707161516999e-07, 0.0, 1.5e-07, 0.0625, 0.0, 0.0)  # the choked step below
def test_the_compiled_step_is_the_numpy_step(p_t, p, a_s, a_e, tube_v, tau, vdot, g):
    """Random tubes, valves (areas, clearances), pressures and piston motions: one step agrees
    to 1e-10 relative.  Not to 1e-12: where the valve is choked its flow's derivative d mdot /
    d p_t is zero up to round-off (numpy's -5e-15 kg/(s Pa) for a 0.49 mm^2 valve filling a tube
    at 3.7 bar), the two paths round it differently, and the Rosenbrock step's Jacobian
    multiplies it by n R T h / V_tube (8e8 Pa s/kg for 0.15 cm^3): hypothesis found such a step
    that differed by 2e-11."""
    vol = 2e-5
    ref = rc_line_step(p_t, p, vol, vdot, tube_v, tau, valve(a_s, a_e, g, 0.5 * g), -1e-6, N, RT, 1e-3)
    fast = rc_line_step_compiled(p_t, p, vol, vdot, tube_v, tau, a_s, a_e, g, 0.5 * g, SUPPLY, -1e-6, GLOB, 1e-3)
    np.testing.assert_allclose(fast, ref, rtol=1e-10)


def test_a_shut_valve_keeps_the_air_of_tube_and_chamber():
    """Valve shut, no leak, piston still: tube and chamber only exchange their air, the sum of
    their masses p V / (n R T)'s numerator kept to 1e-9 while they settle to one pressure."""
    p_t, p, tube_v, vol = 6e5, 2e5, 2e-6, 2e-5
    total = p_t * tube_v + p * vol
    for _ in range(200):
        p_t, p = rc_line_step(p_t, p, vol, 0.0, tube_v, 0.01, valve(0.0, 0.0), 0.0, N, RT, 1e-3)
    assert abs(p_t * tube_v + p * vol - total) < 1e-9 * total
    assert abs(p_t - p) < 1.0  # settled (the pair's time constant 9 ms)


def test_the_tube_empties_into_a_large_chamber_with_its_time_constant():
    """Into a chamber that holds its pressure, the tube's excess pressure falls as exp(-t / tau)
    (ROS2's sub-steps at 1 ms within 0.5 % at one time constant: second order, its error
    constant large for gamma = 1 + 1/sqrt(2))."""
    tau, p0, excess = 0.02, 3e5, 1e5
    p_t = p0 + excess
    for _ in range(20):  # 20 ms
        p_t, _ = rc_line_step(p_t, p0, PINNED_VOLUME_M3, 0.0, 2e-6, tau, valve(0.0, 0.0), 0.0, N, RT, 1e-3)
    assert (p_t - p0) / excess == pytest.approx(math.exp(-1.0), rel=5e-3)


def test_an_open_valve_fills_tube_and_chamber_to_the_supply():
    p_t, p = ROOM, ROOM
    for _ in range(3000):
        p_t, p = rc_line_step_compiled(p_t, p, 2e-5, 0.0, 2e-6, 0.01, 2e-6, 0.0, 0.0, 0.0, SUPPLY, 0.0, GLOB, 1e-3)
    assert p_t == pytest.approx(SUPPLY, rel=1e-4) and p == pytest.approx(SUPPLY, rel=1e-4)
    assert p <= p_t <= SUPPLY + 1.0


@pytest.mark.parametrize("a_s, a_e, g", [(1e-6, 0.0, 0.0), (0.0, 1e-6, 0.0), (2e-8, 2e-8, 3e-11), (0.0, 0.0, 0.0)])
@pytest.mark.parametrize("p", [ROOM, 3e5, SUPPLY - 1e3])
def test_the_settled_tube_balances_the_flows(a_s, a_e, g, p):
    """mdot_valve(p_t) = G (p_t - p) at the settled pressure, which lies between the chamber's
    and the side the valve opens to; compiled and numpy alike."""
    G = float(tube_conductance(2e-6, 0.01, N, RT))
    x = tube_quasi_steady(p, G, valve(a_s, a_e, g, g), ROOM, SUPPLY)
    m_v, _ = valve(a_s, a_e, g, g)(x)
    assert abs(m_v - G * (x - p)) <= 1e-9 * max(abs(m_v), G * 1e3)
    assert ROOM - 1e-6 <= x <= SUPPLY + 1e-6
    assert tube_quasi_steady_compiled(p, 2e-6, 0.01, a_s, a_e, g, g, SUPPLY, GLOB) == pytest.approx(x, rel=1e-12)


def test_warming_up_the_tubes_is_its_python_loop():
    """warm_tubes_compiled against the loop it compiles: settled `lead` steps before each
    window, then stepped against the held chamber pressure."""
    rng = np.random.default_rng(4)
    F, lead = 400, 50
    p_ch = 3e5 + np.cumsum(rng.normal(0.0, 2e3, F))
    a_s, a_e = rng.uniform(0.0, 1e-6, F), rng.uniform(0.0, 1e-6, F)
    g = np.zeros(F)
    first = np.array([0, 20, 120, 399])
    out = np.empty(first.size)
    warm_tubes_compiled(p_ch, a_s, a_e, g, g, first, lead, 2e-6, 0.01, SUPPLY, GLOB, out)
    G = float(tube_conductance(2e-6, 0.01, N, RT))
    for w, f1 in enumerate(first):
        f0 = max(f1 - lead, 0)
        pt = tube_quasi_steady(p_ch[f0], G, valve(a_s[f0], a_e[f0]), ROOM, SUPPLY)
        for f in range(f0, f1):
            pt = rc_line_step(pt, p_ch[f], PINNED_VOLUME_M3, 0.0, 2e-6, 0.01, valve(a_s[f], a_e[f]), 0.0, N, RT,
                              1e-3)[0]
        assert out[w] == pytest.approx(pt, rel=1e-9)  # 50 steps' round-off
