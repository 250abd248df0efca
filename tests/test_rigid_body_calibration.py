"""The rigid body's calibration: parallel filtering keeps the inertia fit unbiased by the
angle noise, and parameters the motions cannot identify stay nominal (mechanics.py)."""
import numpy as np
import pytest
from scipy.interpolate import make_smoothing_spline

from controllers.pid import ARM2_PIDF
from controllers.reference import hand_moved
from identification.doctor.valve_arm.data import prepare
from identification.doctor.valve_arm.mechanics import calibrate_rigid_body
from identification.doctor.valve_arm.torque_balance import torque_data
from identification.base.smoothing import spline_cutoff_hz
from pneumatics.robot import load_robot
from pneumatics.runner import run
from pneumatics.sim import Simulation


@pytest.mark.parametrize("lam", [1e-6, 1e-5, 1e-4])  # 16, 9, 5 Hz at 100 Hz
def test_spline_cutoff_is_where_the_spline_halves_a_sinusoid(lam):
    dt = 0.01
    t = np.arange(0, 40, dt)
    fc = spline_cutoff_hz(lam, dt)
    for f, expected in ((0.2 * fc, 1 / (1 + 0.2 ** 4)), (fc, 0.5), (1.5 * fc, 1 / (1 + 1.5 ** 4))):
        y = np.sin(2 * np.pi * f * t)
        gain = np.std(make_smoothing_spline(t, y, lam=lam)(t)[400:-400]) / np.std(y[400:-400])
        assert gain == pytest.approx(expected, abs=0.03)


def _recording(robot, seconds=40.0, seed=5, **kw):
    ref = hand_moved(robot.joint_names, robot.joint_range(), seconds, seed=seed)
    sim = Simulation(robot)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=4.5e5)
    run(sim, ARM2_PIDF.build(ref, robot.tables.valve[:, 0]), 1.0, seed=seed)
    sim.data.time = 0.0
    return run(sim, ARM2_PIDF.build(ref, robot.tables.valve[:, 0]), seconds, seed=seed + 7, **kw)


def _links_off():
    """arm2 with its upper link 8 % heavier and its forearm 6 % lighter than the model."""
    true = load_robot("arm2")
    for body, k in (("upper_link", 1.08), ("forearm", 0.94)):
        i = true.model.body(body).id
        true.model.body_mass[i] *= k
        true.model.body_inertia[i] *= k
    return true


def test_link_inertias_are_recovered_through_the_angle_noise():
    """Links 8 % heavier and 6 % lighter than the model, the sensors' 0.05 deg angle noise:
    without parallel filtering this fit gave the upper link +14 % and both armatures at a bound."""
    robot, true = load_robot("arm2"), _links_off()
    rec = _recording(true)
    td = torque_data(prepare(robot, rec))
    assert 1.0 < td.lowpass_hz < 5.0  # a fifth of where the angle spline halves (~10-15 Hz)
    fit = calibrate_rigid_body(td)
    got = dict(zip(fit.names, 1 + fit.values))
    assert got["mass_scale.upper_link"] == pytest.approx(1.08, abs=0.02)
    assert got["mass_scale.forearm"] == pytest.approx(0.94, abs=0.01)
    assert got["damping_scale.shoulder"] == pytest.approx(1.0, abs=0.03)
    assert got["damping_scale.elbow"] == pytest.approx(1.0, abs=0.03)
    # the shoulder armature and the upper link's inertia are one column: one is fitted
    assert "mass_scale.upper_link" in td.fixed["armature_scale.shoulder"]
    # a 0.25 % share of the elbow's inertia: not identifiable, kept at nominal, not at a bound
    assert "not identifiable" in td.fixed["armature_scale.elbow"] and got["armature_scale.elbow"] == 1.0
    assert np.isnan(fit.stderr[fit.names.index("armature_scale.elbow")]) and fit.at_bound == []


def test_noise_free_angles_fit_the_nominal_model():
    """Without noise the angle spline still smooths a little (its noise estimate is the
    signal's own third difference); the filtered fit must then give the model back."""
    robot = load_robot("arm2")
    td = torque_data(prepare(robot, _recording(robot, seconds=20.0, noise=False, average=False), averaged=False))
    fit = calibrate_rigid_body(td)
    got = dict(zip(fit.names, 1 + fit.values))
    assert got["mass_scale.forearm"] == pytest.approx(1.0, abs=0.005)
    assert got["mass_scale.upper_link"] == pytest.approx(1.0, abs=0.02)


def test_an_effect_the_calibration_took_up_hands_the_inertias_back_when_fitted_beside_it():
    """An encoder reading 0.06 rad high on the shoulder: alone, the calibration takes part of
    the offset's gravity torque as wrong link masses; fitted jointly with the offset's
    regressor (what the doctor does once it keeps the offset) the true masses come back."""
    from identification.doctor.valve_arm.hypotheses import mechanical_hypotheses
    from identification.doctor.valve_arm.screening import stack_terms

    robot, true = load_robot("arm2"), _links_off()
    rec = _recording(true)
    rec.columns["q.shoulder"] = rec.columns["q.shoulder"] + 0.06
    exp = prepare(robot, rec)
    td = torque_data(exp)
    alone = dict(zip(td.names, 1 + calibrate_rigid_body(td).values))
    (offset,) = [h for h in mechanical_hypotheses(robot) if h.label == "angle_sensor_offset@shoulder"]
    joint = dict(zip(td.names, 1 + calibrate_rigid_body(td, *stack_terms(None, offset.regressor(exp, td), offset)).values))
    assert abs(alone["mass_scale.upper_link"] - 1.08) > 0.04 or abs(alone["mass_scale.forearm"] - 0.94) > 0.04
    assert joint["mass_scale.upper_link"] == pytest.approx(1.08, abs=0.02)
    assert joint["mass_scale.forearm"] == pytest.approx(0.94, abs=0.01)
    assert td.calibration.names == td.names  # the rigid body's part only, as fit_rigid_body holds it


@pytest.mark.parametrize("name", ["arm2", "humanoid38"])
def test_a_joints_damping_and_armature_regressors_are_its_own_rate_and_acceleration(name, rng):
    """torque_balance.own_dof_regressor (b qd_j, a qdd_j at the joint's own dof) against the
    inverse dynamics with the damping or armature doubled less the nominal's, at random states,
    some past the joint limits (where MuJoCo's inverse dynamics holds the limits' forces)."""
    from identification.doctor.valve_arm.torque_balance import finite_difference_regressor, own_dof_regressor

    robot = load_robot(name)
    lo, hi = robot.joint_range().T
    n = 40
    q = lo + (hi - lo) * rng.uniform(-0.05, 1.05, (n, lo.size))
    qd, qdd = rng.normal(0, 2, q.shape), rng.normal(0, 20, q.shape)
    qadr, dadr = robot.qpos_index, robot.dof_index
    checked = 0
    for j in range(lo.size):
        for attr in ("dof_damping", "dof_armature"):
            fast = own_dof_regressor(robot.model, attr, j, dadr, qd, qdd)
            if fast is None:
                continue
            slow = finite_difference_regressor(robot.model, attr, j, qadr, dadr, q, qd, qdd)
            np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-9 * max(np.abs(slow).max(), 1e-6))
            checked += 1
    assert checked >= lo.size
