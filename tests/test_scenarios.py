"""Every scenario's --fast version runs through the CLI entry and shows the paper's behaviour."""
import json
import subprocess
import sys

import pytest

from scenarios.common import run_scenario, scenario_names


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    return tmp_path_factory.mktemp("runs")


def run(name, out, **kw):
    return run_scenario(name, out / name, fast=True, quiet=True, **kw)


def test_list_names_every_scenario():
    text = subprocess.run([sys.executable, "-m", "pneumasim.cli", "run", "--list"], capture_output=True,
                          text=True, check=True).stdout
    for name in scenario_names():
        assert name in text


def test_asymptotic_pressure(out):
    m = run("arm2_asymptotic_pressure", out)
    assert m["asymptote_spread_pa"] < 1000.0          # same asymptote from 1 and 7 bar
    assert m["asymptote_monotone"] == 1
    assert 1.2e5 < m["asymptote_4_5v_pa"] < 2.0e5     # reference: ~1.5 bar
    assert 4.8e5 < m["asymptote_5v_pa"] < 5.8e5       # reference: ~5.3 bar, intermediate
    assert 6.6e5 < m["asymptote_5_5v_pa"] < 7.0e5     # reference: ~6.9 bar
    assert m["t90_near_null_s"] > 10 * m["t90_full_open_s"]
    assert abs(m["t90_argmax_v"] - 5.0) <= 0.5
    assert (out / "arm2_asymptotic_pressure" / "asymptotic_pressure.png").stat().st_size > 10_000


def test_plastoelastic(out):
    m = run("arm2_plastoelastic", out)
    assert m["push_excursion_deg"] > 5.0
    assert m["return_error_deg"] < 1.0
    assert m["equilibrium_shift_deg"] > 10.0 * max(m["return_error_deg"], 0.5)


def test_step_response(out):
    m = run("arm2_step_response", out)
    assert 1200.0 <= m["peak_velocity_deg_s"] <= 1700.0
    assert m["antagonist_peak_after_velocity_peak"] == 1 and m["antagonist_peak_pressure_pa"] > 1.05e5
    assert m["peak_velocity_5v_deg_s"] < 0.5 * m["peak_velocity_deg_s"]
    assert m["min_velocity_after_peak_5v_deg_s"] < 0.5 * m["peak_velocity_5v_deg_s"]  # nearly stops


def test_humanoid38_demo(out):
    m = run("humanoid38_demo", out)
    assert m["finite"] == 1 and m["mujoco_warnings"] == 0
    assert 0.3e5 < m["min_pressure_pa"] and m["max_pressure_pa"] < 15e5
    assert m["joint_travel_median_frac"] > 0.1


def test_demo_writes_recording_plot_and_rerun_file(out):
    m = run("demo", out)
    d = out / "demo"
    assert m["rms_err_deg_shoulder"] < 6 and m["rms_err_deg_elbow"] < 6
    assert m["doctor_correct"] == 1, m["doctor_named"]  # the main job ends with the doctor right
    assert (d / "doctor" / "report.json").is_file() and (d / "doctor_case" / "mystery.truth.json").is_file()
    for f in ("arm2_demo.csv", "arm2_demo.png", "demo.rrd", "metrics.json"):
        assert (d / f).is_file(), f
    assert json.loads((d / "metrics.json").read_text()) == m
    subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", str(d / "demo.rrd")], check=True,
                   capture_output=True)


def test_python_m_entry_point(tmp_path):
    subprocess.run([sys.executable, "-m", "scenarios.arm2_plastoelastic", "--fast", "--out", str(tmp_path)],
                   check=True, capture_output=True)
    assert json.loads((tmp_path / "metrics.json").read_text())["return_error_deg"] < 1.0


def test_unknown_scenario_is_one_clear_line():
    r = subprocess.run([sys.executable, "-m", "pneumasim.cli", "run", "arm3_nothing"], capture_output=True, text=True)
    assert r.returncode != 0
    assert r.stderr.strip().startswith("pneumasim: error: unknown scenario 'arm3_nothing'; valid: ")
    assert "Traceback" not in r.stderr


def test_doctor_blind_benchmark_fast(out, monkeypatch):
    """Three fresh cases (null, Coulomb friction, valve hysteresis), 20 s + 10 s each; in this
    process (inline), which has compiled the simulation loop already (a worker would again)."""
    monkeypatch.setenv("PNEUMASIM_BACKEND", "inline")
    m = run("doctor_blind_benchmark", out)
    assert m["cases"] == 3
    assert m["null_false_discovery_rate"] == 0.0
    assert m["effect_accuracy"] >= 0.5 and m["location_accuracy"] >= 0.5
    assert m["median_heldout_nrmse_reduction"] >= 0.3
    assert (out / "doctor_blind_benchmark" / "confusion_matrix.png").is_file()
