"""The papers' experiments added by issue 21: their building blocks, and each scenario's --fast
version showing the figure's behaviour."""
import numpy as np
import pytest

import models
from pneumatics.errors import PneumasimError
from pneumatics.jetpipe.params import load_jetpipe_cfg
from scenarios.common import run_scenario


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    return tmp_path_factory.mktemp("paper_runs")


def _fast(name, out):
    return run_scenario(name, out / name, fast=True, quiet=True)


@pytest.fixture(scope="module")
def jet_cfg():
    return load_jetpipe_cfg(models.fluid_path("jetpipe"))


# -- building blocks ---------------------------------------------------------------------
def test_third_order_fit_recovers_exact_parameters(jet_cfg):
    from pneumatics.jetpipe.jet_sweep import JetResponse, fit_third_order, third_order

    f = np.logspace(1, 3, 30)
    truth = (4e-3, 900.0, 2000.0, 0.35)
    fit = fit_third_order(JetResponse(f, third_order(f, *truth), 0.04, 0.0, False))
    assert fit.r2 > 0.999999
    assert (fit.gain_m_per_a, fit.omega1_rad_s, fit.omega2_rad_s, fit.zeta) == pytest.approx(truth, rel=1e-4)


def test_jet_response_without_hysteresis_is_eq3_times_the_driver(jet_cfg):
    """Small amplitude, no hysteresis: the tanh is linear, so the response is k_m x_sat / F_sat
    times the driver's first-order lag times eq. 3."""
    from pneumatics.jetpipe.jet_sweep import jet_frequency_response, third_order

    f = np.array([50.0, 200.0, 400.0])
    resp = jet_frequency_response(jet_cfg, f, 0.002, hysteresis=False)
    j, d = jet_cfg.jet, jet_cfg.driver
    wd = 2 * np.pi * d.corner_hz
    expected = third_order(f, d.force_constant_n_per_a * j.saturation_m / j.saturation_force_n,
                           j.omega1_rad_s, j.omega2_rad_s, j.damping_ratio) * wd / (2j * np.pi * f + wd)
    assert np.abs(resp.gain_m_per_a / expected - 1) == pytest.approx(0, abs=2e-3)


def test_jet_response_rejects_bad_amplitude(jet_cfg):
    from pneumatics.jetpipe.jet_sweep import jet_frequency_response

    with pytest.raises(PneumasimError, match="amplitude"):
        jet_frequency_response(jet_cfg, [10.0], 1.0)


def test_linear_model_holds_the_operating_point_and_matches_its_dc_gain(jet_cfg):
    from pneumatics.jetpipe.linear import linearize, operating_point
    from pneumatics.jetpipe.linear_sim import LinearJetpipe
    from pneumatics.jetpipe.sim import OpenLoopCurrent

    op = operating_point(45.0, jet_cfg)
    lin = LinearJetpipe(op, jet_cfg)
    rec = lin.run(OpenLoopCurrent(lambda t: op.current_a), 0.05)
    assert np.allclose(rec["force.piston"], 45.0)
    a, b, c, _ = linearize(op, jet_cfg)
    dc = float(-(c @ np.linalg.solve(a, b))[0, 0])  # N/A
    rec = lin.run(OpenLoopCurrent(lambda t: op.current_a + 1e-3), 3.0)
    assert rec["force.piston"][-1] - 45.0 == pytest.approx(dc * 1e-3, rel=2e-2)


def test_period_rates_are_exact_on_quadratic_pressures():
    from identification.air_dynamics import HeldOutRecord, period_rates

    t = np.arange(200) * 1e-3
    p = np.column_stack([2e5 + 3e6 * t - 4e6 * t ** 2, 5e5 - 1e5 * t])
    rec = HeldOutRecord(t, p, np.column_stack([0.01 + 0.2 * t]), np.zeros_like(p), 10)
    r = period_rates(rec)
    assert r.time.size == 20
    assert r.measured_rate[:, 0] == pytest.approx(3e6 - 8e6 * r.time)
    assert r.measured_rate[:, 1] == pytest.approx(-1e5)
    assert r.length_rate[:, 0] == pytest.approx(0.2)


# -- scenarios -----------------------------------------------------------------------------
def test_jetpipe_swept_sine(out):
    m = _fast("jetpipe_swept_sine", out)
    assert m["model_fit_r2_no_hysteresis"] > 0.98      # eq. 3 + the driver pole: third order fits
    assert 0.85 < m["model_fit_r2"] < m["model_fit_r2_no_hysteresis"]  # hysteresis: a phase lag eq. 3 lacks
    assert m["fit_omega2_rad_s"] == pytest.approx(1856.7, rel=0.15)    # the resonance stays
    assert m["fit_omega1_rad_s"] < 973.8               # the driver and hysteresis lags pull w1 down
    assert (out / "jetpipe_swept_sine" / "swept_sine.png").stat().st_size > 10_000


def test_jetpipe_saturation(out):
    m = _fast("jetpipe_saturation", out)
    assert m["saturated_share_kp_20"] == 0 and m["saturated_share_kp_50"] == 0  # paper: 50 is the limit
    assert m["saturated_share_kp_80"] > 0.05            # Fig. 19(d)
    assert m["max_err_n_kp_50"] < m["max_err_n_kp_20"] < 2.5  # Fig. 20: 0.89 N and 1.97 N
    assert m["max_err_n_kp_80"] > m["max_err_n_kp_50"]  # saturation spoils the tracking
    assert 0.95 < m["gain_5hz"] < 1.08


