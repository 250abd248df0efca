"""PID and PIDF valve controllers of paper 002 §V (eqs. 13-15).

Per joint i, with the tracking error q*_i - q_i::

    e_i = k_P (q* - q) + k_D d/dt (q* - q) + k_I int (q* - q) dt           (eq. 13)
    PID:   u_i^+ = 5 + e_i,                 u_i^- = 5 - e_i                  (eq. 14)
    PIDF:  u_i^+ = 5 + e_i - k_F d_i,       u_i^- = 5 - e_i + k_F d_i        (eq. 15)

where d_i = p_i^+ - p_i^- is the measured pressure difference (in bar, so k_F is in V/bar)
and 5 V stands for each valve's own null.  The robot measures angles only: the derivative
term differentiates the measured error through a first-order low-pass filter.  The integral
is clamped (anti-windup).  Commands leave the controller clipped to 0-10 V.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pneumatics.config import spec
from pneumatics.sim import Observation


@dataclass(frozen=True, kw_only=True)
class PIDFCfg:
    """Gains of a PID(F) controller, one value per joint (or one for all)."""

    kp_v_per_rad: tuple = spec(doc="proportional gain k_P", unit="V/rad")
    kd_v_s_per_rad: tuple = spec(doc="derivative gain k_D", unit="V s/rad")
    ki_v_per_rad_s: tuple = spec(doc="integral gain k_I", unit="V/(rad s)")
    kf_v_per_bar: tuple = spec((0.0,), "pressure-difference feedback k_F (0: plain PID, eq. 14)", "V/bar")
    integral_limit_v: float = spec(3.0, "clamp of the integral term's contribution", "V")
    deriv_filter_s: float = spec(0.02, "time constant of the derivative's low-pass filter", "s")
    rate_hz: float = spec(100.0, "control rate", "Hz")

    def build(self, reference, null_v) -> "PIDF":
        """A controller tracking ``reference`` (an object with ``reference(t) -> (n_joint,)``),
        around the valves' nulls ``null_v`` (n_ch,)."""
        return PIDF(self, reference, np.asarray(null_v, float))


#: arm2 gains of reference/arm2.md (shoulder, elbow): tracks a varied 60 s reference at ~2-3 deg
ARM2_PIDF = PIDFCfg(kp_v_per_rad=(40.0, 50.0), kd_v_s_per_rad=(1.5, 2.5), ki_v_per_rad_s=(10.0, 10.0),
                    kf_v_per_bar=(4.0, 3.0))


@dataclass
class PIDF:
    """The control law; ``reset()`` and ``__call__(time, observation) -> (n_ch,) volts``."""

    cfg: PIDFCfg
    ref: object
    null_v: np.ndarray
    _integral: np.ndarray = field(default=None, init=False)
    _deriv: np.ndarray = field(default=None, init=False)
    _last_err: np.ndarray = field(default=None, init=False)

    def reset(self):
        self._integral = None
        self._deriv = None
        self._last_err = None

    def reference(self, t: float) -> np.ndarray:
        return self.ref.reference(t)

    def __call__(self, t: float, obs: Observation) -> np.ndarray:
        c = self.cfg
        dt = 1.0 / c.rate_hz
        err = self.reference(t) - obs.q
        if self._last_err is None:
            self._integral = np.zeros_like(err)
            self._deriv = np.zeros_like(err)
            self._last_err = err.copy()
        raw = (err - self._last_err) / dt
        alpha = dt / (c.deriv_filter_s + dt)
        self._deriv += alpha * (raw - self._deriv)
        self._last_err = err.copy()
        ki = np.broadcast_to(np.asarray(c.ki_v_per_rad_s, float), err.shape)
        self._integral += err * dt
        lim = c.integral_limit_v / np.maximum(ki, 1e-12)
        np.clip(self._integral, -lim, lim, out=self._integral)
        e = (np.asarray(c.kp_v_per_rad) * err + np.asarray(c.kd_v_s_per_rad) * self._deriv
             + ki * self._integral)
        d_bar = (obs.p_a - obs.p_b) / 1e5
        e = e - np.asarray(c.kf_v_per_bar) * d_bar
        u = np.empty(2 * e.size)
        u[0::2] = self.null_v[0::2] + e
        u[1::2] = self.null_v[1::2] - e
        return np.clip(u, 0.0, 10.0)
