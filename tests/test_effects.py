"""Physics of the effect models, inside the simulator."""
import dataclasses

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pneumatics.effects.effect_set import EffectSet
from pneumatics.effects.pressure_sensor_offset import offset_at
from pneumatics.effects.friction import friction_torque
from pneumatics.effects.valve_dynamics import dead_time, first_order_lag, play, slew_limited, slew_limited_reference
from pneumatics.effects.valve_lag import COMMAND_SPAN_V
from pneumatics.sim import COMMAND_RANGE_V
from pneumatics.robot import load_robot
from pneumatics.sim import Simulation


def leak_free(robot, n=1.0):
    fluid = robot.fluid
    acts = tuple(dataclasses.replace(a, valve_a=dataclasses.replace(a.valve_a, null_leak_fraction=0.0),
                                     valve_b=dataclasses.replace(a.valve_b, null_leak_fraction=0.0))
                 for a in fluid.actuators)
    return robot.with_fluid(dataclasses.replace(fluid, actuators=acts,
                                                gas=dataclasses.replace(fluid.gas, polytropic_exponent=n)))


def coast(robot, effects):
    sim = Simulation(robot, effects=effects)
    sim.model.opt.gravity[:] = 0
    sim.model.eq_active0[sim.model.equality("brace_shoulder").id] = 1
    sim.model.dof_damping[:] = 0
    sim.reset(pressure_pa=robot.tables.room_pa)
    sim.set_command([5, 5, 0, 0])  # elbow chambers vented
    sim.data.qvel[1] = 2.0
    mujoco.mj_forward(sim.model, sim.data)
    M = np.zeros((2, 2))
    mujoco.mj_fullM(sim.model, sim.data, M)
    sim.step(200)
    return (2.0 - sim.data.qvel[1]) / sim.time, M[1, 1]


def test_coulomb_friction_decelerates_a_free_joint_at_fc_over_inertia():
    """Closed form: Coulomb friction F_c adds F_c / I to a coasting joint's deceleration
    (measured against the same coast without friction: the vented chambers' air brakes too)."""
    robot = load_robot("arm2")
    fc = 0.05
    with_f, inertia = coast(robot, EffectSet(friction={"elbow": {"coulomb_nm": fc}}))
    without, _ = coast(robot, EffectSet())
    assert abs((with_f - without) - fc / inertia) < 0.02 * fc / inertia


def test_friction_law_signs_and_stribeck_peak():
    v = np.array([-1.0, -0.05, 0.0, 0.05, 1.0])
    tau = friction_torque(v, coulomb_nm=0.1, stiction_extra_nm=0.05, stribeck_rad_s=0.1, viscous_nm_s=0.01)
    assert np.all(np.sign(tau[v != 0]) == -np.sign(v[v != 0])) and tau[2] == 0.0
    assert abs(tau[3]) > abs(tau[4]) - 0.01 * 1.0  # breakaway above Coulomb at low speed


@pytest.mark.parametrize("effects", [EffectSet(piston_leak_m2={"elbow": 5e-9}),
                                     EffectSet(piston_leak_laminar_kg_s_pa={"elbow": 1e-11})], ids=["orifice", "laminar"])
def test_piston_leak_conserves_the_cylinders_air(effects):
    robot = leak_free(load_robot("arm2"), n=1.0)
    sim = Simulation(robot, effects=effects)
    sim.model.opt.gravity[:] = 0
    sim.reset(pressure_pa=[3e5, 3e5, 6e5, 2e5])
    tab = sim.tables
    x = sim.data.actuator_length[1] - tab.length_zero[1]
    v = np.array([tab.dead_volume[2] + tab.area_a[1] * x, tab.dead_volume[3] + tab.area_b[1] * (tab.stroke[1] - x)])
    sim.model.eq_active0[sim.model.equality("brace_shoulder").id] = 1
    mass0 = sim.pressure[2:] @ v
    sim.model.dof_damping[:] = 1e6  # hold the joints: static volumes
    sim.step(2000)
    mujoco.mj_forward(sim.model, sim.data)
    x = sim.data.actuator_length[1] - tab.length_zero[1]
    v = np.array([tab.dead_volume[2] + tab.area_a[1] * x, tab.dead_volume[3] + tab.area_b[1] * (tab.stroke[1] - x)])
    assert sim.pressure[2] < 5.5e5 and sim.pressure[3] > 2.5e5  # it leaked a -> b
    assert abs(sim.pressure[2:] @ v / mass0 - 1) < 2e-3


