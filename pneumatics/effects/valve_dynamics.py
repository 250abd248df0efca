"""Valve dynamics acting on the command before the valve map.

* Hysteresis: the play (backlash) operator of width 2h — the spool follows the command only
  once it has reversed by more than 2h (Krasnosel'skii & Pokrovskii 1989; the simplest
  rate-independent hysteresis with minor loops).
* Lag: a first-order low-pass u_eff' = (u - u_eff)/tau (valve bandwidth, paper 002: 100 Hz).
* Dead time: u_eff(t) = u(t - d) (line transport delay, controller latency).
"""
from __future__ import annotations

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
