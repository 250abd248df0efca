"""The end stop's torque-balance regressor where a stiff bumper is pressed by a few milliradians.

The torque balance's equation error is the angle spline's filter applied to the missing torque
(it enters through the smoothed angle's second derivative).  A bumper evaluated on the smoothed
angle sees the overshoot spread and lowered before the hinge cuts it; evaluated on the barely
smoothed angle and passed through the same spline (Experiment.like_q_s) it matches the filtered
true torque, which is what lets the doctor place such a stop (the variant generator's bumpers,
pressed by 1-5 mrad, were reported unexplained before)."""
import numpy as np
import pytest

from identification.base.smoothing import discrepancy_lambda, smooth_derivatives, smoothing_spline
from identification.doctor.valve_arm.data import Experiment, light_spline
from pneumatics.effects import get_family

STOP_RAD = 0.733


def _recording(rng, noise_rad=8.7e-4, rate_hz=100.0, seconds=20.0):
    """A joint swinging out past STOP_RAD every 4 s, with white angle noise (0.05 deg)."""
    t = np.arange(0.0, seconds, 1.0 / rate_hz)
    q_true = 0.55 + 0.19 * np.sin(2 * np.pi * t / 4.0)
    return t, q_true + rng.normal(0.0, noise_rad, t.size)


def _experiment(t, q):
    lam = discrepancy_lambda(t, q)
    q_s, qd, qdd = smooth_derivatives(t, q, order=2, lam=lam)
    light = light_spline(t, q)
    col = lambda x: x[:, None]
    return Experiment(None, None, t, t, col(q), col(q_s), col(qd), col(qdd), np.zeros((t.size, 2)), np.zeros((t.size, 2)),
                      False, q_light=col(light(t)), qd_light=col(light.derivative(1)(t)), q_lam=np.array([[lam]]))


def _stop_torque_term(exp, td, stop):
    """The equation-error term of a bumper of unit stiffness and damping at ``stop`` (upper side), joint 0."""
    fam = get_family("end_stop")
    return fam.torque_balance_term(exp, td, 0, fam.form_class("spring_damper")(stop, 1.0, 1.0, 1.0))[:, 0]


