"""Bench physics (leak, gas-wall heat transfer, seal friction), the bench models and the bench
doctor on synthetic recordings it must tell apart, and the fast real-data scenario."""
import json
import math

import numpy as np
import pytest

from identification.doctor.bench.chamber_fit import leak_and_heat
from identification.doctor.bench.diagnose import diagnose_bench
from pneumatics.bench.model import load_bench, replay_cylinder
from pneumasim.cli import main as cli_main
from pneumatics.effects.external_leak import leak_mass_flow
from pneumatics.effects.heat_transfer import (
    chamber_rates,
    closed_chamber,
    integrate,
    thermal_time_constant_s,
)
from pneumatics.effects.seal_friction import load_cell_reading, seal_friction
from pneumatics.recording import Recording

R, K, TW, PR = 287.0, 1.4, 293.15, 101325.0
CV = R / (K - 1)


def test_closed_chamber_relaxes_to_the_wall_with_the_thermal_time_constant():
    V, hA, p0, T0 = 1e-4, 0.05, 8e5, 330.0
    tau = thermal_time_constant_s(p0, T0, V, hA)
    t = np.linspace(0, 5 * tau, 2001)
    P, T = integrate(t, p0, T0, lambda p, T: chamber_rates(p, T, V, hA, TW))
    Pc, Tc = closed_chamber(t, p0, T0, TW, tau)
    assert np.max(np.abs(T - Tc)) < 1e-6 * T0 and np.max(np.abs(P - Pc)) < 1e-6 * p0
    assert T[-1] == pytest.approx(TW + (T0 - TW) * math.exp(-5), rel=1e-6)   # -> wall temperature
    assert P[-1] == pytest.approx(p0 * T[-1] / T0, rel=1e-9)                 # mass and volume constant
    # energy balance: the change of internal energy is the heat through the wall
    m = p0 * V / (R * T0)
    q = hA * (TW - T)
    assert m * CV * (T[-1] - T0) == pytest.approx(np.trapezoid(q, t), rel=1e-5)


def test_leak_conserves_mass_and_energy():
    V, hA, G, p0, T0 = 2e-4, 0.02, 2e-11, 8e5, 300.0
    t = np.linspace(0, 60, 6001)

    def rates(p, T):
        return chamber_rates(p, T, V, hA, TW, mdot_out=leak_mass_flow(p, PR, G))

    P, T = integrate(t, p0, T0, rates)
    m = P * V / (R * T)
    mdot = leak_mass_flow(P, PR, G)
    assert m[0] - m[-1] == pytest.approx(np.trapezoid(mdot, t), rel=1e-5)
    # energy: d(m c_v T)/dt = -c_p T mdot + h A (T_w - T)
    u = m * CV * T
    flux = -(CV + R) * T * mdot + hA * (TW - T)
    assert u[-1] - u[0] == pytest.approx(np.trapezoid(flux, t), rel=1e-4)


def test_adiabatic_leak_is_isentropic_and_the_compiled_twin_agrees():
    V, G, p0 = 1e-4, 5e-11, 8e5
    t = np.linspace(0, 20, 4001)
    P, T = integrate(t, p0, TW, lambda p, T: chamber_rates(p, T, V, 0.0, TW, mdot_out=leak_mass_flow(p, PR, G)))
    rho = P / (R * T)
    assert np.ptp(P / rho ** K) / (P[0] / rho[0] ** K) < 1e-6          # p / rho^k constant
    # the numba RK4 of the doctor integrates the same equations (V = 1 m^3, rates per volume)
    tau_leak = V / (R * TW * G)
    hA = 0.03
    tau_th = thermal_time_constant_s(p0, TW + 5, V, hA)
    t = np.linspace(0, 20, 401)       # the doctor's RK4 step (0.05 s): same nodes, same scheme
    P2, _ = integrate(t, p0, TW + 5, lambda p, T: chamber_rates(p, T, V, hA, TW, mdot_out=leak_mass_flow(p, PR, G)))
    cfg = load_bench("bench_chamber")
    P3 = leak_and_heat([p0, math.log(tau_leak), 5.0, math.log(tau_th)], t, cfg)
    assert np.max(np.abs(P3 - P2)) < 1e-6 * p0


