"""Chamber pressure dynamics (paper 002 eq. 9): conservation, closed forms, bounds, accuracy."""
import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.integrate import solve_ivp

from pneumatics.chamber import integrate, pressure_rate, static_transient
from pneumatics.medium import GasCfg
from pneumatics.robot import load_robot
from pneumatics.sim import Simulation
from pneumatics.valve import valve_areas

import models

GAS = GasCfg()
PS, PR = 7e5, 1e5


def smallest_dead_volume():
    """The smallest chamber dead volume [m^3] of any shipped model, and its valve row."""
    best = None
    for name in models.available(models.VALVE_ARM):
        tab = load_robot(name).tables
        i = int(np.argmin(tab.dead_volume))
        if best is None or tab.dead_volume[i] < best[0]:
            best = (tab.dead_volume[i], tab.valve[i])
    return best


def closed_valve_robot(n: float):
    """arm2 with leak-free valves that are shut at null, polytropic exponent n."""
    robot = load_robot("arm2")
    fluid = robot.fluid
    acts = tuple(dataclasses.replace(a, valve_a=dataclasses.replace(a.valve_a, null_leak_fraction=0.0),
                                     valve_b=dataclasses.replace(a.valve_b, null_leak_fraction=0.0))
                 for a in fluid.actuators)
    fluid = dataclasses.replace(fluid, actuators=acts, gas=dataclasses.replace(fluid.gas, polytropic_exponent=n))
    return robot.with_fluid(fluid)


def volumes(sim):
    tab = sim.tables
    x = sim.data.actuator_length - tab.length_zero
    return np.column_stack([tab.dead_volume[0::2] + tab.area_a * x,
                            tab.dead_volume[1::2] + tab.area_b * (tab.stroke - x)]).ravel()


def shake(sim, seconds=1.0):
    """Move the joints back and forth with external torques; return pressures and volumes."""
    ps, vs = [], []
    for k in range(int(seconds / sim.dt)):
        sim.data.qfrc_applied[:] = 0.8 * np.sin(2 * np.pi * np.array([1.3, 2.1]) * sim.time)
        sim.step(1)
        if k % 10 == 0:
            import mujoco
            mujoco.mj_fwdPosition(sim.model, sim.data)
            ps.append(sim.pressure.copy())
            vs.append(volumes(sim))
    return np.array(ps), np.array(vs)


def test_mass_is_conserved_with_closed_leak_free_valves_isothermal():
    sim = Simulation(closed_valve_robot(1.0))
    sim.reset(pressure_pa=[3e5, 4e5, 5e5, 2e5])
    p, v = shake(sim)
    mass = p * v / (GAS.gas_constant_j_per_kg_k * GAS.temperature_k)
    assert np.ptp(v[:, 0]) / v[0, 0] > 0.2  # the pistons really moved
    assert np.max(np.abs(mass / mass[0] - 1)) < 2e-4


def test_adiabatic_compression_keeps_p_v_to_the_k_constant():
    sim = Simulation(closed_valve_robot(1.4))
    sim.reset(pressure_pa=[3e5, 4e5, 5e5, 2e5])
    p, v = shake(sim)
    inv = p * v ** 1.4
    assert np.max(np.abs(inv / inv[0] - 1)) < 1e-3  # second-order scheme: O(h^2) drift over 1 s of shaking


def test_compression_faster_than_venting_drives_a_chamber_above_supply():
    """No clamping to [room, supply]: the antagonist of paper 002 Fig. 2C goes above supply."""
    p, vol = np.array([6.9e5]), np.array([5e-6])
    a_s, a_e = valve_areas(np.array([5.0]), np.array([[5, 5, 0.02, 0.6, 0.15, 1.3, 6e-7, 7e-7]]))
    for _ in range(20):  # volume shrinking at 1e-4 m^3/s (a piston at 0.5 m/s)
        p = integrate(p, vol, np.array([-1e-4]), a_s, a_e, GAS, PS, PR, 1e-3)
        vol = vol - 1e-7
    assert p[0] > PS


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 10.0), st.floats(PR, PS), st.floats(1e-7, 1e-4))
def test_static_volume_pressure_stays_between_room_and_supply(u, p0, vol):
    row = np.array([[5, 5, 0.02, 0.6, 0.15, 1.3, 8e-7, 9e-7]])
    _, p = static_transient(row, vol, p0, [u], 0.3, 1e-3, GAS, PS, PR)
    assert np.all(p >= PR - 1e-6) and np.all(p <= PS + 1e-6)


@settings(max_examples=15, deadline=None)  # a few seconds each: violent expansion halves the steps six times
@given(st.lists(st.floats(0.0, 10.0), min_size=8, max_size=8),
       st.lists(st.floats(-2e-3, 2e-3), min_size=8, max_size=8),
       st.floats(0.2e5, 12e5))
