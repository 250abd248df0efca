"""Where and when a residual lives: time windows and physically meaningful regimes.

Each regime is a boolean mask over samples built from the recording (velocity sign and size,
velocity reversals, commands near null or reversing, pressure level, chamber volume, flow
direction, time since a command step).  A residual "lives" in the regime whose share of the
residual energy most exceeds its share of time (lift), among regimes covering at least 5 %
of the samples.
"""
from __future__ import annotations

import numpy as np

from .data import Experiment


def joint_regimes(exp: Experiment, j: int) -> dict:
    qd = exp.qd[:, j]
    speed = np.abs(qd)
    slow = speed < np.percentile(speed, 20)
    sign = np.sign(qd)
    flip = np.zeros_like(slow)
    idx = np.nonzero(np.diff(sign) != 0)[0]
    for i in idx:
        flip[max(0, i - 5): i + 6] = True
    rng = exp.robot.joint_range()[j]
    span = rng[1] - rng[0]
    q = exp.q_s[:, j]
    return {
        "velocity reversals": flip,
        "low velocity (stick-slip range)": slow,
        "high velocity": speed > np.percentile(speed, 80),
        "positive velocity": qd > 0,
        "negative velocity": qd < 0,
        "near the joint limits": (q < rng[0] + 0.1 * span) | (q > rng[1] - 0.1 * span),
        # where a position-dependent torque (a spring, a hose, a gravity error) shows most
        "upper third of the angles visited": q > np.percentile(q, 67),
        "lower third of the angles visited": q < np.percentile(q, 33),
    }


def chamber_regimes(exp: Experiment, c: int) -> dict:
    tab = exp.robot.tables
    u = exp.u[:, c]
    null = tab.valve[c, 0]
    du = np.diff(u, prepend=u[0])
    rev = np.zeros(u.size, bool)
    s = np.sign(du)
    nz = np.nonzero(s)[0]
    for a, b in zip(nz[:-1], nz[1:]):
        if s[a] != s[b]:
            rev[b: b + 5] = True
    step = np.zeros(u.size, bool)
    for i in np.nonzero(np.abs(du) > 1.0)[0]:
        step[i: i + 5] = True
    p = exp.p[:, c]
    act = tab.actuator_of_chamber[c]
    x = exp.fine_length[:: exp.n_sub][: u.size, act] - tab.length_zero[act]
    travel = x if tab.is_a[c] else tab.stroke[act] - x
    return {
        "command near null (within 0.5 V)": np.abs(u - null) < 0.5,
        "command reversals": rev,
        "within 50 ms of a command step": step,
        "valve open to supply (filling)": u > null + 0.5,
        "valve open to room (venting)": u < null - 0.5,
        "high pressure (above 5 bar)": p > 5e5,
        "low pressure (below 3 bar)": p < 3e5,
        "small chamber volume": travel < 0.25 * tab.stroke[act],
    }