def test_like_q_s_is_the_angle_spline_applied_per_pooled_recording():
    rng = np.random.default_rng(0)
    t, q = _recording(rng)
    exp = _experiment(t, q)
    x = rng.normal(size=t.size)
    assert np.allclose(exp.like_q_s(x, 0), smoothing_spline(t, x, exp.q_lam[0, 0])(t))
    assert np.allclose(exp.like_q_s(q, 0), exp.q_s[:, 0])  # the angle itself: its own spline
    exp.breaks, exp.q_lam = (t.size // 2,), np.array([[exp.q_lam[0, 0]], [exp.q_lam[0, 0] * 10]])
    h = t.size // 2
    out = exp.like_q_s(x, 0)
    assert np.allclose(out[:h], smoothing_spline(t[:h], x[:h], exp.q_lam[0, 0])(t[:h]))
    assert np.allclose(out[h:], smoothing_spline(t[h:], x[h:], exp.q_lam[1, 0])(t[h:]))


def test_the_bumper_term_is_its_torque_on_the_light_angle_filtered_and_nothing_where_the_joint_is_left_out():
    rng = np.random.default_rng(1)
    t, q = _recording(rng)
    exp = _experiment(t, q)
    pen = np.maximum(exp.q_light[:, 0] - STOP_RAD, 0.0)
    expected = exp.like_q_s(pen + np.where(pen > 0, exp.qd_light[:, 0], 0.0), 0)
    assert np.allclose(_stop_torque_term(exp, None, STOP_RAD), expected)
    assert not np.any(_stop_torque_term(exp, None, 1.0))  # a stop never reached adds nothing
    # where the torque balance leaves the joint out (near the model's own limit) the bumper's
    # torque is zero before the filter: there it would fit the limit's impacts
    left_out = np.zeros((t.size, 1), bool)
    left_out[t < 10.0] = True

    class Td:
        joint_ok = ~left_out
    term = _stop_torque_term(exp, Td, STOP_RAD)
    kept = np.where(t >= 10.0, pen + np.where(pen > 0, exp.qd_light[:, 0], 0.0), 0.0)
    assert np.allclose(term, exp.like_q_s(kept, 0))
    assert np.max(np.abs(term[t < 9.0])) < 1e-3 * np.max(np.abs(term))


@pytest.mark.slow
@pytest.mark.parametrize("seed, form", [(176774977, "progressive_bumper"), (176775022, "linear_bumper")])
def test_a_bumper_of_another_law_pressed_by_a_few_milliradians_is_named(tmp_path, seed, form):
    """The random-form generator's bumpers (development seeds of the eighth fresh run: a
    progressive bumper on the elbow's lower side pressed by ~3 mrad, a linear one on its upper
    side by ~2 mrad) were reported unexplained at the elbow; with the regressor above the
    doctor names the end stop there, at the generator's stop angle."""
    from identification.doctor.valve_arm.diagnose import diagnose
    from pneumatics.recording import read_csv
    from pneumatics.robot import load_robot
    from scenarios._variantsim.cases import make_case
    from scenarios._variantsim.forms_joint import STOP_MARGIN_RAD

    truth = make_case(tmp_path, seed, ["end_stop"], forms=[form], seconds=60.0, heldout_seconds=30.0, name="c")
    hidden = truth["effects"][0]
    rep = diagnose(load_robot("arm2"), [read_csv(tmp_path / "c.csv")], [read_csv(tmp_path / "c_heldout.csv")])
    assert [(f["effect"], f["where"]) for f in rep["findings"]][:1] == [("end_stop", hidden["where"])]
    e, p = hidden["effective"], rep["findings"][0]["parameters"]
    side = "upper" if p["side_sign"]["value"] > 0 else "lower"
    stop = (e["reach_upper_rad"] + STOP_MARGIN_RAD - e["upper_intrusion_rad"] if side == "upper"
            else e["reach_lower_rad"] - STOP_MARGIN_RAD + e["lower_intrusion_rad"])
    assert abs(p["stop_rad"]["value"] - stop) < 0.005
    assert p["stiffness_nm_per_rad"]["value"] > 50  # a stop, not a spring


def test_a_bumper_the_held_out_motions_only_graze_is_left_to_the_training_data():
    """torque_judge.scarce_in_heldout: a stop pressed 10 % of the training samples by 10 mrad and
    grazed by 2 mrad in 0.5 % of the held-out ones carries far less than SCARCE_SHARE of its
    training torque there: the held-out data cannot judge it.  Held-out motions that press it
    as often can; an effect that is not local is never handed over."""
    from types import SimpleNamespace

    from identification.doctor.valve_arm.hypotheses import Hypothesis
    from identification.doctor.valve_arm.screening import Scored
    from identification.doctor.valve_arm.torque_judge import scarce_in_heldout

    n = 2000
    pressed = np.zeros((n, 2, 2))
    pressed[:200, 0, 0], pressed[:200, 0, 1] = 0.010, 0.0
    grazed = np.zeros((n, 2, 2))
    grazed[:10, 0, 0] = 0.002
    train = SimpleNamespace(valid=np.ones(n, bool), mask=lambda a: a)
    held = SimpleNamespace(valid=np.ones(n, bool), mask=lambda a: a)
    exp_t, exp_h = object(), object()
    on_held = {"now": grazed}

    def reg(e, td):
        return pressed if e is exp_t else on_held["now"]

    def scored(local):
        h = Hypothesis("end_stop", {"joint": "j0"}, "mechanical", [("stiffness_nm_per_rad", 20.0, 20.0, np.inf, 0.0),
                       ("damping_nm_s_per_rad", 0.0, 0.0, np.inf, 0.0)], joint=0, regressor=reg, local=local)
        return Scored(h, 0.2, fit=SimpleNamespace(values=np.array([0.01, -0.02, 300.0, 0.5])))

    assert scarce_in_heldout(scored(True), reg(exp_h, held), held, reg(exp_t, train), train)
    on_held["now"] = pressed[::-1].copy()  # the same presses at other times
    assert not scarce_in_heldout(scored(True), reg(exp_h, held), held, reg(exp_t, train), train)
    on_held["now"] = grazed
    assert not scarce_in_heldout(scored(False), reg(exp_h, held), held, reg(exp_t, train), train)
