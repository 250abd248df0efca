"""identification.inverse_dynamics: the 8-parameter model of paper 002 eqs. 1-5."""
import mujoco
import numpy as np
import pytest

from controllers.pid import ARM2_PIDF
from controllers.reference import hand_moved
from identification import inverse_dynamics as idyn
from pneumatics.errors import PneumasimError
from pneumatics.recording import Recording
from pneumatics.runner import run
from pneumatics.sim import Simulation


def mujoco_torques(robot, q, qd, qdd):
    m, d = robot.model, mujoco.MjData(robot.model)
    out = np.empty_like(q)
    for k in range(q.shape[0]):
        d.qpos[:], d.qvel[:], d.qacc[:] = q[k], qd[k], qdd[k]
        mujoco.mj_inverse(m, d)
        out[k] = d.qfrc_inverse
    return out


def test_model_structure_fits_mujoco_rigid_body_exactly(arm2, rng):
    """The paper's sanity check: fitted to a rigid-body simulator's inverse dynamics (d = tau),
    the model has zero error; the lumped parameters are the arm's known numbers."""
    n = 300
    q, qd, qdd = rng.uniform(-1, 1, (n, 2)), rng.normal(0, 3, (n, 2)), rng.normal(0, 50, (n, 2))
    gain = idyn.torque_gain(arm2)
    tau = mujoco_torques(arm2, q, qd, qdd)
    s = idyn.Samples(np.arange(n) * 0.01, q, qd, qdd, tau / gain)
    model = idyn.fit(s, gain)
    assert idyn.r2(model, s)["pooled"] == pytest.approx(1.0, abs=1e-12)
    m2, l2 = 0.45, 0.16
    w = dict(zip(idyn.PARAM_NAMES, model.params))
    assert w["w3_inertia_elbow_kg_m2"] == pytest.approx(0.0035 + m2 * l2 ** 2 + 3.8e-5, rel=1e-9)
    assert w["w4_gravity_n_m"] == pytest.approx(-m2 * 9.81 * l2, rel=1e-9)  # arm points up at q = 0
    assert w["w5_viscous_shoulder_n_m_s"] == pytest.approx(0.03, rel=1e-9)
    assert w["w6_viscous_elbow_n_m_s"] == pytest.approx(0.02, rel=1e-9)
    assert abs(w["w7_offset_shoulder_n_m"]) < 1e-9 and abs(w["w8_offset_elbow_n_m"]) < 1e-9


def test_coriolis_terms_are_the_christoffel_symbols_of_m(rng):
    """Eq. 2 follows from eq. 1: n_i = sum_jk (dM_ij/dq_k - 1/2 dM_jk/dq_i) qd_j qd_k."""
    w = np.array([0.02, 0.007, 0.015, 0.0, 0.0, 0.0, 0.0, 0.0])
    q, qd = rng.uniform(-1, 1, 2), rng.normal(0, 2, 2)

    def mass(qq):
        y = idyn.regressor(qq[None], np.zeros((1, 2)), np.eye(2)[None, 0]) @ w, \
            idyn.regressor(qq[None], np.zeros((1, 2)), np.eye(2)[None, 1]) @ w
        return np.column_stack([y[0][0], y[1][0]])

    h = 1e-6
    dm = [(mass(q + h * e) - mass(q - h * e)) / (2 * h) for e in np.eye(2)]  # dm[k][i, j]
    expect = np.array([sum((dm[k][i, j] - 0.5 * dm[i][j, k]) * qd[j] * qd[k] for j in range(2) for k in range(2))
                       for i in range(2)])
    got = idyn.regressor(q[None], qd[None], np.zeros((1, 2)))[0] @ w
    np.testing.assert_allclose(got, expect, rtol=1e-6, atol=1e-12)


@pytest.fixture(scope="module")
def pidf_recording(arm2):
    ref = hand_moved(arm2.joint_names, arm2.joint_range(), 8.0, seed=5, speed=1.5)
    sim = Simulation(arm2)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=4e5)
    return run(sim, ARM2_PIDF.build(ref, arm2.tables.valve[:, 0]), 8.0, seed=2)


def test_fit_on_a_noisy_simulated_recording(arm2, pidf_recording):
    """From angles and pressures alone (noise, DAQ averaging, rod-side area not modelled) the
    fit predicts held-out pressure differences well and finds the rigid-body numbers."""
    from identification.doctor.valve_arm.data import split

    a, b = split(pidf_recording, 0.3)
    model = idyn.fit(idyn.samples(a, arm2.joint_range()), idyn.torque_gain(arm2))
    assert idyn.r2(model, idyn.samples(b, arm2.joint_range()))["pooled"] > 0.9
    w = dict(zip(idyn.PARAM_NAMES, model.params))
    assert w["w4_gravity_n_m"] == pytest.approx(-0.45 * 9.81 * 0.16, rel=0.2)
    assert w["w3_inertia_elbow_kg_m2"] == pytest.approx(0.015058, rel=0.25)
    assert np.all(np.isfinite(model.stderr)) and np.all(model.stderr > 0)


def test_save_and_load_roundtrip(tmp_path, arm2):
    m = idyn.InverseDynamics(np.arange(1.0, 9.0), idyn.torque_gain(arm2), np.full(8, 0.1))
    m.save(tmp_path / "m.json")
    back = idyn.InverseDynamics.load(tmp_path / "m.json")
    np.testing.assert_array_equal(back.params, m.params)
    np.testing.assert_array_equal(back.gain_m3, m.gain_m3)
    with pytest.raises(PneumasimError, match="missing key"):
        idyn.InverseDynamics.from_dict({"params": {}})


def test_bad_recordings_get_clear_errors(arm2, pidf_recording):
    cols = {k: v for k, v in pidf_recording.columns.items() if k != "p_b.elbow"}
    with pytest.raises(PneumasimError, match="p_b.elbow"):
        idyn.samples(Recording(pidf_recording.time, cols, {}), arm2.joint_range())
    with pytest.raises(PneumasimError, match="too short"):
        idyn.samples(pidf_recording.slice(0, 0.2), arm2.joint_range())


def test_parameter_spread():
    p = np.array([[1.0, -2.0], [1.2, -2.0], [0.8, -2.0]])
    np.testing.assert_allclose(idyn.param_cv(p), [0.2, 0.0])
