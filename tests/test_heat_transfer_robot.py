"""heat_transfer on the robots' chambers: the energy equation with a gas temperature
(pneumatics.effects.heat_transfer.thermal_step), in the simulator and in the doctor's replays."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from identification.doctor.valve_arm.thermal import track_compiled, track_reference
from pneumatics.effects.effect_set import EffectSet
from pneumatics.effects.heat_transfer import chamber_flows, closed_chamber, thermal_step
from pneumatics.robot import load_robot
from pneumatics.sim import Simulation

ROBOT = load_robot("arm2")
GAS = ROBOT.tables.gas
T_REF = GAS.temperature_k
R, K = GAS.gas_constant_j_per_kg_k, GAS.heat_capacity_ratio


def _march(p, T, seconds, dt, volume, volume_rate, a_s, a_e, hA):
    for i in range(int(round(seconds / dt))):
        v_mid = volume(i * dt + 0.5 * dt)
        p, T = thermal_step(p, T, v_mid, volume_rate, a_s, a_e, GAS, 7e5, 1e5, hA, T_REF, dt)
    return p, T


def test_thermal_step_converges_to_the_energy_equation():
    """Filling a slowly compressed chamber: the 1 ms steps agree with Radau (rtol 1e-10) on the
    energy equation (Richer & Hurmuzlu 2000 eq. 11), and halving the step at least halves the error."""
    v0, area, speed, hA = 1.5e-5, 3.1e-4, 0.01, 0.05
    volume = lambda t: v0 - area * speed * t  # noqa: E731

    def f(t, y):
        p, T = y
        m, h_in, _ = chamber_flows(p, T, 3e-7, 0.0, GAS, 7e5, 1e5, T_REF)
        dp = (K * R * h_in + K * p * area * speed + (K - 1) * hA * (T_REF - T)) / volume(t)
        return [dp, T * (dp / p - area * speed / volume(t) - m * R * T / (p * volume(t)))]

    ref = solve_ivp(f, [0, 0.3], [1e5, T_REF], method="Radau", rtol=1e-10, atol=1e-8).y[:, -1]
    errs = []
    for dt in (1e-3, 5e-4):
        p, T = _march(1e5, T_REF, 0.3, dt, volume, -area * speed, 3e-7, 0.0, hA)
        errs.append(abs(T - ref[1]))
        assert abs(p - ref[0]) < 1e-3 * ref[0]
    assert ref[1] > T_REF + 40  # filling heats the gas (towards k T_supply)
    assert errs[0] < 0.3 and errs[0] / errs[1] > 1.8  # at least first order (second order seen: 4.4)


@settings(max_examples=10, deadline=None)
@given(p0=st.floats(1.2e5, 6e5), t0=st.floats(280.0, 380.0), stroke_rate=st.floats(-0.05, 0.05))
def test_a_closed_moving_chamber_keeps_its_air(p0, t0, stroke_rate):
    """No valve flow: the mass p V / (R T) is the same after 0.2 s of compression or expansion
    and wall exchange, whatever the start."""
    v0, area = 1.5e-5, 3.1e-4
    volume = lambda t: v0 + area * stroke_rate * t  # noqa: E731
    p, T = _march(p0, t0, 0.2, 1e-3, volume, area * stroke_rate, 0.0, 0.0, 0.05)
    assert abs(p * volume(0.2) / (R * T) / (p0 * v0 / (R * t0)) - 1) < 1e-9


def test_a_closed_rigid_chamber_cools_to_the_wall_in_closed_form():
    """Hot gas in a closed rigid chamber: T relaxes to the wall with tau = m c_v / (h A) and
    p / T stays constant (heat_transfer.closed_chamber)."""
    p0, t0, v, hA = 4e5, 350.0, 1.5e-5, 0.05
    tau = p0 * v / (R * t0) * R / (K - 1) / hA
    p, T = _march(p0, t0, 0.2, 1e-3, lambda t: v, 0.0, 0.0, 0.0, hA)
    p_ref, T_ref = closed_chamber(0.2, p0, t0, T_REF, tau)
    # tau itself shrinks as the gas cools (m fixed, so tau is constant) -> exact closed form
    assert abs(T - T_ref) < 0.05 and abs(p - p_ref) < 1e-3 * p_ref


def _filled_elbow(hA):
    eff = EffectSet(heat_transfer={"elbow.a": {"conductance_w_k": hA}})
    sim = Simulation(ROBOT, effects=eff)
    sim.reset(pressure_pa=1.5e5)
    u = sim.command.copy()
    u[2] = 9.0  # fill elbow.a
    sim.set_command(u)
    sim.step(150)
    hot = sim.gas_temperature[2], sim.pressure[2]
    u[2] = ROBOT.tables.valve[2, 0]  # shut it (near null: the valve's small null leak only)
    sim.set_command(u)
    sim.step(600)
    return hot, (sim.gas_temperature[2], sim.pressure[2]), sim


def test_simulator_heats_the_gas_on_filling_and_cools_it_at_the_walls_rate():
    (t_hot, _), (t_late, _), sim = _filled_elbow(0.05)
    (t_hot_ad, _), (t_late_ad, _), _ = _filled_elbow(0.0)
    assert t_hot > T_REF + 20  # charging heats the gas
    assert T_REF < t_late < t_hot - 10  # then it cools towards the wall ...
    assert t_late_ad > t_late + 10  # ... which an adiabatic chamber does not
    assert sim.gas_temperature[[0, 1, 3]].tolist() == [T_REF] * 3  # the other chambers are eq. 9


def test_temperature_observer_compiled_equals_reference():
    rng = np.random.default_rng(0)
    F, n = 3000, 2
    t = np.arange(F) * 1e-3
    p = 3e5 + 1e5 * np.sin(2 * np.pi * 1.3 * t)[:, None] * np.ones(n)
    vol = 1.5e-5 + 2e-6 * np.cos(2 * np.pi * 0.7 * t)[:, None] * np.ones(n)
    vdot = np.gradient(vol, 1e-3, axis=0)
    m = 2e-4 * np.sin(2 * np.pi * 2.1 * t[:, None] + rng.uniform(0, 3, n))
    args = (p, vol, vdot, np.maximum(m, 0), np.minimum(m, 0), np.array([0.05, 0.2]), R, K, T_REF)
    ref = track_reference(*args)
    fast = track_compiled(*[np.ascontiguousarray(a, float) for a in args[:6]], R, K, T_REF, 1e-3)
    assert np.allclose(ref, fast, rtol=1e-12, atol=1e-9)
    assert ref.min() > 200 and ref.max() < 500
