"""The SARCOS hydraulic elbow (paper 001): each physical element against physics, the coupled
simulation's stability and convergence, and the scenarios' --fast versions."""
import dataclasses
import math

import mujoco
import numpy as np
import pytest

import models
from pneumatics.errors import ConfigError
from pneumatics.hydraulics import (
    BLOCKED,
    HydraulicCircuit,
    Hysteresis,
    HysteresisCfg,
    load_hydraulic,
)
from pneumatics.hydraulics.config import load_hydraulic_cfg, parse_hydraulic
from pneumatics.hydraulics.hysteresis import major_loop
from pneumatics.oil import OilCfg, orifice_flow, orifice_flow_scalar
from scenarios.common import run_scenario


@pytest.fixture(scope="module")
def cfg():
    return load_hydraulic_cfg(models.fluid_path("sarcos_elbow"))


@pytest.fixture(scope="module")
def sim():
    return load_hydraulic("sarcos_elbow")


def circuit_of(cfg, kernel="fast", **vane_changes):
    vane = dataclasses.replace(cfg.vane, **vane_changes)
    return HydraulicCircuit(cfg.oil, cfg.power, cfg.supply_line, cfg.return_line, cfg.servovalve,
                            vane, kernel=kernel)


# ----------------------------------------------------------------------------- hysteresis
def test_major_loop_is_symmetric_and_open():
    """The descending branch, integrated on its own, is the ascending one turned by 180 deg;
    the loop has a width (coercive current of the order of k0)."""
    hc = HysteresisCfg()
    x, up, down = major_loop(hc)
    assert np.max(np.abs(down - (-up[::-1]))) < 1e-9
    assert up[0] == pytest.approx(-1.0) and up[-1] == pytest.approx(1.0)
    assert np.all(np.diff(up) >= 0) and np.all(np.diff(down) >= 0)
    coercive = np.interp(0.0, up, x) * hc.saturation_current_a
    assert 0.3 * hc.k0_a < coercive < 3 * hc.k0_a
    assert np.all(down[1:-1] > up[1:-1])  # descending branch lies above the ascending one


def test_minor_loops_close_and_nest():
    h = Hysteresis(HysteresisCfg())
    h.demagnetize()
    assert abs(h(0.0)) < 0.01  # demagnetised: near the null
    cycle = np.concatenate([np.linspace(0.05, 0.25, 40), np.linspace(0.25, 0.05, 40)[1:]])
    outs = [[h(float(i)) for i in cycle] for _ in range(3)]
    # return-point memory: from the second cycle on (once 0.05 A is a switching point) the
    # loop closes on itself and every cycle retraces the previous one exactly
    assert outs[1][0] == pytest.approx(outs[1][-1], abs=1e-12)
    assert outs[2] == pytest.approx(outs[1], abs=1e-12)
    up, down = np.array(outs[1][:40]), np.array(outs[1][39:][::-1])
    assert np.all(down[1:-1] > up[1:-1])  # a real loop with an area
    # a loop nested inside it closes, and the outer branch carries on as if never left
    h(0.05)
    before = [h(float(i)) for i in np.linspace(0.05, 0.2, 30)]
    for i in list(np.linspace(0.2, 0.1, 20)) + list(np.linspace(0.1, 0.2, 20)):
        h(float(i))
    assert h(0.2) == pytest.approx(before[-1], abs=1e-12)
    assert h(0.25) == pytest.approx(outs[1][39], abs=1e-12)
    # minor loops stay inside the major loop
    x, mu, md = major_loop(h.cfg)
    for i, v in zip(cycle, outs[1]):
        assert np.interp(i, x, mu) - 1e-9 <= v <= np.interp(i, x, md) + 1e-9


