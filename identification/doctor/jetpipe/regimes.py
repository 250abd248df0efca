"""Where a jet-pipe residual (or a finding's improvement) lives: physically meaningful regimes
of the held-out data, and Ljung's residual tests.

Regime features (each an (N,) array per held-out trace, computed from the data and the
calibrated model's replay; issue 4 step 4):

* command level and the jet's distance from the ports' centre (model, eq. 4: x_jet + offset):
  valve near null vs wide open;
* time since a command reversal (a local extremum of the 5 ms-smoothed command) and since a
  command step (a peak of its 10 ms change), in ms;
* chamber pressures p_a, p_b and their difference (the rod force / piston area);
* flow into chamber a / b: the sign and size of the model's dP/dt (eq. 12: dP/dt ~ net mass
  flow at a fixed volume), i.e. filling vs venting;
* jet velocity (model): which way the jet is moving.

A per-sample weight (the squared-residual reduction a finding buys, or the residual energy
above the noise floor) is binned by each feature into quantile bins; the (feature, bin) whose
share of the weight most exceeds its share of the samples (the lift, as in
identification.base.statistics.locate_regime for arm2) is where it concentrates, when that lift is at least
``MIN_LIFT``; otherwise it is spread "throughout".
"""
from __future__ import annotations

import numpy as np
from scipy.signal import find_peaks

N_BINS = 5          # quantile bins per feature (each 20 % of the held-out samples)
MIN_LIFT = 2.0      # a bin must hold twice its share of the samples (40 % of the weight in 20 %)

#: feature -> (unit label, scale from SI to that unit)
FEATURES = {
    "current command": ("mA", 1e3),
    "jet distance from centre (model)": ("um", 1e6),
    "time since a command reversal": ("ms", 1e3),
    "time since a command step": ("ms", 1e3),
    "pressure p_a": ("kPa", 1e-3),
    "pressure p_b": ("kPa", 1e-3),
    "pressure difference p_a - p_b": ("kPa", 1e-3),
    "flow into chamber a (model dp_a/dt)": ("MPa/s", 1e-6),
    "flow into chamber b (model dp_b/dt)": ("MPa/s", 1e-6),
    "jet velocity (model)": ("mm/s", 1e3),
}


def _smooth(x: np.ndarray, n: int) -> np.ndarray:
    if n <= 1 or x.size < n:
        return x
    return np.convolve(np.pad(x, (n // 2, n - 1 - n // 2), mode="edge"), np.ones(n) / n, mode="valid")


def _time_since(t: np.ndarray, events: np.ndarray) -> np.ndarray:
    """(N,) seconds since the latest event at or before each sample (since the trace start if none)."""
    last = np.full(t.size, t[0])
    if events.size:
        k = np.searchsorted(t[events], t, side="right") - 1
        last = np.where(k >= 0, t[events[np.maximum(k, 0)]], t[0])
    return t - last


def features(t: np.ndarray, command_a: np.ndarray, p_a: np.ndarray, p_b: np.ndarray, pred: dict,
             jet_offset_m: float = 0.0) -> dict:
    """feature name -> (N,) SI values for one trace. ``pred``: the calibrated model's replay
    (``jetpipe_replay.replay``: p_a, p_b [Pa], jet [m]); ``jet_offset_m``: the jet origin's
    misalignment (paper 000 eq. 4: the ports see x_jet + offset)."""
    dt = float(np.median(np.diff(t)))
    c = _smooth(command_a, max(1, round(0.005 / dt)))
    span = max(float(np.ptp(c)), 1e-12)
    rev = np.sort(np.concatenate([find_peaks(c, prominence=0.05 * span)[0], find_peaks(-c, prominence=0.05 * span)[0]]))
    lag = max(1, round(0.01 / dt))
    dc = np.abs(c - np.concatenate([np.full(lag, c[0]), c[:-lag]]))
    steps = find_peaks(dc, height=max(5.0 * float(np.median(dc)), 0.1 * span), distance=max(1, int(0.1 / dt)))[0]
    return {
        "current command": command_a,
        "jet distance from centre (model)": np.abs(pred["jet"] + jet_offset_m),
        "time since a command reversal": _time_since(t, rev),
        "time since a command step": _time_since(t, steps),
        "pressure p_a": p_a,
        "pressure p_b": p_b,
        "pressure difference p_a - p_b": p_a - p_b,
        "flow into chamber a (model dp_a/dt)": np.gradient(_smooth(pred["p_a"], 3), t),
        "flow into chamber b (model dp_b/dt)": np.gradient(_smooth(pred["p_b"], 3), t),
        "jet velocity (model)": np.gradient(pred["jet"], t),
    }


def _bins(x: np.ndarray, n: int = N_BINS) -> np.ndarray:
    """(n+1,) quantile edges (duplicates removed)."""
    return np.unique(np.quantile(x, np.linspace(0.0, 1.0, n + 1)))


def _describe(name: str, lo: float, hi: float, first: bool, last: bool) -> str:
    unit, k = FEATURES[name]
    if name.startswith("time since"):
        return f"within {hi * k:.0f} {unit} of a {name.split(' a ')[-1]}" if first else \
            f"{name} {lo * k:.0f}-{hi * k:.0f} {unit}"
    if first:
        return f"{name} below {hi * k:.3g} {unit}"
    if last:
        return f"{name} above {lo * k:.3g} {unit}"
    return f"{name} {lo * k:.3g} to {hi * k:.3g} {unit}"


def concentrate(weight: np.ndarray, feats: dict, min_lift: float = MIN_LIFT) -> dict:
    """Where the per-sample ``weight`` (N,) concentrates among the regime ``feats`` (name -> (N,)).

    Returns {"regime": words, "feature", "bin": [lo, hi] SI, "lift", "share", "cover",
    "by_feature": {name: best lift}}; feature None when no bin reaches ``min_lift``."""
    total = float(np.sum(weight))
    out = {"regime": "throughout (no regime feature concentrates it)", "feature": None, "bin": None,
           "lift": 1.0, "share": 1.0, "cover": 1.0, "by_feature": {}}
    if not np.isfinite(total) or total <= 0:
        return out
    best = (min_lift, None)
    for name, x in feats.items():
        edges = _bins(x)
        if edges.size < 3:
            continue
        k = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
        top = 0.0
        for b in range(edges.size - 1):
            m = k == b
            cover = float(m.mean())
            if not 0.05 <= cover <= 0.95:
                continue
            share = float(np.sum(weight[m])) / total
            lift = share / cover
            top = max(top, lift)
            if lift >= best[0]:
                best = (lift, (name, b, edges, share, cover))
        out["by_feature"][name] = round(top, 3)
    if best[1] is not None:
        name, b, edges, share, cover = best[1]
        out.update(regime=_describe(name, edges[b], edges[b + 1], b == 0, b == edges.size - 2), feature=name,
                   bin=[float(edges[b]), float(edges[b + 1])], lift=float(best[0]), share=share, cover=cover)
    return out