def test_leak_flow_signs_and_laws():
    assert leak_mass_flow(PR, PR, 1e-10) == 0.0
    for law, c in (("laminar", 1e-10), ("linear", 1e-10), ("orifice", 1e-8)):
        assert leak_mass_flow(3e5, PR, c, law) > 0 > leak_mass_flow(0.5e5, PR, c, law)
    small = PR + 100.0   # laminar -> linear for small pressure differences
    assert leak_mass_flow(small, PR, 1e-10) == pytest.approx(leak_mass_flow(small, PR, 1e-10, "linear"), rel=1e-3)


def _chamber_rec(p, t, seed):
    rng = np.random.default_rng(seed)
    meas = np.round((p + rng.normal(0, 150.0, t.size)) / 100.0) * 100.0     # 0.001 bar resolution
    return Recording(t, {"p_a.chamber": meas}, {}, "synthetic")


def test_doctor_tells_a_leak_from_a_thermal_relaxation():
    t = np.arange(0, 150, 0.1)
    p0 = 8.5e5
    # simulated with the effect models: a laminar leak with tau_leak = V/(R T G) = 200 s from a
    # chamber whose gas exchanges heat with the wall in ~1 s (so it stays near wall temperature)
    V, hA = 1e-4, 1.0
    G = V / (R * TW * 200.0)
    P, _ = integrate(t, p0, TW, lambda p, T: chamber_rates(p, T, V, hA, TW, mdot_out=leak_mass_flow(p, PR, G)))
    leak = diagnose_bench("bench_chamber", [_chamber_rec(P, t, 1)])
    # gas 6 K above the wall after charging, tau 25 s: levels off
    thermal = diagnose_bench("bench_chamber", [_chamber_rec(closed_chamber(t, p0, TW + 6, TW, 25.0)[0], t, 2)])
    assert [f["effect"] for f in leak["findings"]] == ["external_leak"] and leak["isolable"]
    assert [f["effect"] for f in thermal["findings"]] == ["heat_transfer"] and thermal["isolable"]
    tl = leak["findings"][0]["parameters"]["leak_time_constant_s"]
    assert abs(tl["value"] - 200.0) < max(4 * tl["stderr"], 10.0)
    th = thermal["findings"][0]["parameters"]
    assert abs(th["thermal_time_constant_s"]["value"] - 25.0) < max(4 * th["thermal_time_constant_s"]["stderr"], 2.5)
    assert abs(th["gas_excess_temperature_k"]["value"] - 6.0) < 1.0
    for rep in (leak, thermal):
        n = rep["findings"][0]["heldout_nrmse"]
        assert n["after"] < 0.2 * n["before"]


def test_chamber_refuses_two_charges_as_training_data():
    from pneumatics.errors import RecordingError

    t = np.arange(0, 10, 0.1)
    rec = _chamber_rec(np.full(t.size, 8e5), t, 0)
    with pytest.raises(RecordingError, match="one charge per diagnosis"):
        diagnose_bench("bench_chamber", [rec, rec])


def test_sealed_chamber_is_no_mismatch():
    t = np.arange(0, 100, 0.1)
    rep = diagnose_bench("bench_chamber", [_chamber_rec(np.full(t.size, 8e5), t, 3)])
    assert rep["verdict"] == "no_significant_mismatch" and not rep["findings"]


def _cyl_rec(bar, coulomb, offset, viscous=0.0, seed=0, duration=40.0):
    cfg = load_bench("bench_cylinder")
    rng = np.random.default_rng(seed)
    t = np.arange(0, duration, 0.01)
    period = 8.0
    q = 0.036 * (1 - np.abs(((t / period) % 1) * 2 - 1))          # triangle 0-36 mm, 9 mm/s
    v = np.gradient(q, t)
    pg = bar * 1e5 + rng.normal(0, 300, t.size)
    true = pg * cfg.area_m2 + seal_friction(v, pg, coulomb, coulomb, viscous, viscous)
    force = load_cell_reading(true, offset) + rng.normal(0, 0.1, t.size)
    return Recording(t, {"q.rod": q, "p_a.rod": pg + cfg.room_pa, "force.rod": force}, {}, f"synthetic {bar} bar")