def test_random_commands_and_motions_keep_pressures_positive_and_finite(us, vrates, p0):
    """Even violent expansion of the smallest volume (2e-3 m^3/s into 0.5 cm^3: 80-fold in the
    20 ms run) stays positive."""
    u = np.array(us)
    rows = np.tile([5, 5, 0.02, 0.6, 0.15, 1.3, 2e-6, 2e-6], (8, 1))
    a_s, a_e = valve_areas(u, rows)
    p = np.full(8, p0)
    vol = np.full(8, 5e-7) + 1e-5 * np.arange(8)
    for _ in range(20):
        p = integrate(p, vol, np.array(vrates), a_s, a_e, GAS, PS, PR, 1e-3)
        vol = np.maximum(vol + np.array(vrates) * 1e-3, 5e-7)
        assert np.all(np.isfinite(p)) and np.all(p > 0)


def test_static_volume_converges_to_the_same_asymptote_from_both_sides():
    """From room and from supply pressure, at each command (one vectorised run of 10 chambers)."""
    commands = [0.0, 4.5, 5.0, 5.5, 10.0]
    row = np.array([[5, 5, 0.02, 0.6, 0.15, 1.3, 6e-7, 7e-7]])
    # 5 ms steps: the integrator subdivides a step wherever a pressure moves fast
    _, p = static_transient(row, 1e-5, [PR] * 5 + [PS] * 5, commands * 2, 25.0, 5e-3, GAS, PS, PR)
    for k, u in enumerate(commands):
        lo, hi = p[:, k], p[:, 5 + k]
        assert np.all(np.diff(lo) >= -1e-6) and np.all(np.diff(hi) <= 1e-6), u  # monotone approach
        assert abs(lo[-1] - hi[-1]) < 50.0, u
        rate, _ = pressure_rate(lo[-1:], np.array([1e-5]), np.zeros(1), *valve_areas(np.array([u]), row), GAS, PS, PR)
        assert abs(rate[0]) < 10.0, u  # Pa/s: at rest


@pytest.mark.parametrize("u,p0", [(10.0, PR), (0.0, PS), (5.0, PR), (6.0, 3e5), (4.2, 6e5)])
def test_ros2_at_1ms_matches_solve_ivp_for_the_smallest_dead_volume(u, p0):
    vol, row = smallest_dead_volume()
    row = row[None]
    a_s, a_e = valve_areas(np.array([u]), row)
    duration = 0.3
    t, p = static_transient(row, vol, p0, [u], duration, 1e-3, GAS, PS, PR)

    def f(_, y):
        return pressure_rate(y, np.array([vol]), np.zeros(1), a_s, a_e, GAS, PS, PR)[0]

    ref = solve_ivp(f, (0, duration), [p0], method="Radau", t_eval=t, rtol=1e-10, atol=1e-3)
    err = np.max(np.abs(p[:, 0] - ref.y[0]))
    assert err < 1e-3 * (PS - PR), f"max error {err:.1f} Pa"


def test_ros2_with_a_moving_piston_matches_solve_ivp():
    """Sinusoidal piston motion of the elbow chamber a at 3 Hz, valve opening and closing."""
    vol0, area, amp, w = 3e-6, np.pi * 0.016 ** 2 / 4, 0.03, 2 * np.pi * 3
    row = np.array([[5, 5, 0.02, 0.6, 0.15, 1.3, 6e-7, 7e-7]])

    def cmd(t):
        return 5.0 + 4.0 * np.sign(np.sin(2 * np.pi * 2 * t))

    def vol(t):
        return vol0 + area * amp * (1 + np.sin(w * t)) / 2

    def vdot(t):
        return area * amp * w * np.cos(w * t) / 2

    dt, T = 1e-3, 1.0
    p = np.array([3e5])
    out = [p[0]]
    for k in range(int(T / dt)):
        t = k * dt
        a_s, a_e = valve_areas(np.array([cmd(t)]), row)
        p = integrate(p, np.array([vol(t + dt / 2)]), np.array([vdot(t + dt / 2)]), a_s, a_e, GAS, PS, PR, dt)
        out.append(p[0])

    def f(t, y):
        k = int(np.floor(t / dt + 1e-9))
        a_s, a_e = valve_areas(np.array([cmd(k * dt)]), row)
        return pressure_rate(y, np.array([vol(t)]), np.array([vdot(t)]), a_s, a_e, GAS, PS, PR)[0]

    t_eval = np.arange(int(T / dt) + 1) * dt
    ref = solve_ivp(f, (0, T), [3e5], method="Radau", t_eval=t_eval, rtol=1e-9, atol=1e-2, max_step=dt / 4)
    err = np.abs(np.array(out) - ref.y[0])
    assert np.max(err) < 0.01 * (PS - PR), f"max error {np.max(err):.0f} Pa"
