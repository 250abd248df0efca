"""The compiled fast path against the readable numpy reference, to round-off."""
import numpy as np
import pytest

from pneumatics import chamber, kernel
from pneumatics.robot import load_robot
from pneumatics.sim import Simulation
from pneumatics.tables import valve_areas_table

import models


@pytest.mark.parametrize("name", models.available(models.VALVE_ARM))
def test_one_step_matches_the_reference_on_random_states(name, rng):
    robot = load_robot(name)
    tab = robot.tables
    act, ch, glob = kernel.pack(tab, np.arange(len(robot.actuator_names)), 1e-3)
    for _ in range(200):
        p = rng.uniform(0.3e5, 12e5, tab.n_chambers)
        u = rng.uniform(0, 10, tab.n_chambers)
        prev = tab.length_zero + rng.uniform(0, 1, tab.stroke.size) * tab.stroke
        length = prev + rng.normal(0, 0.003, prev.size) * tab.stroke
        ref = chamber.fluid_step(tab, p, u, prev, length, 1e-3)
        a_s, a_e = valve_areas_table(tab, u)
        fast = p.copy()
        ctrl = np.zeros(len(robot.actuator_names))
        kernel.fluid_step_fast(fast, np.column_stack([a_s, a_e]), prev.copy(), length, ctrl, act, ch, glob)
        # (here the fluid actuators are MuJoCo actuators 0..n-1; test_reordered_actuators covers the rest)
        np.testing.assert_allclose(fast, ref, rtol=1e-11, atol=0)
        np.testing.assert_allclose(ctrl, chamber.actuator_force(tab, ref), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("name", models.available(models.VALVE_ARM))
def test_simulation_fast_and_reference_agree(name, rng):
    robot = load_robot(name)
    runs = []
    commands = rng.uniform(0, 10, (20, robot.tables.n_chambers))
    for kern in ("fast", "reference"):
        sim = Simulation(robot, kernel=kern)
        sim.reset(pressure_pa=4e5)
        trace = []
        for u in commands:
            sim.set_command(u)
            sim.step(10)
            trace.append(np.concatenate([sim.pressure, sim.data.qpos]))
        runs.append(np.array(trace))
    np.testing.assert_allclose(runs[0], runs[1], rtol=1e-8, atol=1e-9)


def test_static_transient_fast_matches_reference():
    robot = load_robot("arm2")
    tab = robot.tables
    _, _, glob = kernel.pack(tab, np.arange(2), 1e-3)
    u = np.linspace(0, 10, 21)
    vol = np.full(u.size, 1e-5)
    t, ref = chamber.static_transient(tab.valve[2][None], vol, 1e5, u, 0.5, 1e-3, tab.gas, tab.supply_pa, tab.room_pa)
    a_s, a_e = chamber.valve_areas(u, tab.valve[2][None])
    out = np.empty_like(ref)
    kernel.static_transient_fast(np.full(u.size, 1e5), vol, a_s, a_e, glob, 1e-3, out)
    np.testing.assert_allclose(out, ref, rtol=1e-11)


def test_step_refinement_is_rare_at_1ms(rng):
    """The adaptive sub-steps are a safety net, not the normal path: count them on arm2."""
    robot = load_robot("arm2")
    tab = robot.tables
    sim = Simulation(robot, kernel="reference")
    sim.reset(pressure_pa=4e5)
    calls = {"steps": 0, "refined": 0}
    original = chamber.integrate

    def counting(p, volume, volume_rate, a_s, a_e, gas, ps, pr, dt, extra_flow=None):
        calls["steps"] += 1
        one = []
        for i in range(p.size):
            q, err = chamber.ros2_step(p[i:i + 1], dt, lambda y: chamber.pressure_rate(
                y, volume[i:i + 1], volume_rate[i:i + 1], a_s[i:i + 1], a_e[i:i + 1], gas, ps, pr))
            one.append(bool(np.abs(q - p[i]) > chamber.MAX_REL_CHANGE * p[i] or err > chamber.ERR_TOL * p[i]))
        calls["refined"] += sum(one)
        return original(p, volume, volume_rate, a_s, a_e, gas, ps, pr, dt, extra_flow)

    chamber.integrate = counting
    try:
        for _ in range(30):
            sim.set_command(rng.uniform(0, 10, tab.n_chambers))
            sim.step(10)
    finally:
        chamber.integrate = original
    assert calls["refined"] / (calls["steps"] * tab.n_chambers) < 0.05


def test_reordered_and_extra_mujoco_actuators(tmp_path, rng):
    """Fluid actuators need not be MuJoCo actuators 0..n-1 in TOML order: the kernel indexes
    data.actuator_length and data.ctrl by MuJoCo id."""
    import mujoco
    from pneumatics.robot import assemble_robot

    xml = models.mjcf_path("arm2").read_text().replace(
        '<motor class="arm2" name="shoulder" joint="shoulder" gear="0.030"/>',
        '<motor name="helper" joint="elbow" gear="0.1" ctrllimited="true" ctrlrange="-1 1"/>'
        '<motor class="arm2" name="elbow_tmp" joint="elbow" gear="0.025"/>'
        '<motor class="arm2" name="shoulder" joint="shoulder" gear="0.030"/>').replace(
        '<motor class="arm2" name="elbow" joint="elbow" gear="0.025"/>', "").replace(
        'name="elbow_tmp"', 'name="elbow"').replace('actuator="shoulder"/>', 'actuator="shoulder"/>', 1)
    xml = xml.replace('<actuatorfrc name="force.shoulder" actuator="shoulder"/>', "").replace(
        '<actuatorfrc name="force.elbow" actuator="elbow"/>', "")
    f = models.folder("arm2") / "_reordered_test.xml"
    try:
        f.write_text(xml)
        model = mujoco.MjModel.from_xml_path(str(f))
    finally:
        f.unlink()
    base = load_robot("arm2")
    odd = assemble_robot("arm2", model, base.fluid, None)
    assert list(odd.actuator_ids) == [2, 1]
    runs = []
    for robot in (base, odd):
        sim = Simulation(robot)
        sim.reset(pressure_pa=4e5)
        for u in np.random.default_rng(5).uniform(0, 10, (30, 4)):
            sim.set_command(u)
            sim.step(10)
        runs.append(np.concatenate([sim.pressure, sim.data.qpos]))
    np.testing.assert_allclose(runs[0], runs[1], rtol=1e-9)


def _traced(kernel: str, effects, commands) -> np.ndarray:
    """(rows, ...) pressures, joint angles, observed pressures and the supply pressure in
    effect after each 10 ms row of ``commands`` on arm2 with ``effects`` under ``kernel``."""
    sim = Simulation(load_robot("arm2"), kernel=kernel, effects=effects)
    sim.reset(pressure_pa=4e5)
    trace = []
    for u in commands:
        sim.set_command(u)
        sim.step(10)
        trace.append(np.concatenate([sim.pressure, sim.data.qpos, sim.observe().p, [sim._packed[2][13]]]))
    return np.array(trace)


@pytest.mark.parametrize("droop_tau_s", [0.0, 0.03])
def test_fast_and_reference_agree_with_every_kernel_effect_on(rng, droop_tau_s):
    """... the supply droop in its linear form and behind a receiver (reservoir form)."""
    from pneumatics.effects.effect_set import EffectSet
    effects = EffectSet(supply_droop_tau_s=droop_tau_s, friction={"shoulder": {"coulomb_nm": 0.05, "stiction_extra_nm": 0.03, "viscous_nm_s": 0.02},
                                                                   "elbow": {"power_viscous_nm": 0.06, "viscous_exponent": 0.5}},
                        valve_leak_m2={"elbow.a": 3e-8}, external_leak_m2={"shoulder.b": 2e-8},
                        piston_leak_m2={"elbow": 2e-8}, valve_hysteresis_v={"shoulder.a": 0.3},
                        external_leak_laminar_kg_s_pa={"elbow.a": 2e-11}, piston_leak_laminar_kg_s_pa={"shoulder": 2e-11},
                        pressure_offset_pa={"elbow.b": 1e4}, angle_offset_rad={"elbow": 0.02},
                        supply_droop_pa_per_kg_s=5e7)
    commands = rng.uniform(0, 10, (30, 4))
    runs = [_traced(kern, effects, commands) for kern in ("fast", "reference")]
    np.testing.assert_allclose(runs[0], runs[1], rtol=1e-8, atol=1e-9)
    assert runs[0][:, -1].min() < 6.9e5  # the supply really drooped


@pytest.mark.parametrize("tau_s", [0.0, 0.03])
def test_a_regulator_orifice_droops_with_the_flow_squared_fast_and_reference_alike(rng, tau_s):
    """supply_droop, regulator_orifice: p_s = nominal - k2 m_f^2; the compiled step keeps the drop
    in effect and recovers the filtered flow from it (effects.supply_droop.flow_of_droop)."""
    from pneumatics.effects.effect_set import EffectSet
    from pneumatics.effects.supply_droop import flow_of_droop
    effects = EffectSet().add("supply_droop", "all", {"droop_pa_per_kg2_s2": 5e10, "time_constant_s": tau_s},
                              form="regulator_orifice")
    commands = rng.uniform(0, 10, (30, 4))
    runs = [_traced(kern, effects, commands) for kern in ("fast", "reference")]
    np.testing.assert_allclose(runs[0], runs[1], rtol=1e-8, atol=1e-9)
    drop = 7e5 - runs[0][:, -1]
    assert drop.max() > 2e4  # it drooped, by 5e10 x (draw)^2
    m = np.array([flow_of_droop(d, 0.0, 5e10) for d in drop])
    np.testing.assert_allclose(5e10 * m ** 2, drop, rtol=1e-12)


def test_a_valve_sealed_by_clearances_leaks_fast_and_reference_alike(rng):
    """valve_leak, clearance form: the lands' laminar conductances follow the spool (numpy
    command path), their flows from the supply in effect (a droop on) and to the room join the
    leak flows of both kernels; the same with the gas temperature as a state (heat_transfer)."""
    from pneumatics.effects.effect_set import EffectSet
    for extra in ({}, {"heat_transfer": {"elbow.a": {"conductance_w_k": 0.05}}}):
        effects = EffectSet(supply_droop_pa_per_kg_s=5e7, **extra).add(
            "valve_leak", "elbow.a", {"clearance_conductance_kg_s_pa": 5e-11, "overlap_width_v": 0.4}, form="clearance")
        commands = rng.uniform(0, 10, (30, 4))
        commands[10:20, 2] = 5.0 + rng.uniform(-0.3, 0.3, 10)  # near null, where the clearance shows most
        runs = [_traced(kern, effects, commands) for kern in ("fast", "reference")]
        np.testing.assert_allclose(runs[0], runs[1], rtol=1e-8, atol=1e-9)
        without = _traced("fast", EffectSet(supply_droop_pa_per_kg_s=5e7, **extra), commands)
        assert np.abs(runs[0][:, 2] - without[:, 2]).max() > 1e3  # it leaked


def test_a_switched_compressor_saws_the_supply_between_its_limits_fast_and_reference_alike(rng):
    """supply_droop's compressor_cycling form: a 0.2 L receiver, 0.3 bar band, the valves
    pumping: the supply pressure falls to the cut-in pressure, the compressor refills it to the
    cut-out, again and again; the compiled kernel and the numpy reference agree (the switch
    flips at the same steps)."""
    from pneumatics.effects.effect_set import EffectSet
    effects = EffectSet().add("supply_droop", "all", {"receiver_volume_m3": 2e-4, "compressor_kg_s": 8e-3,
                                                      "band_pa": 3e4, "cut_out_pa": 7e5, "leak_kg_s_pa": 1e-11},
                              form="compressor_cycling")
    commands = np.where(rng.uniform(size=(300, 4)) < 0.5, 0.0, 10.0)
    runs = [_traced(kern, effects, commands) for kern in ("fast", "reference")]
    np.testing.assert_allclose(runs[0], runs[1], rtol=1e-8)
    supply = runs[0][:, -1]
    assert supply.min() > 7e5 - 3e4 - 5e3 and supply.max() < 7e5 + 5e3   # within the switch's limits (a 10 ms row's swing)
    below = supply < 7e5 - 2.5e4
    assert np.sum(below[1:] & ~below[:-1]) >= 2                           # cycles: reaches the cut-in again and again