def test_doctor_finds_coulomb_friction_and_says_an_offset_is_not_separable():
    rep = diagnose_bench("bench_cylinder", [_cyl_rec(3, 6.0, 1.5)])
    eff = {f["effect"]: f for f in rep["findings"]}
    assert abs(eff["coulomb_friction"]["parameters"]["coulomb_n"]["value"] - 6.0) < 0.2
    off = eff["force_sensor_offset"]
    assert abs(off["parameters"]["offset_n"]["value"] - 1.5) < 0.2
    assert off["alternatives"] == ["coulomb_friction"] and not rep["isolable"]
    clean = diagnose_bench("bench_cylinder", [_cyl_rec(3, 6.0, 0.0, seed=1)])
    assert [f["effect"] for f in clean["findings"]] == ["coulomb_friction"] and clean["isolable"]


def test_doctor_fits_friction_growth_with_pressure_over_several_files():
    recs = [_cyl_rec(bar, 2.0 + 0.8 * bar, 0.0, seed=bar) for bar in (1, 3, 5, 7)]
    rep = diagnose_bench("bench_cylinder", recs)
    par = {k: v for f in rep["findings"] for k, v in f["parameters"].items()}
    assert abs(par["coulomb_n_per_bar"]["value"] - 0.8) < 0.05
    assert abs(par["coulomb_n"]["value"] - 2.0) < 0.3


def test_a_second_run_of_the_same_seal_can_be_the_held_out_data():
    rep = diagnose_bench("bench_cylinder", [_cyl_rec(3, 6.0, 0.0, seed=4)], [_cyl_rec(3, 6.0, 0.0, seed=5)])
    assert rep["diagnostics"]["heldout_seconds"] == pytest.approx(40.0, abs=0.1)
    f = rep["findings"][0]
    assert f["effect"] == "coulomb_friction" and f["heldout_nrmse"]["after"] < 0.2 * f["heldout_nrmse"]["before"]


def test_mujoco_bench_cylinder_load_cell_reads_pressure_force_plus_friction():
    cfg = load_bench("bench_cylinder")
    t = np.arange(0, 3, 0.01)
    q = 0.01 * (1 - np.abs(((t / 2) % 1) * 2 - 1))
    p = np.full(t.size, 4e5)
    fr = seal_friction(np.gradient(q, t), 0.0, 5.0, 5.0)
    F = replay_cylinder(cfg, t, q, p, fr, offset_n=0.5)
    expect = (p - cfg.room_pa) * cfg.area_m2 + fr + 0.5
    assert np.max(np.abs(F[5:] - expect[5:])) < 0.02 * np.max(expect)


def test_cli_routes_bench_models_to_the_bench_doctor(tmp_path):
    rec = _cyl_rec(3, 6.0, 0.0, duration=20.0)
    rec.to_csv(tmp_path / "r.csv")
    cli_main(["doctor", "--model", "bench_cylinder", str(tmp_path / "r.csv"), "--out", str(tmp_path / "d")])
    rep = json.loads((tmp_path / "d" / "report.json").read_text())
    assert rep["model"] == "bench_cylinder" and rep["verdict"] == "missing_physics"
    assert {"baseline", "calibrated", "findings", "unexplained"} <= set(rep)
    assert (tmp_path / "d" / "report.md").is_file() and (tmp_path / "d" / "friction_fit.png").is_file()


def test_real_bench_doctor_fast_runs(tmp_path):
    from scenarios.common import run_scenario

    m = run_scenario("real_bench_doctor", tmp_path, fast=True, quiet=True)
    assert m["chamber_files"] == 2 and m["friction_files"] == 1
    assert 0.0 <= m["named_fraction"] <= 1.0 and m["median_heldout_nrmse_reduction"] > 0.5
    assert (tmp_path / "table.md").is_file() and (tmp_path / "table.csv").is_file()
