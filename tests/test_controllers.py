"""Control laws of controllers/: PID and PIDF (paper 002 eqs. 13-15), model-based PIDF
(eqs. 16-17), the iLQG pressure MPC, the perturbation wrappers and the tuning cost."""
import numpy as np
import pytest
from scipy.optimize import lsq_linear

from controllers.ilqg import AirModel, ILQGCfg, PressureMPC, box_qp
from controllers.model_based import ModelBasedCfg
from controllers.perturbation import CommandPerturbation, ExternalPush
from controllers.pid import ARM2_PIDF, BAR, PIDFCfg, valve_commands
from controllers.tuning import LIMIT_PENALTY_DEG, gains_to_x, tracking_cost, x_to_gains
from identification.inverse_dynamics import InverseDynamics, torque_gain
from pneumatics.chamber import integrate
from pneumatics.errors import ConfigError
from pneumatics.recording import Recording
from pneumatics.sim import Observation, Simulation
from pneumatics.valve import valve_areas

NULL = np.full(4, 5.0)


class Const:
    """A reference held at ``q`` (and a JointReference-like grid for the model-based law)."""

    def __init__(self, q):
        self.q0 = np.asarray(q, float)
        self.time = np.linspace(0, 10, 1001)
        self.q = np.tile(self.q0, (self.time.size, 1))

    def reference(self, t):
        return self.q0.copy()

    def derivatives(self, t):
        t = np.atleast_1d(t)
        return np.tile(self.q0, (t.size, 1)), np.zeros((t.size, 2)), np.zeros((t.size, 2))


def obs(q=(0.0, 0.0), p=(4e5, 4e5, 4e5, 4e5), t=0.0):
    return Observation(t, np.asarray(q, float), np.zeros(2), np.asarray(p, float))


def pid(kp=10.0, kd=0.0, ki=0.0, kf=0.0, **kw):
    return PIDFCfg(kp_v_per_rad=(kp, kp), kd_v_s_per_rad=(kd, kd), ki_v_per_rad_s=(ki, ki),
                   kf_v_per_bar=(kf, kf), **kw)


def test_zero_error_gives_the_valve_null():
    for cfg in (pid(), ARM2_PIDF):
        c = cfg.build(Const([0.2, -0.1]), NULL)
        u = c(0.0, obs(q=[0.2, -0.1]))
        np.testing.assert_allclose(u, 5.0)
    # each valve's own null, not a hard-coded 5 V
    null = np.array([4.8, 5.1, 5.0, 4.9])
    u = pid().build(Const([0.0, 0.0]), null)(0.0, obs())
    np.testing.assert_allclose(u, null)


def test_pid_signs_and_antagonism():
    c = pid(kp=10.0).build(Const([0.1, -0.2]), NULL)
    u = c(0.0, obs())
    # joint below its reference: chamber a (positive direction) fills, b exhausts, symmetric
    np.testing.assert_allclose(u, [5 + 1.0, 5 - 1.0, 5 - 2.0, 5 + 2.0])


def test_saturation_at_0_and_10_volt():
    u = pid(kp=1000.0).build(Const([0.5, -0.5]), NULL)(0.0, obs())
    np.testing.assert_allclose(u, [10.0, 0.0, 0.0, 10.0])
    assert valve_commands(NULL, np.array([-7.0, 7.0])).tolist() == [0.0, 10.0, 10.0, 0.0]


def test_pidf_pressure_feedback_opposes_the_measured_difference():
    c = pid(kp=10.0, kf=2.0).build(Const([0.0, 0.0]), NULL)
    u = c(0.0, obs(p=[5e5, 3e5, 3e5, 4e5]))  # d = +2 bar and -1 bar, no position error
    np.testing.assert_allclose(u, [5 - 4.0, 5 + 4.0, 5 + 2.0, 5 - 2.0])


def test_derivative_of_a_ramp_error_converges_to_kd_times_slope():
    c = pid(kp=0.0, kd=2.0).build(Const([0.0, 0.0]), NULL)
    for k in range(100):  # q falls at 1 rad/s: error rises at 1 rad/s
        u = c(k * 0.01, obs(q=[-0.01 * k, 0.0], t=k * 0.01))
    assert u[0] - 5.0 == pytest.approx(2.0, rel=1e-3)


