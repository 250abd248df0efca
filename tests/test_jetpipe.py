"""The jet-pipe actuator of paper 000: each physical element against closed forms, limits and
conservation laws; the coupled simulation; the force controller; the fast scenarios."""
import math

import numpy as np
import pytest

import models
from controllers.force import ForceCfg
from pneumatics.errors import ConfigError
from pneumatics.jetpipe import kernel
from pneumatics.jetpipe.chambers import (
    leak_area_m2,
    piston_force,
    pressure_rates,
    static_pressures,
)
from pneumatics.jetpipe.hysteresis import PlayHysteresis
from pneumatics.jetpipe.params import JetpipeCfg, load_jetpipe_cfg, parse_jetpipe
from pneumatics.jetpipe.plant import I_P1, I_P2, initial_state, rk4_step
from pneumatics.jetpipe.ports import circle_overlap, orifice_areas, port_area_m2
from pneumatics.jetpipe.sim import JetpipeSim, OpenLoopCurrent
from pneumatics.jetpipe.valve import static_position


@pytest.fixture(scope="module")
def cfg():
    return load_jetpipe_cfg(models.fluid_path("jetpipe"))


@pytest.fixture(scope="module")
def sim():
    return JetpipeSim()


# -- receiver geometry -------------------------------------------------------------------
def test_circle_overlap_closed_forms():
    r = 0.5e-3
    assert circle_overlap(r, r, 0.0) == pytest.approx(math.pi * r * r)
    assert circle_overlap(r, r, 2 * r) == pytest.approx(0.0, abs=1e-20)
    # two equal circles whose centres are one radius apart: r^2 (2 pi/3 - sqrt(3)/2)
    assert circle_overlap(r, r, r) == pytest.approx(r * r * (2 * math.pi / 3 - math.sqrt(3) / 2), rel=1e-12)
    assert circle_overlap(3 * r, r, 1.5 * r) == pytest.approx(math.pi * r * r)  # small one inside
    # the compiled kernel's scalar lens agrees
    rng = np.random.default_rng(0)
    for d in rng.uniform(0, 4 * r, 50):
        assert kernel.lens(3 * r, r, d) == pytest.approx(float(circle_overlap(3 * r, r, d)), rel=1e-12, abs=1e-22)


def test_orifice_areas_centre_extremes_symmetry_monotonic(cfg):
    p, d = cfg.ports, cfg.ports.jet_diameter_m
    port = port_area_m2(p)
    s1, r1, s2, r2 = orifice_areas(np.array([0.0]), p)
    assert max(s1[0], r1[0], s2[0], r2[0]) < 1e-6 * port  # critically lapped when centred
    s1, r1, s2, r2 = orifice_areas(np.array([d]), p)  # jet fully over port 1
    assert s1[0] == pytest.approx(port) and r2[0] == pytest.approx(port)
    assert r1[0] == pytest.approx(0.0, abs=1e-12 * port) and s2[0] == pytest.approx(0.0, abs=1e-12 * port)
    x = np.linspace(0.0, d, 200)
    a = orifice_areas(x, p)
    b = orifice_areas(-x, p)
    np.testing.assert_allclose(a[0], b[2], atol=1e-18)  # mirror symmetry
    np.testing.assert_allclose(a[3], b[1], atol=1e-18)
    assert np.all(np.diff(a[0]) >= -1e-18) and np.all(np.diff(a[3]) >= -1e-18)  # opening monotonic
    assert np.all(a[1] < 1e-6 * port) and np.all(a[2] < 1e-6 * port)  # the flange keeps the others shut


# -- hysteresis --------------------------------------------------------------------------
def test_minor_loops_close():
    h = PlayHysteresis(0.02, 8)
    t = np.linspace(0, 3, 3001)
    major = 0.3 * np.sin(2 * np.pi * t[:1000])
    h.trace(major)  # leave the major loop somewhere
    minor = 0.05 + 0.03 * np.sin(2 * np.pi * 5 * t[:1001])  # 5 cycles of a minor loop
    out = h.trace(minor)
    cyc = 200
    np.testing.assert_allclose(out[2 * cyc:3 * cyc], out[3 * cyc:4 * cyc], atol=1e-12)
    assert np.ptp(out) > 0.01  # it does move


