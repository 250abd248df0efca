"""Put irregularly timed samples onto a recording's time base.

Three rules, chosen by what the channel is (docs/recordings.md):

* **zero-order hold** for commands (valve voltages, currents, references): a valve sees the
  last command sent until the next one arrives, so the value at ``t`` is the last message at
  or before ``t`` — exact, with no look-ahead and no invented in-between values; it matches
  the recording's convention that row k's command is held from ``time[k]`` to ``time[k+1]``
  (DESIGN.md, the DAQ of paper 002);
* **linear** interpolation for sensors sampled at about the recording's rate or faster: the
  measured quantities (angles, pressures) are continuous, and the linear interpolant's error
  is bounded by ``h^2 max|x''| / 8`` for a message spacing ``h`` (the Lagrange remainder for
  n = 1, ``|x''(xi) (t - t0)(t - t1)| / 2`` with ``|(t - t0)(t - t1)| <= h^2 / 4``: Burden & Faires,
  *Numerical Analysis*, Thm. 3.3), with no delay;
* **period mean**: the mean over the period ``(t - T, t]`` of that linear interpolant — the
  DAQ averaging of paper 002 (row k's sensors are the mean over the control period ending at
  ``time[k]``), for sensors published much faster than the recording's rate; it is an
  anti-aliasing box filter and makes the resampled values mean what pneumasim's own
  recordings mean (``daq_averaging``).

Times are int64 nanoseconds (as ROS stamps them), so a grid at 100 Hz lands exactly on
messages stamped at multiples of 10 ms; differences are taken in float seconds.
"""
from __future__ import annotations

import numpy as np


def time_grid(start_ns: int, stop_ns: int, rate_hz: float) -> np.ndarray:
    """(N,) int64 times ``start_ns + round(k 1e9 / rate_hz)`` up to and including ``stop_ns``."""
    period = 1e9 / rate_hz
    n = int(np.floor((stop_ns - start_ns) / period + 1e-9)) + 1
    return start_ns + np.round(np.arange(max(n, 0)) * period).astype(np.int64)


def zero_order_hold(stamps_ns: np.ndarray, values: np.ndarray, grid_ns: np.ndarray) -> np.ndarray:
    """values (M, K) stamped ``stamps_ns`` (M,), increasing, held: the last one at or before
    each grid time (every grid time must be at or after the first stamp)."""
    idx = np.searchsorted(stamps_ns, grid_ns, side="right") - 1
    if np.any(idx < 0):
        raise ValueError("a grid time precedes the first sample: nothing to hold")
    return values[idx]


def linear(stamps_ns: np.ndarray, values: np.ndarray, grid_ns: np.ndarray) -> np.ndarray:
    """values (M, K) linearly interpolated at the grid times (inside the stamps' span)."""
    s, g = _seconds(stamps_ns, grid_ns)
    return np.column_stack([np.interp(g, s, values[:, k]) for k in range(values.shape[1])])


def period_mean(stamps_ns: np.ndarray, values: np.ndarray, grid_ns: np.ndarray, period_s: float) -> np.ndarray:
    """Mean over ``(t - period_s, t]`` of the linear interpolant of values (M, K), at each grid
    time t (the window must lie inside the stamps' span)."""
    s, g = _seconds(stamps_ns, grid_ns)
    out = np.empty((g.size, values.shape[1]))
    for k in range(values.shape[1]):
        v = values[:, k]
        area = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(s))])  # trapezoid rule
        out[:, k] = (_integral(g, s, v, area) - _integral(g - period_s, s, v, area)) / period_s
    return out


def _integral(x: np.ndarray, s: np.ndarray, v: np.ndarray, area: np.ndarray) -> np.ndarray:
    """Integral from s[0] to x of the piecewise-linear interpolant through (s, v)."""
    i = np.clip(np.searchsorted(s, x, side="right") - 1, 0, s.size - 2)
    h = x - s[i]
    slope = (v[i + 1] - v[i]) / (s[i + 1] - s[i])
    return area[i] + v[i] * h + 0.5 * slope * h * h


def _seconds(stamps_ns: np.ndarray, grid_ns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both in float seconds from the first stamp (exact differences of int64 first)."""
    t0 = stamps_ns[0]
    return (stamps_ns - t0) * 1e-9, (grid_ns - t0) * 1e-9


def largest_gap(stamps_ns: np.ndarray) -> tuple[float, float, float]:
    """(largest message spacing [s], the time before it [ns], median spacing [s])."""
    gaps = np.diff(stamps_ns)
    i = int(np.argmax(gaps))
    return gaps[i] * 1e-9, float(stamps_ns[i]), float(np.median(gaps)) * 1e-9