def test_external_leak_vents_a_closed_chamber_to_room_and_not_below():
    robot = leak_free(load_robot("arm2"))
    sim = Simulation(robot, effects=EffectSet(external_leak_m2={"shoulder.a": 6e-8}))
    sim.model.dof_damping[:] = 1e6  # hold the joints: static volumes
    sim.reset(pressure_pa=[6e5, 6e5, 6e5, 6e5])
    trace = []
    for _ in range(40):
        sim.step(100)
        trace.append(sim.pressure.copy())
    trace = np.array(trace)
    assert np.all(np.diff(trace[:, 0]) <= 1.0) and trace[-1, 0] < 2e5 and trace[-1, 0] > 0.99e5
    assert abs(trace[-1, 2] - 6e5) < 0.2e5  # the other cylinder keeps its air


def test_laminar_external_leak_follows_the_isothermal_closed_form():
    """A closed, held, isothermal chamber leaking through a capillary:
    V/(R T) dp/dt = -G (p^2 - p0^2) / (2 p0) has (p - p0)/(p + p0) = A exp(-G R T t / V)."""
    robot = leak_free(load_robot("arm2"), n=1.0)
    tab, gas = robot.tables, robot.fluid.gas
    sim = Simulation(robot, effects=EffectSet(external_leak_laminar_kg_s_pa={"shoulder.a": 2e-11}))
    sim.model.dof_damping[:] = 1e6  # hold the joints: static volumes
    sim.reset(pressure_pa=[6e5, 4e5, 4e5, 4e5])
    sim.set_command(tab.valve[:, 0])  # valves at null: closed (no null leak in leak_free)
    x = sim.data.actuator_length[0] - tab.length_zero[0]
    volume = tab.dead_volume[0] + tab.area_a[0] * x
    rate = 2e-11 * gas.gas_constant_j_per_kg_k * gas.temperature_k / volume  # [1/s]
    p0 = tab.room_pa
    a = (6e5 - p0) / (6e5 + p0)
    for _ in range(10):
        sim.step(100)
        e = a * np.exp(-rate * sim.time)
        assert sim.pressure[0] == pytest.approx(p0 * (1 + e) / (1 - e), rel=2e-3)
    assert sim.pressure[1] == pytest.approx(4e5, rel=1e-3)  # nothing else leaks


def test_play_operator_minor_loops_close_and_major_loop_width():
    h = 0.3
    up = np.linspace(4, 6, 50)
    down = up[::-1]
    y = play(np.concatenate([up, down]), h)
    assert abs((y[49] - up[-1]) + h) < 1e-12           # lags the rising command by h
    assert abs(y[-1] - (down[-1] + h)) < 1e-12         # leads the falling one by h
    wiggle = 5.0 + 0.2 * np.sin(np.linspace(0, 20, 200))  # reversals smaller than 2h
    y = play(wiggle, h, u0=5.0)
    assert np.ptp(y) == 0.0                            # minor loop: the spool does not move


def test_lag_and_delay_are_what_they_claim():
    u = np.r_[np.zeros(10), np.ones(1000)]
    y = first_order_lag(u, 0.02, 1e-3)
    assert abs(y[10 + 20] - (1 - np.exp(-21 / 20))) < 0.02
    d = dead_time(u, 0.005, 1e-3)
    assert d[14] == 0.0 and d[15] == 1.0