def test_integral_windup_is_clamped_and_recovers():
    cfg = pid(kp=0.0, ki=50.0, integral_limit_v=3.0)
    c = cfg.build(Const([0.0, 0.0]), NULL)
    for k in range(1000):  # 10 s of a constant 0.5 rad error would integrate to 250 V
        u = c(k * 0.01, obs(q=[-0.5, -0.5], t=k * 0.01))
    assert u[0] == pytest.approx(5.0 + 3.0)
    # error reverses: output crosses back through null within 3 V / (50 V/(rad s) * 0.5 rad) = 0.12 s
    for k in range(13):
        u = c(10 + k * 0.01, obs(q=[0.5, 0.5], t=10 + k * 0.01))
    assert u[0] < 5.0


def test_bad_gains_are_rejected():
    with pytest.raises(ConfigError):
        pid(kp=float("nan"))
    with pytest.raises(ConfigError):
        ModelBasedCfg(pidf=pid(kf=0.0)).build(Const([0, 0]), NULL, InverseDynamics(np.ones(8), np.ones(2)))
    with pytest.raises(ConfigError):
        ModelBasedCfg(pidf=ARM2_PIDF).build(Const([0, 0]), NULL, None)


def test_model_based_feedforward_is_the_inverse_dynamics(arm2):
    """Eqs. 16-17: at rest on the reference, the law commands d^ = the model's gravity term;
    if the measured d equals d^ the valves sit at null."""
    q0 = np.array([0.4, -0.3])
    model = InverseDynamics(np.array([0.012, 0.007, 0.015, -0.7, 0.03, 0.02, 0.1, -0.05]), torque_gain(arm2))
    d_hat = model.pressure_difference(q0[None], np.zeros((1, 2)), np.zeros((1, 2)))[0]
    c = ModelBasedCfg(pidf=ARM2_PIDF).build(Const(q0), NULL, model)
    np.testing.assert_allclose(c.feedforward_pa(1.0), d_hat)
    p = np.array([4e5 + d_hat[0] / 2, 4e5 - d_hat[0] / 2, 4e5 + d_hat[1] / 2, 4e5 - d_hat[1] / 2])
    np.testing.assert_allclose(c(0.0, obs(q=q0, p=p)), 5.0, atol=1e-9)
    # measured difference below the prediction: chamber a fills, by k_F per bar
    u = c(0.01, obs(q=q0, p=p - np.array([0.5e5, 0, 0, 0])))
    assert u[0] - 5.0 == pytest.approx(ARM2_PIDF.kf_v_per_bar[0] * 0.5, rel=1e-6)


def test_box_qp_matches_a_bounded_least_squares_solver(rng):
    for _ in range(40):
        a = rng.normal(size=(4, 4))
        h = a @ a.T + 0.1 * np.eye(4)
        g = rng.normal(size=4) * 5
        lo, hi = -rng.uniform(0.1, 1, 4), rng.uniform(0.1, 1, 4)
        x, free = box_qp(h, g, lo, hi)
        chol = np.linalg.cholesky(h)
        ref = lsq_linear(chol.T, -np.linalg.solve(chol, g), bounds=(lo, hi)).x
        def f(v, h=h, g=g):
            return 0.5 * v @ h @ v + g @ v
        assert np.all(x >= lo - 1e-12) and np.all(x <= hi + 1e-12)
        assert f(x) <= f(ref) + 1e-9
        assert np.all(free == ((x > lo + 1e-9) & (x < hi - 1e-9)))


def test_air_model_is_the_fluid_layer_over_a_control_step(arm2):
    """One 10 ms prediction step equals ten 1 ms steps of the numpy reference chamber model."""
    air = AirModel(arm2, 0.01)
    p0 = np.array([2e5, 6e5, 4e5, 1.2e5])
    u = np.array([7.0, 3.0, 5.0, 9.0])
    length = air.lengths(np.array([0.2, -0.3]))
    got = air.step(p0[None], u[None], length, length)[0]
    tab = arm2.tables
    from pneumatics.chamber import chamber_geometry

    vol, rate = chamber_geometry(tab, length, length, 1e-3)
    a_s, a_e = valve_areas(u, tab.valve)
    p = p0.copy()
    for _ in range(10):
        p = integrate(p, vol, rate, a_s, a_e, tab.gas, tab.supply_pa, tab.room_pa, 1e-3)
    np.testing.assert_allclose(got, p, rtol=2e-3)


def test_ilqg_reaches_a_reference_pressure_difference_within_bounds(arm2):
    cfg = ILQGCfg(horizon=3)
    air = AirModel(arm2, cfg.step_s)
    mpc = PressureMPC(cfg, air, arm2.tables.valve[:, 0])
    p = np.full(4, 4e5)
    q = np.zeros((cfg.horizon + 1, 2))
    d_ref = np.tile([1.5e5, -1.0e5], (cfg.horizon, 1))
    length = air.lengths(q[0])
    for _ in range(15):
        u = mpc.solve(p, q, d_ref)
        assert np.all((u >= 0.0) & (u <= 10.0))
        p = air.step(p[None], u[None], length, length)[0]
    d = (p[0::2] - p[1::2]) / BAR
    np.testing.assert_allclose(d, [1.5, -1.0], atol=0.1)
    # redundancy resolved towards closed valves: once there, the commands are near 5 V
    assert np.abs(u - 5.0).max() < 1.0


