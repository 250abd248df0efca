"""Where a hydraulic finding's improvement (or an unexplained residual) lives, and whether
something pays that no family names.

Regimes are boolean masks of the held-out samples, physically named (paper 001's plant): the
valve near null or wide open, within 100 ms of a current reversal, the vane sliding fast or
slow or stuck, a large load pressure, the first 100 ms after a stick-slip transition.  A
per-sample weight is located with :func:`identification.base.statistics.locate_regime` (the
mask holding the most weight per unit of time, lift >= ``MIN_LIFT``).

The flexible check (:func:`flexible_regressors`): a linear model of each channel's training
residual on generic signals (current and its lags, |current|, pressures, angle, speed, the
sign of the speed, the torque) that no family's law shapes; when it cuts the held-out J by
the keep rule, something pays that the families do not name: ``unexplained``.
"""
from __future__ import annotations

import numpy as np

from identification.base.statistics import locate_regime

MIN_LIFT = 1.5
REVERSAL_S = 0.1


def _since(t, events):
    last = np.full(t.size, -np.inf)
    if events.size:
        k = np.searchsorted(t[events], t, side="right") - 1
        last = np.where(k >= 0, t[events[np.maximum(k, 0)]], -np.inf)
    return t - last


def masks(tr, i_sat: float = 1.0) -> dict:
    """regime name -> (N,) bool for trace ``tr`` (all samples; callers cut the scored ones)."""
    t, i, qd = tr.time, tr.current_a, tr.smooth["qd"]
    di = np.diff(i)
    rev = np.flatnonzero((np.sign(di[1:]) != np.sign(di[:-1])) & (np.abs(di[1:]) > 0) & (np.abs(di[:-1]) > 0)) + 1
    big = np.abs(np.diff(i, prepend=i[0])) > 0.02 * i_sat
    rev = rev[big[rev]] if rev.size else rev
    moving = np.abs(qd) > 0.05
    switch = np.flatnonzero(np.diff(moving.astype(int)) != 0) + 1
    p_l = tr.p_a - tr.p_b
    return {
        "valve near null (|i| < 5 % of saturation)": np.abs(i) < 0.05 * i_sat,
        "valve wide open (|i| > 50 % of saturation)": np.abs(i) > 0.5 * i_sat,
        "within 100 ms of a current reversal": _since(t, rev) < REVERSAL_S,
        "vane stuck": ~moving,
        "vane sliding fast (> 0.5 rad/s)": np.abs(qd) > 0.5,
        "within 100 ms of a stick-slip transition": _since(t, switch) < REVERSAL_S,
        "large load pressure (top fifth)": np.abs(p_l - np.median(p_l)) > np.quantile(np.abs(p_l - np.median(p_l)), 0.8),
        "load braced": np.full(t.size, bool(tr.braced)),
    }


def locate(weight: np.ndarray, regime_masks: dict) -> dict:
    """{"regime": words, "lift", "share"} of where the non-negative per-sample ``weight`` lives."""
    w = np.sqrt(np.maximum(weight, 0.0))  # locate_regime squares its input
    name, lift, share = locate_regime(w, regime_masks)
    if lift < MIN_LIFT:
        return {"regime": "throughout (no regime concentrates it)", "lift": float(lift), "share": 1.0}
    return {"regime": name, "lift": float(lift), "share": float(share)}


def flexible_regressors(tr) -> np.ndarray:
    """(N, K) generic signals for the flexible check, each scaled to unit s.d."""
    i = tr.current_a
    lag = lambda x, n: np.concatenate([np.full(n, x[0]), x[:-n]])  # noqa: E731
    dt = float(np.median(np.diff(tr.time)))
    cols = [np.ones_like(i), i, np.abs(i), lag(i, max(1, round(0.01 / dt))), lag(i, max(1, round(0.03 / dt))),
            lag(i, max(1, round(0.1 / dt))), tr.p_a, tr.p_b, tr.smooth["q"], np.cos(tr.smooth["q"]), tr.smooth["qd"],
            np.sign(tr.smooth["qd"]) * (np.abs(tr.smooth["qd"]) > 0.05), tr.smooth["qdd"]]
    if tr.torque is not None:
        cols += [tr.smooth["tau"], tr.smooth["taud"]]
    a = np.column_stack(cols)
    s = a.std(axis=0)
    s[0] = 1.0
    return a / np.where(s > 0, s, 1.0)
