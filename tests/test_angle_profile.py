"""The angle-profile yardstick (hypotheses.angle_profile_yardstick): a histogram regression of a
joint's torque residual on its angle, the flexible correction that follows a detent or cogging
torque (periodic in the angle) where the smooth yardstick's q and q^2 cannot."""
from types import SimpleNamespace

import numpy as np

from identification.doctor.valve_arm.hypotheses import (
    ANGLE_PROFILE_BIN_RAD, ANGLE_PROFILE_MIN_SAMPLES, angle_profile_yardstick)


#: torque data that leave no equation out (TorqueData.mask on a recording without limit episodes)
ALL = SimpleNamespace(mask=lambda reg: reg)


def _exp(q0, q1):
    q = np.column_stack([q0, q1])
    return SimpleNamespace(q_s=q, qd=np.zeros_like(q))


def _motion(seconds, seed):
    t = np.arange(0.0, seconds, 0.01)
    rng = np.random.default_rng(seed)
    return 0.6 * np.sin(2 * np.pi * 0.13 * t + rng.uniform(0, 6)) + 0.1 * np.sin(2 * np.pi * 0.7 * t)


def test_every_sample_falls_in_one_bin_of_its_own_joint(arm2):
    q = _motion(60.0, 1)
    h = angle_profile_yardstick(arm2, 1, _exp(np.zeros_like(q), q))
    reg = h.regressor(_exp(np.zeros_like(q), q), ALL)
    assert np.all(reg[:, 0] == 0) and np.all(reg[:, 1].sum(axis=1) == 1)
    counts = reg[:, 1].sum(axis=0)
    assert counts.min() >= ANGLE_PROFILE_MIN_SAMPLES            # sparse bins were merged
    assert len(h.params) <= int(np.ptp(q) / ANGLE_PROFILE_BIN_RAD) + 1
    # angles past the training range take the end bins
    out = h.regressor(_exp(np.zeros(2), np.array([-5.0, 5.0])), ALL)[:, 1]
    assert out[0, 0] == 1 and out[1, -1] == 1


def _heldout_gain(arm2, torque, seed_noise=0):
    """Held-out share of the mean square removed by the bin means fitted on the training data."""
    rng = np.random.default_rng(seed_noise)
    q, q_h = _motion(60.0, 2), _motion(30.0, 3)
    y, y_h = torque(q) + rng.normal(0, 0.01, q.size), torque(q_h) + rng.normal(0, 0.01, q_h.size)
    h = angle_profile_yardstick(arm2, 0, _exp(q, np.zeros_like(q)))
    A, A_h = h.regressor(_exp(q, np.zeros_like(q)), ALL)[:, 0], h.regressor(_exp(q_h, np.zeros_like(q_h)), ALL)[:, 0]
    means = np.linalg.lstsq(A, y, rcond=None)[0]
    return 1.0 - np.mean((y_h - A_h @ means) ** 2) / np.mean(y_h ** 2)


def test_it_takes_up_a_cogging_torque_and_no_noise(arm2):
    cogging = lambda q: 0.05 * np.sin(2 * np.pi * q / np.radians(8.0) + 1.0)  # 8 deg pitch
    assert _heldout_gain(arm2, cogging) > 0.85
    assert _heldout_gain(arm2, lambda q: 0.0 * q) < 0.0