def test_major_loop_half_width_is_8_percent_of_jet_range(cfg):
    h = PlayHysteresis(cfg.hysteresis_half_width_n, cfg.hysteresis.n_operators)
    f = np.concatenate([np.linspace(0, 0.5, 500), np.linspace(0.5, -0.5, 1000), np.linspace(-0.5, 0.5, 1000)])
    x = static_position(h.trace(f), cfg.jet)
    down = np.interp(0.0, f[500:1500][::-1], x[500:1500][::-1])
    up = np.interp(0.0, f[1500:], x[1500:])
    half_width = (down - up) / 2
    assert half_width / (2 * cfg.jet.saturation_m) == pytest.approx(0.08, rel=0.02)


# -- chambers ----------------------------------------------------------------------------
def _closed_valve_cfg(cfg, leak: bool):
    c = cfg.replace("jet", offset_m=0.0).replace("gas", polytropic_exponent=1.0)  # isothermal: m ~ P V
    return c if leak else c.replace("leak", slope_m2=0.0, offset_m2=0.0)


@pytest.mark.parametrize("leak", [False, True])
def test_chamber_mass_is_conserved_with_valves_shut(cfg, leak):
    """Jet centred (all ports shut), piston moving: without the leak each chamber keeps its
    mass (P V const, isothermal); with it, the leak only moves mass from 1 to 2.  Compiled
    step as the simulation uses it; the piston motion is held over each 0.1 ms step, so the
    balance holds to the step's first-order volume error."""
    c = _closed_valve_cfg(cfg, leak)
    prm = kernel.pack(c)
    y = initial_state(c, 5e5, 2e5)
    plays = np.zeros(4)
    radii = np.zeros(4)
    h, q0, n = 1e-4, c.cylinder.chamber1_length_m, 3000

    def mass(y, q):
        v1 = c.cylinder.dead_volume_1_m3 + c.cylinder.piston_area_m2 * q
        v2 = c.cylinder.dead_volume_2_m3 + c.cylinder.piston_area_m2 * (c.cylinder.stroke_m - q)
        return np.array([y[I_P1] * v1, y[I_P2] * v2])

    def q_of(t):
        return q0 + 0.01 * math.sin(2 * math.pi * 2 * t), 0.01 * 2 * math.pi * 2 * math.cos(2 * math.pi * 2 * t)

    m0 = mass(y, q0)
    for k in range(n):
        kernel.step(y, plays, radii, 0.0, *q_of(k * h), h, 1, prm)
    m1 = mass(y, q_of(n * h)[0])
    assert m1.sum() == pytest.approx(m0.sum(), rel=2e-4)
    if not leak:
        np.testing.assert_allclose(m1, m0, rtol=2e-4)
    else:
        assert m1[0] < m0[0] * 0.99  # air did leak from the high to the low chamber


def test_reference_rk4_matches_the_compiled_step(cfg):
    y0 = initial_state(cfg, 4e5, 3e5)
    y0[0], y0[2] = 0.05, 2e-4
    f_tip = cfg.driver.force_constant_n_per_a * y0[0]  # a play of radius 0 passes the tip force
    a = rk4_step(y0.copy(), 1e-4, 0.06, f_tip, 0.02, 0.01, cfg)
    b = y0.copy()
    kernel.step(b, np.zeros(1), np.zeros(1), 0.06, 0.02, 0.01, 1e-4, 1, kernel.pack(cfg))
    np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-14)


def test_adiabatic_compression_follows_p_v_to_the_gamma(cfg):
    c = cfg.replace("jet", offset_m=0.0).replace("leak", slope_m2=0.0, offset_m2=0.0)
    q0 = c.cylinder.chamber1_length_m
    v1 = c.cylinder.dead_volume_1_m3 + c.cylinder.piston_area_m2 * q0
    dp1, _ = pressure_rates(0.0, 3e5, 3e5, q0, 0.01, c)  # jet centred: all ports shut
    assert dp1 == pytest.approx(-1.4 * 3e5 * c.cylinder.piston_area_m2 * 0.01 / v1, rel=1e-12)