def test_jetpipe_linear_vs_nonlinear(out):
    m = _fast("jetpipe_linear_vs_nonlinear", out)
    assert m["force_amplitude_n_nonlinear"] > 4.0
    assert m["max_force_diff_n"] < 0.1 * 2 * 5.0  # the two models agree at 45 N (Fig. 22)
    assert m["max_force_diff_n_25n"] > m["max_force_diff_n"]  # and less well away from it


def test_arm2_air_dynamics_fit(out):
    m = _fast("arm2_air_dynamics_fit", out)
    assert m["r2_pdot_min"] > 0.8
    for c in ("shoulder_a", "shoulder_b", "elbow_a", "elbow_b"):
        assert m[f"r2_pdot_{c}"] > m[f"noise_floor_r2_{c}"] - 0.05  # near what the sensor noise allows


def test_arm2_mpc_pressure(out):
    m = _fast("arm2_mpc_pressure", out)
    assert m["pressure_diff_rmse_pa"] < 0.1 * m["reference_diff_rms_pa"]  # 'indistinguishable'
    assert m["pressure_diff_rmse_pa"] < 1e4
    assert m["realized_pressure_diff_rmse_pa"] < 0.15 * m["reference_diff_rms_pa"]


def test_real_bench_friction_predicts_a_held_out_pressure(out):
    """X-ring257: each pressure's run predicted from the other three (thesis data)."""
    from scenarios.real_bench_friction_heldout import friction_files

    try:
        friction_files()
    except PneumasimError:
        pytest.skip("the thesis data (shared/real) is not beside the repository")
    m = _fast("real_bench_friction_heldout", out)
    assert m["heldout_files"] == 4
    assert m["heldout_nrmse_median"] < 0.5 * m["nominal_nrmse_median"]  # friction explains most of F - pA
    assert m["in_file_nrmse_median"] <= m["heldout_nrmse_median"]       # a prediction is no better than a fit
    assert m["heldout_nrmse_median_interpolation"] < m["heldout_nrmse_median_extrapolation"]


def test_jetpipe_servo_rate_timing_assumptions(out):
    m = _fast("jetpipe_servo_rate", out)
    # at 70 Hz the output delay decides the error: a whole-period delay nearly destabilises the loop
    assert m["max_err_n_70hz_one_tick"] > 10.93 > m["max_err_n_70hz_fixed_1ms"] > m["max_err_n_70hz_no_delay"] * 0.9
    # at 500 Hz the timing hardly matters
    assert abs(m["max_err_n_500hz_one_tick"] - m["max_err_n_500hz_no_delay"]) < 0.3
    assert 0.0 < m["calibrated_delay_fraction_70hz"] < 1.0
    assert m["predicted_max_err_n_500hz_same_time"] > m["predicted_max_err_n_500hz_same_fraction"]
    # proportional alone keeps an offset at any servo rate (Fig. 18)
    assert m["max_err_n_500hz_proportional_no_delay"] > m["max_err_n_500hz_no_delay"] + 0.5


def test_humanoid_tubes_follow_the_body_and_carry_volume_and_delay(tmp_path):
    import math

    from pneumatics.effects.tubes import load_tube_layout, tube_lengths, tube_line_dynamics
    from pneumatics.robot import load_robot

    robot = load_robot("humanoid38")
    layout = load_tube_layout(models.folder("humanoid38") / "tubes.toml")
    lengths = tube_lengths(robot, layout)
    assert set(lengths) == set(robot.actuator_names)
    assert all(v >= layout.offboard_length_m for v in lengths.values())
    for name in robot.actuator_names:
        if name.startswith("left_"):  # the right side mirrors the left
            assert lengths[name] == pytest.approx(lengths["right_" + name[5:]], abs=1e-6)
    assert lengths["left_wrist_pitch"] > lengths["left_elbow"] > lengths["left_shoulder_pitch"] - 0.2
    assert lengths["left_toe"] > lengths["left_knee"] > lengths["left_hip_yaw"]
    line = tube_line_dynamics(robot, layout)["left_knee.a"]
    assert line["delay_s"] == pytest.approx(lengths["left_knee"] / 343.0)
    assert line["volume_m3"] == pytest.approx(math.pi / 4 * 2.5e-3 ** 2 * lengths["left_knee"])
    bad = tmp_path / "tubes.toml"
    bad.write_text("[tubes]\noffboard_length_m = -1\n")
    with pytest.raises(PneumasimError, match=r"tubes.toml: \[tubes\] offboard_length_m"):
        load_tube_layout(bad)


def test_jetpipe_jet_statics(out):
    m = _fast("jetpipe_jet_statics", out)
    assert m["position_loop_gap_mm"] == pytest.approx(0.16, abs=0.005)  # 8 % of the 1 mm range (Fig. 6)
    assert m["gap_spread_mm"] < 0.05                                     # "almost constant" mid-range
    assert m["force_constant_n_per_a"] == pytest.approx(1.946, rel=1e-6)  # Fig. 6(c): linear, k_m
    assert 0.95 < m["position_range_mm"] < 1.0                           # saturates at +-0.5 mm
