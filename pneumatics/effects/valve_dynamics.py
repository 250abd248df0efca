"""Valve dynamics acting on the command before the valve map.

* Hysteresis: the play (backlash) operator of width 2h — the spool follows the command only
  once it has reversed by more than 2h (Krasnosel'skii & Pokrovskii 1989; the simplest
  rate-independent hysteresis with minor loops).
* Lag: a first-order low-pass u_eff' = (u - u_eff)/tau (valve bandwidth, paper 002: 100 Hz).
* Dead time: u_eff(t) = u(t - d) (line transport delay, controller latency).
* Slew limit: |u_eff'| <= r (a solenoid's force bounds the spool's speed: a large step takes
  the spool a fixed time, a small one goes as fast as the lag allows; the valve's datasheet
  "response time 0-100 %").
"""
from __future__ import annotations

import numba
import numpy as np


def play(u: np.ndarray, half_width_v: float, u0: float | None = None) -> np.ndarray:
    """Play operator along axis 0 of u (F,) or (F, n); output starts at u0 (default u[0])."""
    u = np.asarray(u, float)
    y = np.empty_like(u)
    y[0] = u[0] if u0 is None else u0
    h = half_width_v
    for k in range(1, u.shape[0]):
        y[k] = np.minimum(np.maximum(y[k - 1], u[k] - h), u[k] + h)
    return y


def first_order_lag(u: np.ndarray, tau_s: float, dt: float) -> np.ndarray:
    """Exact discretisation of a first-order lag for piecewise-constant input (axis 0)."""
    u = np.asarray(u, float)
    if tau_s <= 0:
        return u.copy()
    a = np.exp(-dt / tau_s)
    from scipy.signal import lfilter

    y = lfilter([1 - a], [1, -a], u, axis=0, zi=a * u[:1])[0]
    return y


def dead_time(u: np.ndarray, delay_s: float, dt: float) -> np.ndarray:
    """u delayed by delay_s (linear interpolation between grid points), held at the start."""
    u = np.asarray(u, float)
    shift = delay_s / dt
    idx = np.arange(u.shape[0]) - shift
    idx = np.clip(idx, 0, u.shape[0] - 1)
    i0 = np.floor(idx).astype(int)
    i1 = np.minimum(i0 + 1, u.shape[0] - 1)
    w = (idx - i0)
    if u.ndim > 1:
        w = w[:, None]
    return (1 - w) * u[i0] + w * u[i1]


def slew_limited_reference(u: np.ndarray, max_step_v: float, y0: float | None = None) -> np.ndarray:
    """The spool after a slew limit, along axis 0 of u (F,): each step it moves toward the
    command by at most ``max_step_v`` [V] (rate x dt); starts at y0 (default u[0]).  The
    readable reference of :func:`slew_limited`."""
    u = np.asarray(u, float)
    y = np.empty_like(u)
    y[0] = u[0] if y0 is None else y0
    for k in range(1, u.shape[0]):
        y[k] = y[k - 1] + min(max_step_v, max(-max_step_v, u[k] - y[k - 1]))
    return y


@numba.njit(cache=True)
def _slew_compiled(u, max_step_v, y0):
    y = np.empty_like(u)
    y[0] = y0
    for k in range(1, u.shape[0]):
        y[k] = y[k - 1] + min(max_step_v, max(-max_step_v, u[k] - y[k - 1]))
    return y


def slew_limited(u: np.ndarray, max_step_v: float, y0: float | None = None) -> np.ndarray:
    """:func:`slew_limited_reference`, compiled (the replays filter ~10^5 samples per chamber)."""
    u = np.ascontiguousarray(u, float)
    return _slew_compiled(u, float(max_step_v), float(u[0] if y0 is None else y0))