def test_leak_coefficient_depends_on_pressure_ratio(cfg):
    lo = leak_area_m2(6e5, 1e5, cfg)
    hi = leak_area_m2(6e5, 5.9e5, cfg)
    assert lo == pytest.approx(cfg.leak.slope_m2 / 6 + cfg.leak.offset_m2)
    assert hi < lo  # eq. 6 with the identified negative slope
    assert leak_area_m2(1e5, 6e5, cfg) == pytest.approx(lo)  # symmetric in direction


def test_force_sign_and_static_limits(cfg):
    d = cfg.ports.jet_diameter_m
    p1, p2 = static_pressures(np.array([0.3 * d, -0.3 * d]), cfg)
    assert piston_force(p1[0], p2[0], cfg) > 20.0  # jet toward port 1: pulls
    assert piston_force(p1[1], p2[1], cfg) < -20.0
    assert np.all((p1 <= cfg.supply.supply_pa) & (p1 >= cfg.supply.room_pa))


def test_simulated_force_sign_and_pull_only(sim):
    sim.reset(None)
    sim.step(0.08, 1000)  # 0.5 s of positive current
    assert sim.force_n() > 30.0 and sim.pressure[0] > sim.pressure[1]
    assert sim.data.qpos[0] == pytest.approx(sim.cfg.cylinder.chamber1_length_m, abs=1e-4)  # on the stopper
    sim.step(-0.08, 1000)  # negative: the piston leaves the stopper, only the spring is felt
    assert sim.pressure[1] > sim.pressure[0]
    assert 0.0 <= sim.force_n() < 1.5
    assert sim.data.qpos[0] < sim.cfg.cylinder.chamber1_length_m - 1e-3


def test_steps_without_mujoco_warnings(sim, rng):
    sim.reset(45.0)
    for _ in range(100):
        sim.step(rng.uniform(-0.4, 0.4), 20)
    assert [w.number for w in sim.data.warning] == [0] * len(sim.data.warning)
    assert np.all(np.isfinite(sim.y)) and np.all(sim.pressure > 0)


def test_timestep_convergence_and_kernels_agree():
    """A current step from 45 N: 5 RK4 substeps per 0.5 ms MuJoCo step (the default, 0.1 ms)
    against 20 substeps; and the compiled kernel against the numpy reference."""
    ctl = OpenLoopCurrent(lambda t: 0.04 + (0.03 if t > 0.01 else 0.0))
    runs = {}
    for n in (5, 20):
        s = JetpipeSim(substeps=n)
        s.reset(45.0)
        runs[n] = s.run(ctl, 0.3, record_hz=2000.0)["force.piston"]
    assert np.ptp(runs[5]) > 5.0
    assert np.max(np.abs(runs[5] - runs[20])) < 0.02  # N
    ref = JetpipeSim(kernel="reference")
    ref.reset(45.0)
    fast = JetpipeSim()
    fast.reset(45.0)
    a = ref.run(ctl, 0.02, record_hz=2000.0)
    b = fast.run(ctl, 0.02, record_hz=2000.0)
    np.testing.assert_allclose(a["p_a.piston"], b["p_a.piston"], rtol=1e-9)
    np.testing.assert_allclose(a["x_jet.piston"], b["x_jet.piston"], rtol=1e-7, atol=1e-12)


def test_bad_config_is_reported():
    with pytest.raises(ConfigError, match="kind"):
        parse_jetpipe({"kind": "valve_arm"}, "x.toml")
    with pytest.raises(ConfigError, match="stopper_position_m"):
        parse_jetpipe({"kind": "jetpipe", "cylinder": {"stopper_position_m": 0.2}}, "x.toml")
    with pytest.raises(ConfigError, match="supply_pa"):
        parse_jetpipe({"kind": "jetpipe", "supply": {"supply_pa": 550.0}}, "x.toml")
    assert isinstance(parse_jetpipe({"kind": "jetpipe"}, "x.toml"), JetpipeCfg)


# -- force controller --------------------------------------------------------------------
class _Obs:
    def __init__(self, f):
        self.force_n = np.array([f])