def test_ilqg_stays_at_null_when_already_on_the_reference(arm2):
    cfg = ILQGCfg(horizon=2)
    air = AirModel(arm2, cfg.step_s)
    mpc = PressureMPC(cfg, air, arm2.tables.valve[:, 0])
    q = np.zeros((3, 2))
    length = air.lengths(q[0])
    p = np.full(4, 4e5)
    # the pressure reached at null in one step, as reference: nothing to do
    p1 = air.step(p[None], np.full((1, 4), 5.0), length, length)[0]
    p2 = air.step(p1[None], np.full((1, 4), 5.0), length, length)[0]
    d_ref = np.array([p1[0::2] - p1[1::2], p2[0::2] - p2[1::2]])
    u = mpc.solve(p, q, d_ref)
    np.testing.assert_allclose(u, 5.0, atol=0.05)


def test_command_perturbation_is_antagonistic_bounded_and_repeatable():
    inner = pid(kp=0.0).build(Const([0, 0]), NULL)
    a, b = CommandPerturbation(inner, 1.5, 0.1, seed=4), CommandPerturbation(inner, 1.5, 0.1, seed=4)
    ua = np.array([a(k * 0.01, obs()) for k in range(50)])
    ub = np.array([b(k * 0.01, obs()) for k in range(50)])
    np.testing.assert_array_equal(ua, ub)
    np.testing.assert_allclose(ua[:, 0] - 5, -(ua[:, 1] - 5))
    assert np.abs(ua - 5).max() <= 1.5
    assert len(np.unique(ua[:, 0])) >= 4  # changes every 0.1 s


def test_external_push_only_inside_its_window(arm2):
    sim = Simulation(arm2)
    bid = sim.model.body("forearm").id
    push = ExternalPush(pid().build(Const([0, 0]), NULL), sim, "forearm", [(0.5, 0.7, (3.0, 0.0, 0.0))])
    push.reset()
    push(0.4, obs())
    assert not sim.data.xfrc_applied[bid].any()
    push(0.6, obs())
    np.testing.assert_allclose(sim.data.xfrc_applied[bid, :3], [3.0, 0, 0])
    push(0.7, obs())
    assert not sim.data.xfrc_applied[bid].any()


def test_tuning_parameterisation_and_limit_penalty(arm2):
    x = gains_to_x(ARM2_PIDF, "pidf")
    back = x_to_gains(x, "pidf")
    np.testing.assert_allclose(back.kp_v_per_rad, ARM2_PIDF.kp_v_per_rad)
    np.testing.assert_allclose(back.kf_v_per_bar, ARM2_PIDF.kf_v_per_bar)
    assert x_to_gains(x[:5], "pid").kf_v_per_bar == (0.0, 0.0)
    jr = arm2.joint_range()
    t = np.arange(0, 2, 0.01)
    ref = np.column_stack([0.5 * np.sin(t), 0 * t])
    slow = Recording(t, {"q.shoulder": ref[:, 0] + 0.01, "q.elbow": ref[:, 1],
                         "ref.shoulder": ref[:, 0], "ref.elbow": ref[:, 1]}, {})
    mae, hit = tracking_cost(slow, jr)
    assert mae == pytest.approx(np.degrees(0.01) / 2) and not hit
    q = np.minimum(jr[0, 1], 4 * t)  # runs into the limit at 4 rad/s
    bang = Recording(t, {"q.shoulder": q, "q.elbow": 0 * t, "ref.shoulder": 0 * t, "ref.elbow": 0 * t}, {})
    assert tracking_cost(bang, jr)[1]
    assert LIMIT_PENALTY_DEG >= 100


def test_nelder_mead_restarts_run_through_the_sweep_api():
    from controllers.tuning import tune

    res = tune("pidf", restarts=2, backend="inline", duration_s=1.5, maxfev=4, seed=3)
    assert len(res["restarts"]) == 2
    for r in res["restarts"]:  # the simplex keeps its best vertex: never worse than its start
        assert r["cost"] <= r["start_cost"] and r["nfev"] <= 5
    assert res["best"]["cost"] == min(r["cost"] for r in res["restarts"])
    assert all(k > 0 for k in res["cfg"].kf_v_per_bar)