def test_a_slew_limit_takes_a_large_step_in_fixed_time_and_passes_small_changes():
    u = np.r_[np.full(10, 5.0), np.full(200, 9.0), np.full(100, 9.05)]
    y = slew_limited(u, 0.05)                           # 50 V/s at 1 ms steps
    assert y[10 + 78] < 9.0 - 0.04 and y[10 + 79] == pytest.approx(9.0, abs=1e-12)  # 4 V at 0.05 V a step
    assert y[210] == pytest.approx(9.05, abs=1e-12)     # a 0.05 V change passes at once
    rng = np.random.default_rng(3)
    w = rng.uniform(0, 10, 500)
    np.testing.assert_array_equal(slew_limited(w, 0.3), slew_limited_reference(w, 0.3))
    assert np.all(np.abs(np.diff(slew_limited(w, 0.3))) <= 0.3 + 1e-12)


def test_the_slew_limits_span_is_the_simulators_command_range():
    assert COMMAND_SPAN_V == COMMAND_RANGE_V[1] - COMMAND_RANGE_V[0]


def test_valve_slew_limit_in_the_simulator_bounds_the_spools_speed():
    sim = Simulation(load_robot("arm2"), effects=EffectSet(valve_slew_s={"elbow.b": 0.1}))  # 100 V/s
    dt = sim.model.opt.timestep
    sim.set_command([5.0, 5.0, 5.0, 9.0])
    sim.step(10)
    assert abs(sim.spool_position[3] - (5.0 + 100.0 * 10 * dt)) < 1e-9
    assert np.all(sim.spool_position[:3] == 5.0)
    sim.step(100)
    assert sim.spool_position[3] == 9.0


def test_valve_hysteresis_in_the_simulator_delays_the_spool():
    robot = load_robot("arm2")
    sim = Simulation(robot, effects=EffectSet(valve_hysteresis_v={"elbow.b": 0.4}))
    sim.set_command([5, 5, 5, 5.3])
    assert sim.spool[3] == 5.0          # within the play
    sim.set_command([5, 5, 5, 6.0])
    assert abs(sim.spool[3] - 5.6) < 1e-12


def test_sensor_offsets_show_in_observations_only():
    robot = load_robot("arm2")
    sim = Simulation(robot, effects=EffectSet(pressure_offset_pa={"elbow.a": 5000.0}, angle_offset_rad={"shoulder": 0.01}))
    sim.reset(pressure_pa=4e5)
    obs = sim.observe()
    assert obs.p[2] == 4e5 + 5000.0 and obs.q[0] == 0.01 and sim.pressure[2] == 4e5


def test_an_angle_sensor_with_a_gain_error_reads_its_law():
    """angle_sensor_offset, offset_and_scale form: q_measured = q + offset + scale_error q, the
    rate scaled alike; the physics never sees it, and the doctor's inverse gives q back."""
    from pneumatics.effects.angle_sensor_offset import reading_error, true_angle

    robot = load_robot("arm2")
    effects = EffectSet().add("angle_sensor_offset", "elbow", {"offset_rad": -0.02, "scale_error": 0.05},
                              form="offset_and_scale")
    sim = Simulation(robot, effects=effects)
    sim.reset(pressure_pa=4e5)
    sim.set_command([5, 5, 9, 1])
    sim.step(75)  # the elbow swinging, short of its limit
    obs, q, qd = sim.observe(), sim.data.qpos[1], sim.data.qvel[1]
    assert abs(q) > 0.05 and abs(qd) > 0.05  # the elbow moved
    assert obs.q[1] == pytest.approx(q + reading_error(q, -0.02, 0.05)) == pytest.approx(1.05 * q - 0.02)
    assert obs.qd[1] == pytest.approx(1.05 * qd) and obs.q[0] == sim.data.qpos[0]
    assert true_angle(obs.q[1], -0.02, 0.05) == pytest.approx(q)


