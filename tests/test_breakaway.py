"""The stick-phase test (identification/doctor/valve_arm/breakaway.py) on a joint whose friction
is known: a link under a slow sinusoidal torque with Karnopp friction (Karnopp 1985), sampled
at 100 Hz as a recording is.  Its holding ratio is the static level over the sliding one."""
import numpy as np
import pytest

from identification.doctor.valve_arm.breakaway import (
    STICTION_HOLDING_RATIO, breakaway_test, sliding_level, stick_phases, white_noise_std)

INERTIA = 0.02      # kg m^2, an arm2 link
RATE_HZ = 100.0


def karnopp_link(fs_nm: float, fc_nm: float, seconds: float = 30.0, seed: int = 0, noise_nm: float = 0.003):
    """(residual, qd) at 100 Hz of a link with Karnopp friction (stuck while |v| < 1e-3 rad/s
    and the drive torque |tau| <= fs, else fc against the motion), driven by a PD loop of
    stiffness 4 N m/rad towards q_ref = 0.5 sin(2 pi 0.25 t) + 0.1 sin(2 pi 0.9 t): at every
    reversal it sticks until the loop's torque reaches fs.  The residual is what the torque
    balance sees with friction left out, tau - I qdd, plus sensor noise."""
    dt = 1e-4
    t = np.arange(0.0, seconds, dt)
    ref = 0.5 * np.sin(2 * np.pi * 0.25 * t) + 0.1 * np.sin(2 * np.pi * 0.9 * t)
    q, v = np.zeros_like(t), np.zeros_like(t)
    tau = np.zeros_like(t)
    for k in range(len(t) - 1):
        tau[k] = 4.0 * (ref[k] - q[k]) - 0.05 * v[k]
        if abs(v[k]) < 1e-3 and abs(tau[k]) <= fs_nm:
            v[k + 1], q[k + 1] = 0.0, q[k]
            continue
        direction = np.sign(v[k]) if abs(v[k]) >= 1e-3 else np.sign(tau[k])
        v[k + 1] = v[k] + dt * (tau[k] - fc_nm * direction) / INERTIA
        q[k + 1] = q[k] + dt * v[k + 1]
    step = int(round(1.0 / (RATE_HZ * dt)))
    vs, taus = v[::step], tau[::step]
    qdd = np.gradient(vs, 1.0 / RATE_HZ)
    noise = np.random.default_rng(seed).normal(0.0, noise_nm, vs.size)
    return taus - INERTIA * qdd + noise, vs


@pytest.mark.parametrize("fs, fc", [(0.3, 0.1), (0.25, 0.1)])
def test_stiction_breaks_away_at_its_static_level(fs, fc):
    residual, qd = karnopp_link(fs, fc)
    ok = np.ones_like(qd, bool)
    assert sliding_level(residual, qd, ok) == pytest.approx(fc, rel=0.1)
    test = breakaway_test(residual, qd, ok, RATE_HZ)
    # it reads low, by up to ~20 %: the joint moves off between two samples and the
    # differentiated velocity already takes in part of the slip's acceleration
    assert 0.75 * fs / fc <= test.ratio <= 1.02 * fs / fc
    assert test.stiction and test.phases >= 10


def test_coulomb_friction_breaks_away_at_its_sliding_level():
    residual, qd = karnopp_link(0.1, 0.1)
    test = breakaway_test(residual, qd, np.ones_like(qd, bool), RATE_HZ)
    assert test.ratio == pytest.approx(1.0, abs=0.2)
    assert not test.stiction
    assert test.ratio < STICTION_HOLDING_RATIO


def test_sensor_noise_alone_reads_no_breakaway():
    """Noise three times the friction level (a weak friction on a noisy joint) raises the held
    torque's high quantile; less the noise's own quantile, no stiction appears."""
    residual, qd = karnopp_link(0.05, 0.05, noise_nm=0.15)
    test = breakaway_test(residual, qd, np.ones_like(qd, bool), RATE_HZ)
    assert not test.stiction
    assert abs(test.ratio - 1.0) < 3 * test.ratio_stderr + 0.2


def test_stick_phases_need_their_length_and_usable_samples():
    qd = np.array([1.0] * 5 + [0.0] * 2 + [1.0] * 5 + [0.0] * 6 + [1.0] * 5)
    ok = np.ones(qd.size, bool)
    assert stick_phases(qd, ok, RATE_HZ) == [(12, 18)]   # the 2-sample dwell is a reversal
    ok[14] = False
    assert stick_phases(qd, ok, RATE_HZ) == [(15, 18)]


def test_no_sliding_samples_give_no_ratio():
    qd = np.zeros(500)
    test = breakaway_test(np.zeros(500), qd, np.ones(500, bool), RATE_HZ)
    assert np.isnan(test.ratio) and not test.stiction