# ----------------------------------------------------------------------------- oil and orifice
def test_orifice_square_root_law_and_sign():
    oil = OilCfg()
    area = 1e-7
    q1, d_from, d_to = orifice_flow(area, 11e6, 10e6, oil)
    q4, _, _ = orifice_flow(area, 14e6, 10e6, oil)
    assert q1 > 0 and q4 / q1 == pytest.approx(2.0, rel=2e-3)           # Q ~ sqrt(dp)
    assert q1 == pytest.approx(0.61 * area * math.sqrt(2 * 1e6 / 860.0), rel=2e-3)   # eq. 5
    qr, _, _ = orifice_flow(area, 10e6, 11e6, oil)
    assert qr == pytest.approx(-q1)                                      # flow reverses
    assert d_from == pytest.approx(-d_to) and d_from > 0
    q0, d0, _ = orifice_flow(area, 10e6, 10e6, oil)                     # laminar near zero
    assert q0 == 0.0 and np.isfinite(d0) and d0 > 0
    qs, ds = orifice_flow_scalar(oil.orifice_coefficient * area, 1e6, oil.laminar_dp_pa ** 2)
    assert qs == pytest.approx(q1) and ds == pytest.approx(d_from)


# ----------------------------------------------------------------------------- chamber ODE
@pytest.mark.parametrize("kernel", ["fast", "reference"])
def test_closed_chamber_compressed_at_constant_rate(cfg, kernel):
    """Blocked ports, no leak, vane turned at constant rate: dp/dt = -beta D_v omega / V(t)
    integrates to p = p0 + beta ln(V0 / V(t))."""
    c = circuit_of(cfg, kernel, leak_coefficient_m3_per_pa_s=0.0)
    c.ports = [BLOCKED, BLOCKED]
    omega, dt, n = -0.05, 1e-4, 2000     # 0.01 rad of D_v: +-4.5 MPa (oil is stiff)
    p0 = c.y[4]
    for k in range(n):
        c.step(dt, 0.0, omega * k * dt, omega)
    v0 = c.vane.volumes(0.0)[0]
    v = c.vane.volumes(omega * n * dt)[0]
    beta = cfg.oil.bulk_modulus_pa
    assert c.y[4] - p0 == pytest.approx(beta * math.log(v0 / v), rel=2e-3)
    vb0, vb = c.vane.volumes(0.0)[1], c.vane.volumes(omega * n * dt)[1]
    assert c.y[5] - p0 == pytest.approx(beta * math.log(vb0 / vb), rel=2e-3)


def test_cross_chamber_leak_decays_exponentially(cfg):
    """Blocked ports, vane still: d(P_a - P_b)/dt = -beta R_l (1/V_a + 1/V_b)(P_a - P_b)."""
    c = circuit_of(cfg)
    c.ports = [BLOCKED, BLOCKED]
    c.y[4], c.y[5] = 15e6, 5e6
    v_a, v_b = c.vane.volumes(0.0)
    rate = cfg.oil.bulk_modulus_pa * cfg.vane.leak_coefficient_m3_per_pa_s * (1 / v_a + 1 / v_b)
    dt, t_end = 1e-4, 0.5 / rate
    for _ in range(round(t_end / dt)):
        c.step(dt, 0.0, 0.0, 0.0)
    assert (c.y[4] - c.y[5]) / 10e6 == pytest.approx(math.exp(-rate * t_end), rel=2e-3)
    assert c.y[4] + c.y[5] == pytest.approx(20e6, rel=1e-3)  # equal volumes: what a loses b gains


def test_fast_kernel_matches_reference(cfg):
    a, b = circuit_of(cfg, "fast"), circuit_of(cfg, "reference")
    for k in range(300):
        t = k * 2e-4
        args = (2e-4, 6e-5 * math.sin(20 * t), 0.2 * math.sin(3 * t), 0.6 * math.cos(3 * t))
        a.step(*args)
        b.step(*args)
    assert a.y == pytest.approx(b.y, rel=1e-9)


# ----------------------------------------------------------------------------- valve
def test_valve_null_leakage_and_mid_pressure(cfg):
    """At null the ports settle at the tip pressure (mid-way for G_s = G_r) and the valve
    passes exactly its clearance leakage from supply to return."""
    c = circuit_of(cfg)
    c.y[4], c.y[5] = 14e6, 6e6
    for _ in range(20000):
        c.step(1e-3, 0.0, 0.0, 0.0)
    f = c.flows()
    p_s, p_r = c.y[0], c.y[2]
    assert c.y[4] == pytest.approx(0.5 * (p_s + p_r), rel=1e-4)
    assert c.y[5] == pytest.approx(c.y[4], rel=1e-6)
    leak = cfg.servovalve.null_leakage_m3_s(p_s, p_r)
    assert leak > 0 and f["valve_in"] == pytest.approx(leak, rel=1e-6)
    assert f["supply_line"] == pytest.approx(leak, rel=1e-4)  # steady: the pump delivers it