def test_a_warming_up_pressure_sensor_drifts_by_the_simulation_clock():
    """pressure_sensor_offset, warm_up_drift: the reading's offset is offset + drift
    (1 - exp(-t / tau)), t the simulation's time; the physics never sees it."""
    robot = load_robot("arm2")
    effects = EffectSet().add("pressure_sensor_offset", "elbow.a",
                              {"offset_pa": 2000.0, "drift_pa": 9000.0, "time_constant_s": 0.5}, form="warm_up_drift")
    sim = Simulation(robot, effects=effects)
    sim.reset(pressure_pa=4e5)
    assert sim.observe().p[2] - sim.pressure[2] == pytest.approx(2000.0)
    sim.set_command([5, 5, 5, 5])
    sim.step(1000)
    obs = sim.observe()
    assert obs.p[2] - sim.pressure[2] == pytest.approx(2000.0 + 9000.0 * (1 - np.exp(-sim.time / 0.5)), rel=1e-9)
    assert np.allclose(obs.p[[0, 1, 3]], sim.pressure[[0, 1, 3]])


@settings(max_examples=60, deadline=None)
@given(offset=st.floats(-3e4, 3e4), drift=st.floats(-3e4, 3e4), tau=st.floats(0.1, 1e3),
       t=st.floats(0.0, 1e4))
def test_a_warm_up_drift_settles_monotonically_from_offset_to_offset_plus_drift(offset, drift, tau, t):
    at = offset_at(t, offset, drift, tau)
    later = offset_at(t + 1.0, offset, drift, tau)
    lo, hi = min(offset, offset + drift), max(offset, offset + drift)
    assert lo - 1e-9 <= at <= hi + 1e-9
    assert (later - at) * drift >= -1e-9          # moves toward the settled value, never back
    assert offset_at(0.0, offset, drift, tau) == offset
    assert offset_at(t, offset, drift, 0.0) == offset  # no time constant: no drift