def test_force_controller_law_sign_saturation_and_hold():
    inv = lambda f: 0.001 * f
    ctl = ForceCfg(kp=20.0, static_gain_n_per_a=500.0, rate_hz=500.0, delay_samples=0).build(lambda t: 45.0, inv)
    ctl.reset()
    assert ctl(0.0, _Obs(45.0))[0] == pytest.approx(0.045)  # at the reference: feedforward only
    ctl.reset()
    assert ctl(0.0, _Obs(40.0))[0] == pytest.approx(0.045 + 20 / 500 * 5)  # too little force: more current
    ctl.reset()
    assert ctl(0.0, _Obs(100.0))[0] < 0.045
    ctl.reset()
    assert ctl(0.0, _Obs(-1e4))[0] == pytest.approx(0.4) and ctl.saturation_fraction == 1.0
    # zero-order hold at 500 Hz when called at 2 kHz: a new value only every 2 ms
    p = ForceCfg(kp=20.0, static_gain_n_per_a=500.0, rate_hz=500.0, feedforward=False, delay_samples=0).build(lambda t: 45.0)
    p.reset()
    out = [p(k * 5e-4, _Obs(40.0 - k))[0] for k in range(8)]
    assert out[0] == out[1] == out[2] == out[3] and out[4] == out[5] == out[6] == out[7] and out[4] > out[0]
    # the default one-tick computation delay: a sample's output is applied at the next tick
    d = ForceCfg(kp=20.0, static_gain_n_per_a=500.0, rate_hz=500.0, feedforward=False).build(lambda t: 45.0)
    d.reset()
    out = [d(k * 2e-3, _Obs(f))[0] for k, f in enumerate([40.0, 44.0, 45.0])]
    assert out == pytest.approx([0.2, 0.2, 0.04])
    with pytest.raises(ConfigError, match="inverse_static"):
        ForceCfg().build(lambda t: 45.0)


# -- scenarios ---------------------------------------------------------------------------
def _fast(name, tmp_path):
    from scenarios.common import run_scenario

    return run_scenario(name, tmp_path / name, fast=True, quiet=True)


def test_static_loop_scenario(tmp_path):
    m = _fast("jetpipe_static_loop", tmp_path)
    assert m["loop_fit_rmse_n"] < 5.0
    assert m["offset_fit_mm"] == pytest.approx(0.099, abs=0.05)  # fast ramps: the loop lags
    assert m["leak_offset_over_cd_fit_mm2"] == pytest.approx(m["leak_offset_over_cd_true_mm2"], rel=0.3)
    assert 6.0 < m["jet_hysteresis_half_width_pct"] < 10.0
    assert m["minor_loop_closure_n"] < 0.5
    assert 50.0 < m["max_force_n"] < 62.0
    assert (tmp_path / "jetpipe_static_loop" / "static_loop.png").is_file()


def test_open_loop_bandwidth_scenario(tmp_path):
    m = _fast("jetpipe_open_loop_bandwidth", tmp_path)
    assert 0.5 < m["bw_hz_min"] <= m["bw_hz_max"] < 4.0  # paper: 0.8-2.8 Hz


def test_linearization_scenario(tmp_path):
    m = _fast("jetpipe_linearization", tmp_path)
    assert m["dominant_pole_hz"] == pytest.approx(2.3, abs=0.3)  # Table II: 14.5 rad/s
    assert m["driver_pole_rad_s"] == pytest.approx(7049.7, rel=1e-3)
    assert m["fluid_pole_slow_rad_s"] < m["fluid_zero_rad_s"] < m["fluid_pole_fast_rad_s"]


def test_force_control_scenario(tmp_path):
    m = _fast("jetpipe_force_control", tmp_path)
    assert m["max_err_n_500hz"] < 4.0 < m["max_err_n_70hz"]  # paper: 2.37 N and 10.93 N
    assert m["max_err_n_5hz_ff"] < m["max_err_n_5hz_p"]  # feedforward removes the offset (Fig. 18)
    assert 10.0 < m["bw_hz_kp_20"] < 60.0  # eq. 16: 0.8 (1 + k_p) .. 2.8 (1 + k_p) Hz
