"""Statistics every doctor shares: where a residual concentrates (regimes, time windows),
whether it is white (Ljung-Box) and independent of the inputs (Ljung's cross-correlation
test), and how sure a held-out improvement is (block bootstrap).

References: Ljung & Box, *On a measure of lack of fit in time series models*, Biometrika 65
(1978); Ljung, *System Identification: Theory for the User*, 2nd ed. (1999), sec. 16.6
(residual analysis); Kuensch, *The jackknife and the bootstrap for general stationary
observations*, Ann. Statist. 17 (1989) (block bootstrap).
"""
from __future__ import annotations

import numpy as np
from scipy.stats import chi2

LB_LAGS = 20        # Ljung-Box lags (samples)
XCORR_S = 0.05      # input cross-correlation: lags 0 .. 50 ms


#: a spread across places is estimated only from at least this many of them
SPREAD_MIN_PLACES = 12
#: robust z-score (median, 1.4826 x median absolute deviation) above which a place stands out
SPREAD_Z = 3.0


def robust_ceiling(values, log: bool = False) -> float:
    """The value above which one of ``values`` (one per place of a robot) stands out of the
    others: median + SPREAD_Z x 1.4826 MAD (the MAD of a normal sample estimates its standard
    deviation so; Hampel 1974), in log space for positive scale-like values (``log``).  With
    fewer than SPREAD_MIN_PLACES values there is no spread to estimate: -inf (no ceiling)."""
    v = np.asarray(values, float)
    if v.size < SPREAD_MIN_PLACES:
        return -np.inf
    x = np.log(np.maximum(v, 1e-300)) if log else v
    med = np.median(x)
    top = med + SPREAD_Z * 1.4826 * np.median(np.abs(x - med))
    return float(np.exp(top)) if log else float(top)


def locate_regime(residual: np.ndarray, regimes: dict, min_cover: float = 0.05):
    """(name, lift, share) of the regime holding the most residual energy per unit time."""
    return locate_energy(residual ** 2, regimes, min_cover)


def locate_energy(e: np.ndarray, regimes: dict, min_cover: float = 0.05):
    """(name, lift, share) of the regime holding the most of the per-sample energy ``e`` per
    unit time (an energy a finding removes may be negative where it does worse)."""
    total = e.sum()
    best = ("throughout", 1.0, 1.0)
    if total <= 0:
        return best
    for name, m in regimes.items():
        cover = m.mean()
        if cover < min_cover or cover > 0.95:
            continue
        share = e[m].sum() / total
        lift = share / cover
        if lift > best[1]:
            best = (name, float(lift), float(share))
    return best


def windows(t: np.ndarray, residual: np.ndarray, block_s: float = 1.0, factor: float = 2.0, most: int = 5):
    """Time windows [[t0, t1], ...] where the residual's block RMS exceeds factor x median."""
    n = max(1, int(round(block_s / np.median(np.diff(t)))))
    nb = residual.size // n
    if nb == 0:
        return []
    rms = np.sqrt(np.mean(residual[: nb * n].reshape(nb, n) ** 2, axis=1))
    hot = rms > factor * np.median(rms)
    spans = []
    i = 0
    while i < nb:
        if hot[i]:
            j = i
            while j + 1 < nb and hot[j + 1]:
                j += 1
            spans.append((float(rms[i: j + 1].max()), [float(t[i * n]), float(t[min((j + 1) * n, t.size - 1)])]))
            i = j + 1
        else:
            i += 1
    spans.sort(key=lambda s: -s[0])
    return sorted([s[1] for s in spans[:most]])


def ljung_box(residual: np.ndarray, lags: int = 20) -> float:
    """Ljung-Box Q statistic of a residual (large = not white)."""
    r = residual - residual.mean()
    n = r.size
    denom = float(r @ r)
    if denom <= 0:
        return 0.0
    q = 0.0
    for k in range(1, lags + 1):
        rho = float(r[k:] @ r[:-k]) / denom
        q += rho ** 2 / (n - k)
    return float(n * (n + 2) * q)


def ljung_box_p(q: float, lags: int = LB_LAGS) -> float:
    """Chi-square(lags) tail probability of a Ljung-Box Q (small = the residual is not white)."""
    return float(chi2.sf(q, lags))


def input_xcorr(residuals: list, inputs: list, dt_s: float, max_lag_s: float = XCORR_S) -> dict:
    """Ljung's input cross-correlation test: rho(tau) = sum r(t) u(t - tau) / sqrt(sum r^2 sum u^2)
    over the traces (means removed per trace), tau = 0 .. ``max_lag_s``.

    ``residuals``, ``inputs``: lists of (N_k,) arrays. Returns {"max_abs": max |rho|, "lag_ms",
    "bound": 1.96 / sqrt(N) (white residual independent of the input, 95 %), "s": N sum rho^2,
    "p": chi-square(L+1) tail probability of s}."""
    lags = max(1, round(max_lag_s / dt_s))
    num = np.zeros(lags + 1)
    rr = uu = 0.0
    n = 0
    for r, u in zip(residuals, inputs):
        r = r - r.mean()
        u = u - u.mean()
        rr += float(r @ r)
        uu += float(u @ u)
        n += r.size
        for tau in range(min(lags + 1, r.size)):
            num[tau] += float(r[tau:] @ u[: r.size - tau])
    if rr <= 0 or uu <= 0 or n == 0:
        return {"max_abs": 0.0, "lag_ms": 0.0, "bound": float("nan"), "s": 0.0, "p": 1.0}
    rho = num / np.sqrt(rr * uu)
    k = int(np.argmax(np.abs(rho)))
    s = float(n * np.sum(rho ** 2))
    return {"max_abs": float(abs(rho[k])), "lag_ms": float(1e3 * k * dt_s), "bound": float(1.96 / np.sqrt(n)),
            "s": s, "p": float(chi2.sf(s, lags + 1))}


def bootstrap_inclusion(e_before, e_after, keep: float, n: int = 500, seed: int = 0) -> float:
    """Share of block-bootstrap resamples of the held-out windows (blocks) in which the effect
    still removes at least the keep threshold of the residual energy."""
    if e_before.size == 0:
        return float("nan")
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, e_before.size, (n, e_before.size))
    gain = 1.0 - e_after[idx].sum(1) / np.maximum(e_before[idx].sum(1), 1e-300)
    return float(np.mean(gain >= keep))
