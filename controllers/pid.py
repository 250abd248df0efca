"""PID and PIDF valve controllers of paper 002 §V (eqs. 13-15).

Per joint i, with the tracking error q*_i - q_i::

    e_i = k_P (q* - q) + k_D d/dt (q* - q) + k_I int (q* - q) dt           (eq. 13)
    PID:   u_i^+ = 5 + e_i,                 u_i^- = 5 - e_i                  (eq. 14)
    PIDF:  u_i^+ = 5 + e_i - k_F d_i,       u_i^- = 5 - e_i + k_F d_i        (eq. 15)

where d_i = p_i^+ - p_i^- is the measured pressure difference (in bar, so k_F is in V/bar)
and 5 V stands for each valve's own null.  The robot measures angles only: the derivative
term differentiates the measured error through a first-order low-pass filter.  The integral
is clamped so that its contribution never exceeds ``integral_limit_v`` (anti-windup).
Commands leave the controller clipped to 0-10 V.

In PIDF the effort e_i is a desired pressure difference e_i / k_F [bar] and the k_F loop a
low-level pressure controller; :mod:`controllers.model_based` adds the inverse-dynamics
prediction to it (eqs. 16-17) and :mod:`controllers.ilqg` replaces the k_F loop by MPC.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pneumatics.config import spec
from pneumatics.errors import ConfigError
from pneumatics.sim import Observation

BAR = 1e5
COMMAND_MIN_V, COMMAND_MAX_V = 0.0, 10.0


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

    def __post_init__(self):
        for name in ("kp_v_per_rad", "kd_v_s_per_rad", "ki_v_per_rad_s", "kf_v_per_bar"):
            v = np.asarray(getattr(self, name), float)
            if not np.all(np.isfinite(v)):
                raise ConfigError(f"PIDFCfg.{name}: gains must be finite, got {getattr(self, name)}")
        if self.deriv_filter_s < 0 or self.rate_hz <= 0 or self.integral_limit_v < 0:
            raise ConfigError("PIDFCfg: deriv_filter_s and integral_limit_v must be >= 0 and rate_hz > 0")

    def build(self, reference, null_v) -> PIDF:
        """A controller tracking ``reference`` (an object with ``reference(t) -> (n_joint,)``),
        around the valves' nulls ``null_v`` (n_ch,)."""
        return PIDF(self, reference, np.asarray(null_v, float))

    def as_vector(self, n_joint: int) -> np.ndarray:
        """(4, n_joint) rows kp, kd, ki, kf."""
        return np.array([np.broadcast_to(np.asarray(getattr(self, k), float), (n_joint,))
                         for k in ("kp_v_per_rad", "kd_v_s_per_rad", "ki_v_per_rad_s", "kf_v_per_bar")])


#: arm2 gains of reference/arm2.md (shoulder, elbow): tracks a varied 60 s reference at ~2-3 deg
ARM2_PIDF = PIDFCfg(kp_v_per_rad=(40.0, 50.0), kd_v_s_per_rad=(1.5, 2.5), ki_v_per_rad_s=(10.0, 10.0),
                    kf_v_per_bar=(4.0, 3.0))

#: arm2 plain PID (eq. 14), found by controllers.tuning (Nelder-Mead, 3 restarts x 60
#: evaluations on a 10 s hand-moved reference, seed 3).  Every gain set tried limit-cycles and
#: hits the joint limits; these have the lowest error (the optimiser all but switched the
#: elbow's proportional term off in favour of the integral and derivative terms)
ARM2_PID = PIDFCfg(kp_v_per_rad=(6.7, 0.05), kd_v_s_per_rad=(1.9, 3.9), ki_v_per_rad_s=(28.0, 28.0),
                   kf_v_per_bar=(0.0, 0.0))


def valve_commands(null_v: np.ndarray, effort_v: np.ndarray) -> np.ndarray:
    """Antagonistic mapping of eqs. 14/15/17: u^+ = null + v, u^- = null - v, clipped to 0-10 V.

    Args: null_v (n_ch,) each valve's null; effort_v (n_joint,) with n_ch = 2 n_joint.
    Returns: (n_ch,) commands ordered a0, b0, a1, b1, ...
    """
    u = np.empty(2 * effort_v.size)
    u[0::2] = null_v[0::2] + effort_v
    u[1::2] = null_v[1::2] - effort_v
    return np.clip(u, COMMAND_MIN_V, COMMAND_MAX_V)


@dataclass
class PIDF:
    """The control law; ``reset()`` and ``__call__(time, observation) -> (n_ch,) volts``."""

    cfg: PIDFCfg
    ref: object
    null_v: np.ndarray
    _integral: np.ndarray = field(default=None, init=False)
    _deriv: np.ndarray = field(default=None, init=False)
    _last_err: np.ndarray = field(default=None, init=False)
    _gains: tuple = field(default=None, init=False)

    def reset(self):
        self._integral = None
        self._deriv = None
        self._last_err = None

    def reference(self, t: float) -> np.ndarray:
        return self.ref.reference(t)

    def effort(self, t: float, obs: Observation) -> np.ndarray:
        """(n_joint,) PID effort e_i of eq. 13 [V]; advances the filter and integral states."""
        c = self.cfg
        dt = 1.0 / c.rate_hz
        err = self.reference(t) - obs.q
        if self._last_err is None:
            self._integral = np.zeros_like(err)
            self._deriv = np.zeros_like(err)
            self._last_err = err.copy()
            # the gains as arrays, once per run (the control law runs every period)
            ki = np.broadcast_to(np.asarray(c.ki_v_per_rad_s, float), err.shape)
            self._gains = (np.asarray(c.kp_v_per_rad), np.asarray(c.kd_v_s_per_rad), ki,
                           c.integral_limit_v / np.maximum(ki, 1e-12))
        kp, kd, ki, lim = self._gains
        raw = (err - self._last_err) / dt
        alpha = dt / (c.deriv_filter_s + dt)
        self._deriv += alpha * (raw - self._deriv)
        self._last_err = err.copy()
        self._integral += err * dt
        np.clip(self._integral, -lim, lim, out=self._integral)
        return kp * err + kd * self._deriv + ki * self._integral

    def compiled_law(self, n_joint: int):
        """This law in compiled form for :func:`pneumatics.runner.run` (None where it cannot be:
        :func:`controllers.compiled_loop.compile_controller`)."""
        from .compiled_loop import compile_controller  # imports this module

        return compile_controller(self, n_joint)

    def kf(self, n_joint: int) -> np.ndarray:
        return np.broadcast_to(np.asarray(self.cfg.kf_v_per_bar, float), (n_joint,))

    def __call__(self, t: float, obs: Observation) -> np.ndarray:
        e = self.effort(t, obs)
        d_bar = (obs.p_a - obs.p_b) / BAR
        return valve_commands(self.null_v, e - self.kf(e.size) * d_bar)
