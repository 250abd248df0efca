"""Jet-pipe effects (pneumatics/jetpipe/effects.py) and the jet-pipe doctor."""
import dataclasses
import math

import numpy as np
import pytest

from identification.doctor.jetpipe.diagnose import diagnose_jetpipe
from pneumatics.errors import ConfigError, RecordingError, UnknownNameError
from pneumatics.jetpipe import effects as E
from pneumatics.jetpipe import kernel
from pneumatics.jetpipe.hysteresis import PlayHysteresis
from pneumatics.jetpipe.sim import JetpipeSim, OpenLoopCurrent, build
from pneumatics.recording import Recording, read_csv
from scenarios._jetpipe_cases import make_case


@pytest.fixture(scope="module")
def cfg():
    return build().cfg


def _shut(cfg):
    """The valve centred and staying there (no jet offset, no current: critically lapped, all four
    port areas 0) and no eq. 6 leak."""
    cfg = cfg.replace("leak", slope_m2=0.0, offset_m2=0.0).replace("jet", offset_m=0.0)
    return cfg, np.zeros(7)


def test_external_leak_empties_a_closed_chamber_and_accounts_for_its_mass(cfg):
    cfg, y = _shut(cfg)
    y[4], y[5] = 5e5, 3e5
    fx = E.JetpipeEffects(external_leak_a_m2=2e-8).pack()
    q = cfg.cylinder.chamber1_length_m
    v1 = cfg.cylinder.dead_volume_1_m3 + cfg.cylinder.piston_area_m2 * q
    n, rt = cfg.gas.polytropic_exponent, cfg.gas.gas_constant_j_per_kg_k * cfg.gas.temperature_k
    h, out_mass, prm, plays = 1e-4, 0.0, kernel.pack(cfg), np.zeros(8)
    hyst = PlayHysteresis(cfg.hysteresis_half_width_n, 8)
    hyst.reset(0.0)
    y_ref = y.copy()
    E.reference_step(y_ref, hyst, 0.0, q, 0.0, h, 3, cfg, fx)  # the numpy twin, a few steps
    for k in range(20000):  # 2 s
        m_out = kernel.flow(2e-8, y[4], cfg.supply.room_pa, prm)
        p_before = y[4]
        E.step(y, plays, hyst.radii, 0.0, q, 0.0, h, 1, prm, fx)
        if k == 2:
            np.testing.assert_allclose(y, y_ref, rtol=1e-12, atol=1e-12)
        out_mass += 0.5 * (m_out + kernel.flow(2e-8, y[4], cfg.supply.room_pa, prm)) * h
        assert y[4] <= p_before + 1e-9  # only ever falls
    # eq. 12 with V fixed: d(P V / (n R T))/dt = net mass flow
    assert (5e5 - y[4]) * v1 / (n * rt) == pytest.approx(out_mass, rel=1e-3)
    room = cfg.supply.room_pa
    assert room < y[4] < room + 0.25 * (5e5 - room)  # most of the way towards room pressure
    assert y[5] == pytest.approx(3e5, abs=1e-6)  # the other chamber untouched


def test_piston_leak_conserves_mass_between_the_chambers(cfg):
    cfg, y = _shut(cfg)
    y[4], y[5] = 5e5, 2e5
    fx = E.JetpipeEffects(piston_leak_m2=5e-8).pack()
    q = cfg.cylinder.chamber1_length_m
    c = cfg.cylinder
    v1, v2 = c.dead_volume_1_m3 + c.piston_area_m2 * q, c.dead_volume_2_m3 + c.piston_area_m2 * (c.stroke_m - q)
    total0 = y[4] * v1 + y[5] * v2
    kernel_y = y.copy()
    E.step(kernel_y, np.zeros(8), np.zeros(8), 0.0, q, 0.0, 1e-4, 5000, kernel.pack(cfg), fx)
    assert kernel_y[4] * v1 + kernel_y[5] * v2 == pytest.approx(total0, rel=1e-9)
    assert kernel_y[4] == pytest.approx(kernel_y[5], rel=1e-3)  # equalised


