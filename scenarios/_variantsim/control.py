"""The variant simulator's own PIDF controller (paper 002 eqs. 13-15, gains from arm2.md), a
seeded reference (minimum-jerk moves with holds plus slow sines), closed-loop recording with
DAQ averaging and noise, and the restarted open-loop replays the concealment test uses."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .arm import (
    ANGLE_NOISE_RAD,
    PRESSURE_NOISE_PA,
    ROW_S,
    Arm2Config,
    Hidden,
    VariantArm,
)

#: rows between restart snapshots (1 s)
SEGMENT_ROWS = 100


@dataclass
class PIDF:
    """u_a = 5 + e - d, u_b = 5 - e + d (eqs. 14-15): e = kp (q* - q) + kd (qd* - qd) + ki int(q* - q),
    d = kf (p_a - p_b) [bar]; chamber a turns the joint positive, so a positive error fills a
    and vents b.  qd is the measured angle's difference, first-order filtered (20 ms)."""

    kp: tuple = (40.0, 50.0)          # V/rad
    kd: tuple = (1.5, 2.5)            # V s/rad
    ki: tuple = (10.0, 10.0)          # V/(rad s)
    kf: tuple = (4.0, 3.0)            # V/bar
    integral_limit_v: float = 3.0
    deriv_filter_s: float = 0.02

    def reset(self, q0):
        self.integ = np.zeros(2)
        self.q_prev = np.array(q0, float)
        self.qd_f = np.zeros(2)

    def __call__(self, ref, ref_d, q, p) -> np.ndarray:
        e = ref - q
        ki = np.array(self.ki)
        self.integ = np.clip(self.integ + e * ROW_S, -self.integral_limit_v / ki, self.integral_limit_v / ki)
        self.qd_f += ROW_S / (self.deriv_filter_s + ROW_S) * ((q - self.q_prev) / ROW_S - self.qd_f)
        self.q_prev = q.copy()
        err = np.array(self.kp) * e + np.array(self.kd) * (ref_d - self.qd_f) + ki * self.integ
        d = np.array(self.kf) * (p[0::2] - p[1::2]) / 1e5
        ua = np.clip(5.0 + err - d, 0.0, 10.0)
        ub = np.clip(5.0 - err + d, 0.0, 10.0)
        return np.array([ua[0], ub[0], ua[1], ub[1]])


def reference(seconds: float, seed: int, limit_deg: float = 40.0) -> np.ndarray:
    """(N, 2) joint references [rad] at 100 Hz: a 1 s hold, then minimum-jerk moves (0.4-0.9 s)
    to random targets within +-limit_deg, each followed by a 0.4-1.5 s hold, plus a slow sine
    (0.15-0.9 Hz, 3-6 deg) on each joint; clipped to +-limit_deg."""
    rng = np.random.default_rng(seed)
    n = round(seconds / ROW_S)
    t = np.arange(n) * ROW_S
    out = np.zeros((n, 2))
    for j in range(2):
        x = np.zeros(n)
        pos, tc = rng.uniform(-15, 15), 1.0
        x[:] = pos
        while tc < seconds:
            tgt = rng.uniform(-limit_deg, limit_deg) if rng.random() > 0.2 else rng.choice([-1, 1]) * limit_deg * 0.95
            T = rng.uniform(0.4, 0.9)
            s = np.clip((t - tc) / T, 0, 1)
            x = np.where(t >= tc, pos + (tgt - pos) * (10 * s**3 - 15 * s**4 + 6 * s**5), x)
            pos, tc = tgt, tc + T + rng.uniform(0.4, 1.5)
        x += rng.uniform(3, 6) * np.sin(2 * math.pi * rng.uniform(0.15, 0.9) * t + rng.uniform(0, 2 * math.pi)) * (t > 1.0)
        out[:, j] = np.radians(np.clip(x, -limit_deg, limit_deg))
    return out


def record(cfg: Arm2Config, hidden: Hidden | None, seconds: float, ref_seed: int, noise_seed: int,
           preroll_s: float = 1.5) -> dict:
    """Closed-loop PIDF run: row k holds the sensors averaged over the 10 ms ending at t_k
    (+ noise) and the command held over [t_k, t_k+1).  Returns arrays: ``ref`` (N,2), ``u``
    (N,4), ``q``/``p`` noisy measurements, ``q_clean``/``p_clean`` (sensor model, no noise),
    ``snaps`` {row: state} every second."""
    ref = reference(seconds, ref_seed)
    ref_d = np.gradient(ref, ROW_S, axis=0)
    n = len(ref)
    rng = np.random.default_rng(noise_seed)
    arm = VariantArm(cfg, hidden)
    arm.reset(ref[0])
    arm.start_clock(seconds, preroll_s)
    ctrl = PIDF()
    ctrl.reset(ref[0])
    qc, pc = arm.measure(ref[0].copy(), np.full(4, 4.5e5))
    out = {k: np.zeros((n, m)) for k, m in (("u", 4), ("q", 2), ("p", 4), ("q_clean", 2), ("p_clean", 4))}
    snaps = {}
    noise = lambda: (rng.normal(0, ANGLE_NOISE_RAD, 2), rng.normal(0, PRESSURE_NOISE_PA, 4))
    dq, dp = noise()
    for k in range(-round(preroll_s / ROW_S), n):
        if k >= 0 and k % SEGMENT_ROWS == 0:
            snaps[k] = arm.snapshot()
        qm, pm = qc + dq, pc + dp
        u = ctrl(ref[max(k, 0)], ref_d[k] if k >= 0 else np.zeros(2), qm, pm)
        if k >= 0:
            out["u"][k], out["q"][k], out["p"][k], out["q_clean"][k], out["p_clean"][k] = u, qm, pm, qc, pc
        q, p = arm.advance_row(u)
        qc, pc = arm.measure(q, p)
        dq, dp = noise()
    out.update(ref=ref, snaps=snaps, time=np.arange(n) * ROW_S)
    return out


def table(rec: dict) -> np.ndarray:
    """The recording as DESIGN.md's columns (arm.COLUMNS)."""
    return np.column_stack([rec["time"], rec["q"], rec["p"], rec["u"], rec["ref"]])


def replay(cfg: Arm2Config, rec: dict, hidden: Hidden | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Open-loop replays of the recorded commands, restarted from the recorded true state every
    second (effect states dropped); returns the noise-free predicted sensors (N,2), (N,4), with
    NaN on the restart rows (which are not predicted)."""
    n = len(rec["u"])
    q_out, p_out = np.full((n, 2), np.nan), np.full((n, 4), np.nan)
    arm = VariantArm(cfg, hidden)
    arm.start_clock(n * ROW_S, 0.0)          # the supply step's time; the snapshots carry the clock
    for k0, snap in sorted(rec["snaps"].items()):
        arm.restore(snap, physics_only=True)
        for k in range(k0, min(k0 + SEGMENT_ROWS, n - 1)):
            q, p = arm.advance_row(rec["u"][k])
            q_out[k + 1], p_out[k + 1] = arm.measure(q, p)
    return q_out, p_out