def test_positive_tip_fills_chamber_a_and_empties_b(cfg):
    c = circuit_of(cfg)
    c.step(1e-4, 0.3 * cfg.servovalve.tip_travel_m, 0.0, 0.0)
    f = c.flows()
    assert f["to_a"] > 0 > f["to_b"]
    c2 = circuit_of(cfg)
    c2.step(1e-4, -0.3 * cfg.servovalve.tip_travel_m, 0.0, 0.0)
    assert c2.flows()["to_a"] < 0 < c2.flows()["to_b"]


def test_oil_volume_is_conserved(cfg):
    """Oil in from the pump minus oil out to the tank = oil stored by compression, step by
    step (the circuit's linear invariant), with a moving vane and a moving valve tip."""
    c = circuit_of(cfg)
    dt = 2e-4
    total_in, total_stored = 0.0, 0.0
    for k in range(3000):
        t = k * dt
        theta, omega = 0.3 * math.sin(4 * t), 1.2 * math.cos(4 * t)
        before = c.stored_volume_m3(theta)
        c.step(dt, 0.5e-4 * math.sin(7 * t), theta, omega)
        total_stored += c.stored_volume_m3(theta) - before
        total_in += dt * (c.y[1] - c.y[3])
    assert abs(total_in) > 1e-9
    assert total_stored == pytest.approx(total_in, rel=1e-8, abs=1e-15)


# ----------------------------------------------------------------------------- vane and friction
def test_pressure_in_chamber_a_turns_the_vane_positive(sim):
    sim.reset()
    sim.model.opt.gravity[:] = 0
    try:
        sim.circuit.y[4] += 2e6
        sim.data.ctrl[0] = sim.torque_hydraulic_nm
        mujoco.mj_forward(sim.model, sim.data)
        assert sim.torque_hydraulic_nm == pytest.approx(sim.d_v * 2e6)
        assert sim.data.qacc[0] > 0
    finally:
        sim.model.opt.gravity[:] = [0, 0, -9.81]
        sim.reset()


@pytest.mark.parametrize("torque_nm, moves", [(1.0, False), (3.0, True)])
def test_coulomb_friction_holds_below_and_slides_above(sim, torque_nm, moves):
    """The vane's Coulomb friction (tau_c = 1.5 N m): a smaller torque does not turn it (but
    for the creep of MuJoCo's soft friction constraint, ~5e-5 rad/s here), a larger one
    accelerates vane and load (~0.3 rad in 0.2 s at 3 N m)."""
    m, d = sim.model, sim.data
    sim.reset()
    m.opt.gravity[:] = 0
    try:
        for _ in range(1000):  # 0.2 s with MuJoCo alone, constant torque
            d.ctrl[0] = torque_nm
            mujoco.mj_step(m, d)
        turned = d.qpos[0] + d.qpos[1]
        assert (turned > 0.1) == moves
        if not moves:
            assert abs(turned) < 1e-4
    finally:
        m.opt.gravity[:] = [0, 0, -9.81]
        sim.reset()


def test_positive_current_lifts_the_free_load(sim):
    sim.reset()
    sim.set_current(0.2)
    sim.step(2500)
    assert sim.load_angle > 0.01 and sim.load_pressure_pa > 0


# ----------------------------------------------------------------------------- coupled sim
def test_steps_without_warnings_under_random_currents(sim, rng):
    sim.reset()
    for _ in range(100):     # 1 s, current changing every 10 ms
        sim.set_current(float(rng.uniform(-1, 1)))
        sim.step(50)
    assert sim.warnings == [0] * len(sim.warnings)
    p = sim.circuit.y
    assert np.all(np.isfinite(p)) and np.all(np.isfinite(sim.data.qpos))
    assert 0 < p[4] < 1.05 * sim.cfg.power.pump_pa and 0 < p[5] < 1.05 * sim.cfg.power.pump_pa
    assert abs(sim.vane_angle) < 1.7