def test_supply_droop_lowers_the_supply_by_k_times_the_supply_flow(cfg):
    y = np.zeros(7)
    y[2], y[4], y[5] = 0.3e-3, 2e5, 2e5  # jet toward port 1: chamber 1 charging
    fx = E.JetpipeEffects(supply_droop_pa_per_kg_s=5e7).pack()
    ps = E.supply_pressure(y, cfg, fx)
    assert 0 < cfg.supply.supply_pa - ps < 0.2 * cfg.supply.supply_pa
    fast = kernel.pack(cfg)
    assert E._supply(y, fast, fx) == pytest.approx(ps, rel=1e-12)
    rate_droop = E.rhs(y, 0.0, 0.0, 0.025, 0.0, cfg.replace("supply", supply_pa=ps), fx)[4]
    rate_nominal = E.rhs(y, 0.0, 0.0, 0.025, 0.0, cfg, E.JetpipeEffects().pack())[4]
    assert 0 < rate_droop < rate_nominal  # chamber 1 charges more slowly


def test_sensor_offsets_change_only_what_is_observed():
    ctl = OpenLoopCurrent(lambda t: 0.03 + 0.02 * math.sin(2 * math.pi * 10 * t))
    runs = []
    for fx in (None, E.JetpipeEffects(pressure_sensor_offset_a_pa=5e3, pressure_sensor_offset_b_pa=-2e3,
                                      force_sensor_offset_n=1.5)):
        sim = JetpipeSim(effects=fx)
        sim.reset(40.0)
        runs.append((sim.run(ctl, 0.05), sim.pressure.copy()))
    (a, pa), (b, pb) = runs
    np.testing.assert_array_equal(pa, pb)  # the physics is untouched
    np.testing.assert_allclose(b["p_a.piston"] - a["p_a.piston"], 5e3, atol=1e-6)
    np.testing.assert_allclose(b["p_b.piston"] - a["p_b.piston"], -2e3, atol=1e-6)
    np.testing.assert_allclose(b["force.piston"] - a["force.piston"], 1.5, atol=1e-9)


def test_valve_lag_delays_the_jet_not_the_measured_current():
    ctl = OpenLoopCurrent(lambda t: 0.0 if t < 0.01 else 0.04)
    recs = []
    for fx in (None, E.JetpipeEffects(valve_lag_s=5e-3)):
        sim = JetpipeSim(effects=fx)
        sim.reset(None)
        recs.append(sim.run(ctl, 0.04))
    a, b = recs
    np.testing.assert_allclose(a["i.piston"], b["i.piston"], atol=1e-12)
    k = np.searchsorted(a.time, 0.013)
    assert b["x_jet.piston"][k] < 0.6 * a["x_jet.piston"][k]  # 3 ms after the step
    assert b["x_jet.piston"][-1] == pytest.approx(a["x_jet.piston"][-1], rel=0.02)  # same end point


def test_compiled_step_matches_the_numpy_reference_with_every_effect_on():
    fx = E.JetpipeEffects(external_leak_a_m2=2e-8, external_leak_b_m2=1e-8, piston_leak_m2=3e-8, valve_lag_s=3e-3,
                          supply_droop_pa_per_kg_s=5e7, hysteresis_extra_half_width_m=3e-5, force_sensor_offset_n=1.0)
    ctl = OpenLoopCurrent(lambda t: 0.03 + 0.03 * math.sin(2 * math.pi * 20 * t))
    recs = []
    for kern in ("fast", "reference"):
        sim = JetpipeSim(kernel=kern, effects=fx)
        sim.reset(45.0)
        recs.append(sim.run(ctl, 0.03))
    for c in ("p_a.piston", "p_b.piston", "force.piston", "x_jet.piston"):
        np.testing.assert_allclose(recs[0][c], recs[1][c], rtol=1e-9, atol=1e-9 * np.ptp(recs[0][c]))
    # and the effects do change the physics
    sim = JetpipeSim()
    sim.reset(45.0)
    assert np.max(np.abs(sim.run(ctl, 0.03)["p_a.piston"] - recs[0]["p_a.piston"])) > 1e3


def test_wider_hysteresis_widens_the_loop(cfg):
    fx = E.JetpipeEffects(hysteresis_extra_half_width_m=4e-5)
    assert fx.half_width_n(cfg) > cfg.hysteresis_half_width_n
    assert E.JetpipeEffects().half_width_n(cfg) == pytest.approx(cfg.hysteresis_half_width_n)


def test_bad_effects_are_clear_errors(cfg):
    with pytest.raises(ConfigError, match="valve_lag_s"):
        E.JetpipeEffects(valve_lag_s=-1e-3)
    with pytest.raises(ConfigError, match="external_leak_a_m2"):
        E.JetpipeEffects(external_leak_a_m2=float("nan"))
    with pytest.raises(ConfigError, match="hysteresis_extra_half_width_m"):
        E.JetpipeEffects(hysteresis_extra_half_width_m=-1e-3).half_width_n(cfg)