# a whole doctor's run (35 s on a slow 2-core machine), slow for CI's 15 minutes;
# the breakaway test's parts are above
@pytest.mark.slow
def test_the_doctor_names_karnopp_sticking_stiction_and_hands_back_the_model_it_proved(tmp_path):
    """A shoulder with Karnopp stick-slip friction (F_s 0.12-0.25 N m, F_c 0.3-0.5 F_s) in a
    recording of the random-form generator: the search fits a Coulomb level, the stick phases
    name it stiction with its breakaway excess, and the fitted model (Coulomb plus breakaway)
    replays the held-out recording to the report's after-NRMSE."""
    from identification.doctor.valve_arm.diagnose import diagnose
    from identification.doctor.valve_arm.fitted_model import heldout_replay
    from identification.doctor.valve_arm.report import write
    from pneumatics.recording import read_csv
    from pneumatics.robot import load_robot
    from scenarios._variantsim.cases import make_case

    truth = make_case(tmp_path, 883927825, ["stiction"], forms=["karnopp_stick_slip"], name="karnopp")
    assert truth["effects"][0]["where"] == {"joint": "shoulder"}
    held = [read_csv(tmp_path / "karnopp_heldout.csv")]
    report = diagnose(load_robot("arm2"), [read_csv(tmp_path / "karnopp.csv")], held)
    (f,) = report["findings"]
    assert (f["effect"], f["where"], f["alternatives"][0]) == ("stiction", {"joint": "shoulder"}, "coulomb_friction")
    assert f["parameters"]["breakaway_extra_nm"]["value"] > 0.5 * f["parameters"]["coulomb_nm"]["value"]
    assert "the stuck joint holds" in f["evidence"]
    assert f["heldout_nrmse"]["after"] < f["heldout_nrmse"]["before"]
    write(report, tmp_path / "out", load_robot("arm2"), rerun=False)
    fitted = load_robot("arm2", fitted=tmp_path / "out" / "model.toml")
    after = heldout_replay(fitted, held).nrmse()
    for ch, v in report["after"]["heldout_nrmse"].items():
        assert after[ch] == pytest.approx(v, rel=1e-9), ch


def smooth_friction_link(friction, seconds: float = 30.0, seed: int = 0, noise_nm: float = 0.003):
    """(residual, qd) at 100 Hz of the link of :func:`karnopp_link` with a friction torque that
    is a function of the velocity alone, ``friction(v)`` [N m] (a regularised law)."""
    dt = 1e-4
    t = np.arange(0.0, seconds, dt)
    ref = 0.5 * np.sin(2 * np.pi * 0.25 * t) + 0.1 * np.sin(2 * np.pi * 0.9 * t)
    q, v, tau = np.zeros_like(t), np.zeros_like(t), np.zeros_like(t)
    for k in range(len(t) - 1):
        tau[k] = 4.0 * (ref[k] - q[k]) - 0.05 * v[k]
        v[k + 1] = v[k] + dt * (tau[k] - friction(v[k])) / INERTIA
        q[k + 1] = q[k] + dt * v[k + 1]
    step = int(round(1.0 / (RATE_HZ * dt)))
    vs, taus = v[::step], tau[::step]
    noise = np.random.default_rng(seed).normal(0.0, noise_nm, vs.size)
    return taus - INERTIA * np.gradient(vs, 1.0 / RATE_HZ) + noise, vs


def test_a_regularised_coulomb_law_holds_no_more_than_its_sliding_level():
    """Coulomb friction Fc tanh(v / 0.02 rad/s) creeps instead of sticking: it holds at most F_c."""
    residual, qd = smooth_friction_link(lambda v: 0.1 * np.tanh(v / 0.02))
    test = breakaway_test(residual, qd, np.ones_like(qd, bool), RATE_HZ)
    assert test.ratio <= 1.05 and not test.stiction


def test_a_stribeck_curve_holds_its_peak():
    """A Stribeck curve (Armstrong-Helouvry et al. 1994) whose peak is 2.5 F_c at a few mrad/s
    holds a torque near that peak while the joint creeps through the reversals: stiction."""
    fc, fs = 0.1, 0.25
    residual, qd = smooth_friction_link(
        lambda v: (fc + (fs - fc) * np.exp(-(v / 0.02) ** 2)) * np.tanh(v / 0.002))
    test = breakaway_test(residual, qd, np.ones_like(qd, bool), RATE_HZ)
    assert 0.7 * fs / fc <= test.ratio <= 1.05 * fs / fc
    assert test.stiction


def test_white_noise_std_reads_the_noise_beside_slow_torques():
    t = np.arange(6000) / RATE_HZ
    slow = 0.3 * np.sin(2 * np.pi * 0.5 * t) + 0.1 * np.sign(np.sin(2 * np.pi * 0.25 * t))
    noise = np.random.default_rng(1).normal(0.0, 0.01, t.size)
    assert white_noise_std(slow + noise, np.ones(t.size, bool)) == pytest.approx(0.01, rel=0.1)
