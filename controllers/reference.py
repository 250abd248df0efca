"""Joint-space reference trajectories made the way a person moving the robot by hand would
(paper 002 §V, Fig. 5A): reaches that stop abruptly, holds, circles and figure eights, slow
and fast parts; scaled to each joint's range minus a safety margin.

Velocities and accelerations come from a smoothing spline (SciPy ``make_smoothing_spline``)
of the sampled positions, as one would differentiate a recorded trajectory.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_smoothing_spline

from pneumatics.recording import Recording


def _min_jerk(s):
    return 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5


@dataclass
class JointReference:
    """A sampled reference: ``time`` (N,) s, ``q`` (N, n_joint) rad, with its spline."""

    time: np.ndarray
    q: np.ndarray
    joint_names: list

    def __post_init__(self):
        lam = 1e-7 * (self.time[-1] - self.time[0])
        self._splines = [make_smoothing_spline(self.time, self.q[:, j], lam=lam) for j in range(self.q.shape[1])]

    def reference(self, t: float) -> np.ndarray:
        """(n_joint,) position at t (held at the ends)."""
        t = min(max(t, self.time[0]), self.time[-1])
        return np.array([np.interp(t, self.time, self.q[:, j]) for j in range(self.q.shape[1])])

    def derivatives(self, t: np.ndarray):
        """(q, qd, qdd) each (len(t), n_joint) from the smoothing splines."""
        return tuple(np.column_stack([s.derivative(k)(t) if k else s(t) for s in self._splines]) for k in range(3))

    def to_recording(self) -> Recording:
        return Recording(self.time.copy(), {f"ref.{j}": self.q[:, i] for i, j in enumerate(self.joint_names)},
                         {"kind": "reference"})


def hand_moved(joint_names, joint_range, duration_s: float, seed: int, *, speed: float = 1.0,
               margin_rad: float = np.radians(5.0), rate_hz: float = 100.0, start_hold_s: float = 1.0,
               extreme_probability: float = 0.2) -> JointReference:
    """A procedural "moved by hand" reference from ``seed``; ``speed`` 2 = the fast version."""
    rng = np.random.default_rng(seed)
    lo = np.asarray(joint_range)[:, 0] + margin_rad
    hi = np.asarray(joint_range)[:, 1] - margin_rad
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    n = len(joint_names)
    dt = 1.0 / rate_hz
    t_total = duration_s * speed  # built on the slow clock, then time-compressed by `speed`
    pieces = [np.zeros((int(start_hold_s * speed * rate_hz), n))]  # normalised [-1, 1] positions
    cur = np.zeros(n)
    length = len(pieces[0])
    while length * dt < t_total:
        kind = rng.choice(["reach", "hold", "circle", "eight"], p=[0.45, 0.2, 0.2, 0.15])
        if kind == "reach":
            extreme = rng.random() < extreme_probability
            target = rng.uniform(-1, 1, n) if not extreme else np.sign(rng.uniform(-1, 1, n)) * rng.uniform(0.85, 1.0, n)
            steps = max(2, int(rng.uniform(0.4, 0.9) * rate_hz))
            s = _min_jerk(np.linspace(0, 1, steps))[:, None]
            seg = cur + (target - cur) * s
        elif kind == "hold":
            seg = np.repeat(cur[None], int(rng.uniform(0.4, 1.5) * rate_hz), axis=0)
        else:
            f = rng.uniform(0.15, 0.9)
            cycles = rng.integers(1, 4)
            steps = int(cycles / f * rate_hz)
            tt = np.arange(steps) * dt
            amp = rng.uniform(0.25, 0.6, n)
            ratio = np.where(np.arange(n) % 2 == 0, 1.0, 2.0 if kind == "eight" else 1.0)
            phase = rng.uniform(0, 2 * np.pi, n)
            wave = amp * (np.sin(2 * np.pi * f * ratio * tt[:, None] + phase) - np.sin(phase))
            centre = np.clip(cur, -1 + amp, 1 - amp)
            ramp = _min_jerk(np.clip(tt / 0.3, 0, 1))[:, None]
            seg = cur + (centre - cur) * ramp + wave * ramp
            seg = np.clip(seg, -1, 1)
        pieces.append(seg)
        cur = seg[-1]
        length += len(seg)
    norm = np.concatenate(pieces)[: int(round(t_total * rate_hz)) + 1]
    t_slow = np.arange(len(norm)) * dt
    time = t_slow / speed
    # resample onto the control grid of the compressed clock
    grid = np.arange(int(round(duration_s * rate_hz)) + 1) * dt
    norm = np.column_stack([np.interp(grid, time, norm[:, j]) for j in range(n)])
    return JointReference(grid, mid + half * norm, list(joint_names))
