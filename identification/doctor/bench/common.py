"""What the bench doctors share: the hold-out split, the keep thresholds, noise and NRMSE.

The chamber doctor (:mod:`.chamber_fit`) and the cylinder doctor (:mod:`.cylinder_fit`) both
judge hypotheses on held-out data with these numbers.
"""
from __future__ import annotations

import math

import numpy as np

from identification.base import lsq

HOLDOUT = 0.3          # share of each recording held out (its end) when no held-out file is given
KEEP = 0.20            # held-out mean-square reduction an effect must bring to be named
ALIKE = 1.0            # (MSE_alt - MSE_best) / max(MSE_best, noise^2) below this: cannot tell apart
                       # (held-out residuals of slow drifts are correlated: a factor 2 in MSE is no proof)
PARSIMONY = 0.05       # chamber pairs: must cut the held-out MSE by this share of the nominal's more
MAX_DT_K = 117.0       # (k - 1) T_w: the most adiabatic charging from vacuum can heat the gas
MIN_DT_K = -10.0       # a gas colder than the wall when shut: not from charging (a margin for room drift)


def split_parts(recordings, holdouts, fraction):
    """(train, held-out) lists of recordings: the given held-out files, else the end of each."""
    if holdouts:
        return list(recordings), list(holdouts)
    train, held = [], []
    for r in recordings:
        t_cut = r.time[0] + (1.0 - fraction) * (r.time[-1] - r.time[0])
        train.append(r.slice(r.time[0], t_cut))
        held.append(r.slice(t_cut, r.time[-1] + 1.0))
    return train, held


def autocorrelation_inflation(fit: lsq.Fit) -> lsq.Fit:
    """Scale ``fit.stderr`` for residuals correlated in time: with lag-1 autocorrelation rho the
    effective sample size is n (1 - rho) / (1 + rho) (AR(1) residuals; e.g. Box, Jenkins &
    Reinsel, *Time Series Analysis*), so standard errors grow by sqrt((1 + rho) / (1 - rho))."""
    r = np.asarray(fit.residual, float)
    if r.size > 3 and np.std(r) > 0:
        rho = float(np.clip(np.corrcoef(r[:-1], r[1:])[0, 1], 0.0, 0.99))
        fit.stderr = fit.stderr * math.sqrt((1 + rho) / (1 - rho))
    return fit


def nrmse(pred, meas) -> float:
    return float(np.sqrt(np.mean((pred - meas) ** 2)) / max(np.std(meas), 1e-12))


def noise_sd(x) -> float:
    """Sensor noise [channel unit]: std of second differences / sqrt(6) (white noise; blind to
    linear trends, so a leak or a ramp does not count as noise)."""
    return float(np.std(np.diff(np.asarray(x, float), 2)) / math.sqrt(6.0))