def _run(effects, steps=300, kernel="fast"):
    sim = Simulation(load_robot("arm2"), kernel=kernel, effects=effects)
    sim.reset(pressure_pa=4e5)
    out = []
    for k in range(steps // 10):
        sim.set_command([6.5, 3.5, 4.0, 6.0] if (k // 8) % 2 == 0 else [3.5, 6.5, 6.0, 4.0])
        sim.step(10)
        out.append(np.r_[sim.pressure, sim.data.qpos])
    return sim, np.array(out)


def test_step_by_step_valve_path_equals_the_batched_kernel_when_the_valve_is_ideal():
    """valve_lag/line_dynamics step one physics step at a time; with a vanishing lag that path
    must reproduce the batched compiled loop (same physics, same order of operations)."""
    _, batched = _run(EffectSet())
    sim, stepped = _run(EffectSet(valve_lag_s={"elbow.a": 1e-12}))
    assert sim.valves.dynamic
    np.testing.assert_allclose(stepped, batched, rtol=1e-10, atol=1e-9)


def test_valve_lag_spool_follows_the_exact_first_order_response():
    tau, dt = 0.02, 1e-3
    sim = Simulation(load_robot("arm2"), effects=EffectSet(valve_lag_s={"shoulder.a": tau}))
    sim.set_command([8.0, 5.0, 5.0, 5.0])
    sim.step(20)
    assert abs(sim.spool_position[0] - (8.0 - 3.0 * np.exp(-20 * dt / tau))) < 1e-12
    assert np.all(sim.spool_position[1:] == 5.0)  # the other valves are ideal


def test_line_delay_holds_the_old_spool_for_the_delay_then_switches():
    sim = Simulation(load_robot("arm2"), effects=EffectSet(line_dynamics={"elbow.b": {"delay_s": 0.015, "volume_m3": 0.0}}))
    sim.set_command([5.0, 5.0, 5.0, 9.0])
    sim.step(14)
    assert sim.spool_position[3] == 5.0
    sim.step(2)
    assert sim.spool_position[3] == 9.0


def test_line_volume_slows_the_chamber_like_a_larger_dead_volume():
    """The tube's volume adds to the dead volume: the pressure rises more slowly after a step."""
    vol = 3e-5
    robot = load_robot("arm2")
    plain = Simulation(robot)
    lined = Simulation(robot, effects=EffectSet(line_dynamics={"shoulder.a": {"delay_s": 0.0, "volume_m3": vol}}))
    assert lined.tables.dead_volume[0] == robot.tables.dead_volume[0] + vol
    for s in (plain, lined):
        s.model.eq_active0[:] = 1  # brace: constant volumes
        s.reset(pressure_pa=1e5)
        s.set_command([9.0, 5.0, 5.0, 5.0])
        s.step(30)
    assert lined.pressure[0] < plain.pressure[0] - 2e3
    robot.model.eq_active0[:] = 0


def test_end_stop_stops_the_joint_inside_the_model_limit():
    robot = load_robot("arm2")
    jid = robot.model.joint("shoulder").id
    hi = robot.model.jnt_range[jid, 1]
    sim = Simulation(robot, effects=EffectSet(end_stop={"shoulder": {"upper_intrusion_rad": 0.2}}))
    assert robot.model.jnt_range[jid, 1] == hi  # the robot's own model is untouched
    sim.model.opt.gravity[:] = 0
    sim.reset(pressure_pa=4e5)
    sim.set_command([10.0, 0.0, 5.0, 5.0])
    q = []
    for _ in range(100):
        sim.step(10)
        q.append(sim.data.qpos[sim.robot.qpos_index[0]])
    assert max(q) < hi - 0.2 + 0.03          # the bumper yields a little, never to the old limit
    assert q[-1] > hi - 0.2 - 0.03           # and the joint rests on it


def _settle_at_null(effects: EffectSet) -> float:
    """Elbow chamber a's pressure [Pa] after 20 s with its valve at null and the arm braced."""
    robot = leak_free(load_robot("arm2"))
    sim = Simulation(robot, effects=effects)
    sim.model.opt.gravity[:] = 0
    sim.model.eq_active0[sim.model.equality("brace_shoulder").id] = 1
    sim.reset(pressure_pa=4e5)
    sim.set_command([5, 5, 5, 5])
    sim.step(20000)
    return float(sim.pressure[2])


def test_an_asymmetric_valve_leak_moves_the_pressure_a_closed_valve_settles_at():
    """A leak open both ways near null pulls the chamber to where its supply inflow equals its
    exhaust outflow (isentropic orifices, paper 002 eqs. 6-8): with equal areas well between
    room and supply, with a larger exhaust-side area lower, with a larger supply side higher."""
    same = _settle_at_null(EffectSet(valve_leak_m2={"elbow.a": 3e-8}))
    more_exhaust = _settle_at_null(EffectSet(valve_leak_m2={"elbow.a": 3e-8}, valve_leak_exhaust_m2={"elbow.a": 6e-8}))
    more_supply = _settle_at_null(EffectSet(valve_leak_m2={"elbow.a": 6e-8}, valve_leak_exhaust_m2={"elbow.a": 3e-8}))
    assert 2e5 < more_exhaust < same - 5e4 and same + 5e4 < more_supply < 7e5


def test_a_valve_sealed_by_clearances_settles_a_closed_chamber_where_the_laminar_flows_balance():
    """valve_leak, clearance form: with equal clearances at null the chamber settles where
    G (p_s^2 - p^2) = G (p^2 - p_room^2), p = sqrt((p_s^2 + p_room^2) / 2) ~ 5.0 bar (the
    orifice leak's settling point depends on the orifices' law instead); a wider overlap on
    the same conductance changes nothing at null."""
    tab = load_robot("arm2").tables
    expected = np.sqrt((tab.supply_pa ** 2 + tab.room_pa ** 2) / 2.0)
    for width in (0.6, 1.5):
        effects = EffectSet().add("valve_leak", "elbow.a", {"clearance_conductance_kg_s_pa": 5e-11,
                                                            "overlap_width_v": width}, form="clearance")
        assert abs(_settle_at_null(effects) - expected) < 500.0


def test_effect_sets_combine_and_refuse_one_family_at_one_place_twice():
    """A fitted model's effects and a study's (tubes on a fitted humanoid) run together; the
    same family at the same place in both is an error, not a silent choice."""
    from pneumatics.errors import ConfigError

    fitted = EffectSet().add("valve_lag", "elbow.a", {"time_constant_s": 0.02}).add(
        "supply_droop", "all", {"droop_pa_per_kg_s": 1e7})
    tubes = EffectSet().add("line_dynamics", "elbow.a", {"delay_s": 0.005, "volume_m3": 2e-6})
    both = fitted.combined(tubes)
    assert both.valve_lag_s == {"elbow.a": 0.02} and both.supply_droop_pa_per_kg_s == 1e7
    assert both.line_dynamics == {"elbow.a": {"delay_s": 0.005, "volume_m3": 2e-6}}
    assert fitted.line_dynamics == {} and tubes.valve_lag_s == {}  # neither is changed
    with pytest.raises(ConfigError, match="valve_lag_s is set at elbow.a in both"):
        both.combined(EffectSet().add("valve_lag", "elbow.a", {"time_constant_s": 0.01}))


@settings(max_examples=30, deadline=None)
@given(st.one_of(st.just(0.0), st.floats(1e-3, 0.5)), st.floats(1e-4, 5e-3), st.floats(0.0, 5e-3))
def test_the_reservoir_droop_is_the_first_order_response_of_the_supply_flow(tau, total, start):
    """supply_droop's reservoir form (effects/supply_droop.py): the filtered flow steps toward
    the total without overshoot, reaches about 1 - 1/e of the way in tau (backward Euler at
    dt = tau / 200: within 1 %), and is the total itself for tau = 0 (the linear form)."""
    from pneumatics.effects.supply_droop import filtered_flow

    dt = tau / 200 if tau > 0 else 1e-5
    f = start
    for _ in range(200):
        f_next = filtered_flow(f, total, tau, dt)
        assert min(f, total) - 1e-15 <= f_next <= max(f, total) + 1e-15
        f = f_next
    if tau == 0.0:
        assert f == total
    else:
        assert abs((f - start) - (1 - np.exp(-1)) * (total - start)) <= 0.01 * abs(total - start) + 1e-15


def test_a_receiver_smooths_the_supply_pressure_and_keeps_its_mean():
    """The same commands drawn from a linear droop and from one behind a 50 ms receiver: the
    supply pressure in effect moves less behind the receiver, about the same mean drop."""
    robot = load_robot("arm2")
    commands = np.random.default_rng(3).uniform(0, 10, (200, 4))
    traces = []
    for tau in (0.0, 0.05):
        sim = Simulation(robot, effects=EffectSet(supply_droop_pa_per_kg_s=8e7, supply_droop_tau_s=tau))
        sim.reset(pressure_pa=4e5)
        trace = []
        for u in commands:
            sim.set_command(u)
            for _ in range(10):
                sim.step(1)
                trace.append(sim._packed[2][13])
        traces.append(np.array(trace[500:]))
    linear, receiver = traces
    assert receiver.std() < 0.7 * linear.std()
    drop_linear, drop_receiver = robot.tables.supply_pa - linear.mean(), robot.tables.supply_pa - receiver.mean()
    assert drop_receiver == pytest.approx(drop_linear, rel=0.15)