# -- the doctor ---------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def clean_case(tmp_path_factory):
    return make_case(tmp_path_factory.mktemp("jp_clean"), 7, None, seconds=2.0, heldout_seconds=1.0)


def _doctor(truth):
    return diagnose_jetpipe("jetpipe", [read_csv(truth["recordings"]["main"])], [read_csv(truth["recordings"]["heldout"])])


def test_doctor_finds_nothing_on_a_clean_recording(clean_case):
    rep = _doctor(clean_case)
    assert rep["verdict"] == "no_significant_mismatch", (rep["findings"], rep["unexplained"])
    assert rep["findings"] == [] and rep["unexplained"] == []
    assert min(rep["baseline"]["heldout_r2"].values()) > 0.95


@pytest.mark.slow  # ~20 s on this machine
def test_doctor_names_a_clear_force_sensor_offset(tmp_path):
    truth = make_case(tmp_path, 8, "force_sensor_offset", seconds=2.0, heldout_seconds=1.0)
    rep = _doctor(truth)
    assert [f["effect"] for f in rep["findings"]] == ["force_sensor_offset"]
    f = rep["findings"][0]
    true = truth["effects"][0]["parameters"]["force_sensor_offset_n"]
    p = f["parameters"]["force_sensor_offset_n"]
    assert abs(p["value"] - true) < max(4 * p["stderr"], 0.05 * abs(true))
    assert f["heldout_nrmse"]["after"] < 0.5 * f["heldout_nrmse"]["before"]


def test_doctor_bad_input_is_a_clear_error(clean_case, tmp_path):
    rec = read_csv(clean_case["recordings"]["main"])
    with pytest.raises(RecordingError, match="kind 'valve_arm'"):
        diagnose_jetpipe("arm2", [rec])
    cols = {k: v for k, v in rec.columns.items() if k != "force.piston"}
    with pytest.raises(RecordingError, match="force.piston"):
        diagnose_jetpipe("jetpipe", [Recording(rec.time, cols, {})])
    kpa = dict(rec.columns, **{"p_b.piston": rec["p_b.piston"] / 1e3})  # kPa, not Pa
    with pytest.raises(RecordingError, match="p_b.piston.*wrong unit"):
        diagnose_jetpipe("jetpipe", [Recording(rec.time, kpa, {})])
    moved = dict(rec.columns, **{"q.piston": rec["q.piston"] + np.linspace(0, 0.01, rec.time.size)})
    with pytest.raises(RecordingError, match="q.piston moves"):
        diagnose_jetpipe("jetpipe", [Recording(rec.time, moved, {})])


def test_cli_routes_jetpipe_and_reports_bad_input_in_one_line(clean_case, tmp_path):
    from pneumasim.cli import main

    rec = read_csv(clean_case["recordings"]["main"])
    Recording(rec.time, {k: v for k, v in rec.columns.items() if k != "force.piston"}, {}).to_csv(tmp_path / "bad.csv")
    with pytest.raises(SystemExit, match=r"pneumasim: error: .*bad.csv: missing column\(s\) force.piston"):
        main(["doctor", "--model", "jetpipe", str(tmp_path / "bad.csv"), "--out", str(tmp_path / "out")])


@pytest.mark.slow  # ~40 s
def test_fitted_effects_replay_what_was_found(tmp_path):
    """The CLI path: report.json/report.md written, the finding usable as a JetpipeEffects."""
    from identification.doctor.jetpipe.diagnose import fitted_effects
    from identification.doctor.jetpipe.report import write

    truth = make_case(tmp_path / "case", 9, "pressure_sensor_offset", seconds=4.0, heldout_seconds=2.0)
    rep = _doctor(truth)
    write(rep, tmp_path / "out")
    for name in ("report.json", "report.md", "heldout_fit.png", "regimes.png", "doctor.rrd"):
        assert (tmp_path / "out" / name).is_file(), name
    fx = fitted_effects(rep)
    assert dataclasses.asdict(fx) != dataclasses.asdict(E.JetpipeEffects())
    field, true = next(iter(truth["effects"][0]["parameters"].items()))
    assert getattr(fx, field) == pytest.approx(true, rel=0.1)


@pytest.mark.slow
def test_fast_blind_benchmark(tmp_path, monkeypatch):
    from scenarios.common import run_scenario

    monkeypatch.setenv("PNEUMASIM_BACKEND", "inline")
    m = run_scenario("doctor_blind_benchmark_jetpipe", tmp_path, fast=True, quiet=True)
    assert m["cases"] == 3
    assert m["null_false_discovery_rate"] == 0.0
    assert m["effect_accuracy"] >= 0.5
    assert (tmp_path / "confusion_matrix.png").is_file()