def test_timestep_convergence():
    """A 0.15 A step on the free joint (valve transient, breakaway from friction, swing):
    the load pressure and the vane angle over 0.2 s at dt = 0.4 ... 0.05 ms.  Errors against
    the finest run fall as dt falls (first order), and at the model's 0.2 ms the largest
    pressure error is below 2 % of the pressure range (0.2 % rms), the angle's below 1 %.
    (0.4 ms is near the stability limit omega dt = 2 of the shaft/oil mode: ~40 % error.)"""
    dts = (4e-4, 2e-4, 1e-4, 5e-5)
    traces = []
    for dt in dts:
        s = load_hydraulic("sarcos_elbow", timestep=dt)
        s.set_current(0.15)
        per_ms = round(1e-3 / dt)
        p, q = [], []
        for _ in range(200):
            s.step(per_ms)
            p.append(s.load_pressure_pa)
            q.append(s.vane_angle)
        assert s.warnings == [0] * len(s.warnings)
        traces.append((np.array(p), np.array(q)))
    ref_p, ref_q = traces[-1]
    err_p = [np.abs(p - ref_p).max() / np.ptp(ref_p) for p, _ in traces[:-1]]
    err_q = [np.abs(q - ref_q).max() / np.ptp(ref_q) for _, q in traces[:-1]]
    assert err_p[0] > err_p[1] > err_p[2] and err_q[0] > err_q[1] > err_q[2]
    rms_p = np.sqrt(np.mean((traces[1][0] - ref_p) ** 2)) / np.ptp(ref_p)
    assert err_p[1] < 0.02 and rms_p < 0.005 and err_q[1] < 0.01
    assert 1.3 < err_p[1] / err_p[2] < 4.0   # ~2 for first order (the reference is not exact)


# ----------------------------------------------------------------------------- config
def test_config_errors_name_the_field(tmp_path):
    with pytest.raises(ConfigError, match="kind"):
        parse_hydraulic({"kind": "jetpipe"}, "x.toml")
    with pytest.raises(ConfigError, match="bulk_modulus_pa"):
        parse_hydraulic({"kind": "hydraulic", "oil": {"bulk_modulus": 1e9}}, "x.toml")
    with pytest.raises(ConfigError, match="outside the plausible range"):
        parse_hydraulic({"kind": "hydraulic", "vane": {"displacement_m3_per_rad": 4.72}}, "x.toml")
    with pytest.raises(ConfigError, match="not found"):
        load_hydraulic_cfg(tmp_path / "missing.toml")


def test_model_is_listed_as_hydraulic():
    assert "sarcos_elbow" in models.available("hydraulic")


# ----------------------------------------------------------------------------- scenarios
@pytest.fixture(scope="module")
def out(tmp_path_factory):
    return tmp_path_factory.mktemp("sarcos_runs")


def test_locked_scenario(out):
    m = run_scenario("sarcos_locked", out / "locked", fast=True, quiet=True)
    assert 2.0 < m["load_pressure_amp_mpa_02a"] < m["load_pressure_amp_mpa_03a"] < 10.3
    assert m["pressure_gain_ratio_03a_over_02a"] < 1.0         # paper: gain falls with amplitude
    assert 20.0 < m["supply_pressure_mean_mpa_03a"] < 20.8     # 20.7 MPa gauge supply
    assert 9.5 < m["chamber_pressure_mean_mpa_02a"] < 11.5     # centred near half supply
    assert m["mujoco_warnings"] == 0
    assert (out / "locked" / "locked_pressures.png").stat().st_size > 10_000


def test_free_scenario(out):
    m = run_scenario("sarcos_free", out / "free", fast=True, quiet=True)
    assert m["stick_count"] >= 1 and 0.05 < m["stick_time_s"] < 2.0
    assert 5.0 < m["load_angle_max_deg"] < 90.0
    assert m["mujoco_warnings"] == 0
    assert (out / "free" / "free_response.png").stat().st_size > 10_000


def test_identification_scenario(out):
    m = run_scenario("sarcos_identification", out / "ident", fast=True, quiet=True)
    for key in ("dv_rel_err", "ks_rel_err", "coulomb_rel_err", "leak_rel_err"):
        assert m[key] < 0.05, key
