"""Least squares with parameter standard errors and identifiability diagnostics.

Both the linear and the nonlinear fits return a :class:`Fit`: values, standard errors from
the Gauss-Newton covariance s^2 (J^T J)^-1, the condition number of J^T J (scaled by the
parameter scales) and which parameters ended at a bound — the identifiability checks the
doctor reports.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, lsq_linear


@dataclass
class Fit:
    names: list
    values: np.ndarray
    stderr: np.ndarray
    rss: float
    n: int
    condition: float
    at_bound: list
    residual: np.ndarray

    def as_dict(self) -> dict:
        return {k: {"value": float(v), "stderr": float(s)} for k, v, s in zip(self.names, self.values, self.stderr)}


def covariance(jac, rss, n):
    """(standard errors, condition number) of a least-squares fit from its Jacobian (n rows),
    residual sum of squares ``rss`` and the usual s^2 = rss / (n - p) (Gauss-Markov)."""
    p = jac.shape[1]
    s2 = rss / max(n - p, 1)
    if hasattr(jac, "toarray"):  # sparse Jacobian from jac_sparsity: J^T J formed sparse, only the
        jtj = (jac.T @ jac).toarray()  # p x p made dense (a humanoid's chambers: J is ~0.6 GiB dense)
    else:
        jtj = jac.T @ jac
    scale = np.sqrt(np.maximum(np.diag(jtj), 1e-300))
    jtj_s = jtj / np.outer(scale, scale)
    cond = float(np.linalg.cond(jtj_s))
    try:
        cov = np.linalg.pinv(jtj) * s2
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        se = np.full(p, np.inf)
    return se, cond


def linear(A: np.ndarray, b: np.ndarray, names, weights: np.ndarray | None = None) -> Fit:
    """Ordinary (optionally weighted) least squares of A theta = b."""
    if weights is not None:
        A = A * weights[:, None]
        b = b * weights
    theta, *_ = np.linalg.lstsq(A, b, rcond=None)
    res = b - A @ theta
    rss = float(res @ res)
    se, cond = covariance(A, rss, b.size)
    return Fit(list(names), theta, se, rss, b.size, cond, [], res)


def nonlinear(fun, x0, names, lower=None, upper=None, **kw) -> Fit:
    """scipy.optimize.least_squares (trust-region reflective) with a Fit summary."""
    x0 = np.asarray(x0, float)
    lower = np.full(x0.size, -np.inf) if lower is None else np.asarray(lower, float)
    upper = np.full(x0.size, np.inf) if upper is None else np.asarray(upper, float)
    r = least_squares(fun, x0, bounds=(lower, upper), x_scale="jac", **kw)
    rss = float(r.fun @ r.fun)
    se, cond = covariance(r.jac, rss, r.fun.size)
    span = np.where(np.isfinite(upper - lower), upper - lower, 1.0)
    at = [n for n, v, lo, hi, s in zip(names, r.x, lower, upper, span)
          if (np.isfinite(lo) and v - lo < 1e-3 * s) or (np.isfinite(hi) and hi - v < 1e-3 * s)]
    return Fit(list(names), r.x, se, rss, r.fun.size, cond, at, r.fun)


def bounded_linear(A: np.ndarray, b: np.ndarray, lower, upper) -> np.ndarray:
    """The x within [lower, upper] minimising |A x - b| (scipy.optimize.lsq_linear), solved on
    the triangular factor of a tall A: with A = Q R (Q's k columns orthonormal),
    |A x - b|^2 = |R x - Q^T b|^2 + |b|^2 - |Q^T b|^2, so the same minimiser comes from a k x k
    problem (Golub & Van Loan, Matrix Computations, 4th ed., section 5.3: least squares by
    QR).  lsq_linear's iterations, each a factorisation of the whole m x k matrix where a bound
    binds, then cost nothing next to the one QR (humanoid38's torque-balance fits: thousands of
    rows a column)."""
    m, k = A.shape
    if m <= 2 * k:
        return lsq_linear(A, b, bounds=(lower, upper)).x
    Q, R = np.linalg.qr(A)
    return lsq_linear(R, Q.T @ b, bounds=(lower, upper)).x