# -- the report's guards: regimes, Ljung's tests, bootstrap inclusion, .rrd ---------------------
def test_regime_concentration_finds_the_bin_that_holds_the_weight():
    from identification.doctor.jetpipe.regimes import concentrate

    rng = np.random.default_rng(0)
    x, y = rng.uniform(0, 1, 5000), rng.uniform(0, 1, 5000)
    feats = {"time since a command step": x, "pressure p_a": y}
    reg = concentrate(np.where(x < 0.2, 1.0, 0.05), feats)  # the improvement lives right after steps
    assert reg["feature"] == "time since a command step"
    assert reg["bin"][0] == pytest.approx(0.0, abs=1e-3) and reg["bin"][1] == pytest.approx(0.2, abs=0.02)
    assert reg["share"] == pytest.approx(1 / (1 + 4 * 0.05), rel=0.05) and reg["regime"].startswith("within")
    flat = concentrate(np.ones(5000), feats)  # a constant offset: no regime
    assert flat["feature"] is None and flat["regime"].startswith("throughout")


def test_input_cross_correlation_sees_an_input_left_in_the_residual():
    from identification.base.statistics import input_xcorr

    rng = np.random.default_rng(1)
    u = np.cumsum(rng.normal(size=8000)) * 1e-3  # a coloured command
    noise = rng.normal(size=u.size)
    lagged = np.concatenate([np.zeros(5), u[:-5]]) / np.std(u) + noise  # residual carrying u(t - 5 ms)
    hit = input_xcorr([lagged], [u], 1e-3)
    assert hit["max_abs"] > 5 * hit["bound"] and hit["p"] < 1e-6
    white = input_xcorr([rng.normal(size=u.size)], [rng.normal(size=u.size)], 1e-3)  # white input, independent
    assert white["max_abs"] < 1.5 * white["bound"] and white["p"] > 1e-3


def test_two_effect_case_family_names_are_checked(tmp_path):
    with pytest.raises(UnknownNameError, match="coulomb_friction"):
        make_case(tmp_path, 1, ["external_leak", "coulomb_friction"])
    with pytest.raises(UnknownNameError, match="hypothesis"):
        diagnose_jetpipe("jetpipe", [], hypotheses=["backlash"])


def test_doctor_finds_a_concealed_leak_fast(tmp_path):
    """A fresh 1.2 s + 1 s recording with a concealed external leak on chamber a; the doctor,
    limited to three hypotheses (a leak to the room from either chamber, across the piston) and
    1 s of fitting, names it at its place, the held-out fit improves, the residual becomes
    whiter, and the report with its .rrd is written and readable by Rerun."""
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    from identification.doctor.jetpipe.report import write

    truth = make_case(tmp_path / "case", 11, "external_leak", seconds=1.2, heldout_seconds=1.0)
    assert min(truth["r2_nominal_heldout"].values()) >= 0.9  # concealed
    rep = diagnose_jetpipe("jetpipe", [read_csv(truth["recordings"]["main"])],
                           [read_csv(truth["recordings"]["heldout"])],
                           hypotheses=["external_leak", "piston_leak"], fit_seconds=1.0)
    assert [f["effect"] for f in rep["findings"]] == ["external_leak"]
    f = rep["findings"][0]
    assert f["where"] == truth["effects"][0]["where"] == {"actuator": "piston", "chamber": "a"}
    assert f["heldout_nrmse"]["after"] < 0.5 * f["heldout_nrmse"]["before"]
    assert 0.5 <= f["inclusion_probability"] <= 1.0 and f["regime"]
    d = rep["diagnostics"]
    lb = d["ljung_box_heldout"]
    assert lb["after"][f["heldout_channel"]]["q"] < lb["before"][f["heldout_channel"]]["q"]
    assert set(d["input_xcorr_heldout"]["after"]) == set(d["channels"])
    write(rep, tmp_path / "out", plots=False)
    rrd = tmp_path / "out" / "doctor.rrd"
    # the rerun CLI (what `python -m rerun` runs), called directly: it starts 2 s faster
    exe = Path(sys.executable).with_name("rerun")
    cmd = [str(exe)] if exe.is_file() else [shutil.which("rerun") or "rerun"]
    ok = subprocess.run([*cmd, "rrd", "verify", str(rrd)], check=False, capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    md = (tmp_path / "out" / "report.md").read_text()
    assert "Ljung-Box" in md and "external_leak" in md
    assert not list((tmp_path / "out").glob(".*tmp*"))  # atomic writes leave no temporaries
