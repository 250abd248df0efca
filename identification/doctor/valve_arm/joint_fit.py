"""The torque balance refitted at one joint: what lets the mechanical screening scale to a
humanoid's 38 joints.

:func:`mechanics.fit_rigid_body` refits, with an effect's regressors, the joints' damping and
the kept effects' terms over every joint's equations (the inertias held at the calibration).
Those free columns act each on one joint's equations (a joint's damping on its own dof, a
friction or a bumper on its own joint), so the least squares splits into one independent
problem per joint, bounds and all: an effect confined to joint j changes only joint j's part of
the fit.  :func:`fit_at_joint` solves that part alone and takes every other joint's from the base
fit, the same solution as the whole fit (tests/test_doctor_scaling.py) at 1/J of its cost.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear

from identification.base.lsq import Fit, covariance

from .mechanics import TorqueData, fit_rigid_body


def confined_joint(reg: np.ndarray, valid: np.ndarray) -> int | None:
    """The one joint whose equations the regressors ``reg`` (N, J, E) act on at the ``valid``
    samples, or None (none, or several: an angle offset's gravity torque reaches the joints
    below it)."""
    touched = np.flatnonzero(np.any(reg[valid] != 0, axis=(0, 2)))
    return int(touched[0]) if touched.size == 1 else None


def fit_effect(td: TorqueData, extra: np.ndarray, names: list, bounds, base: Fit, base_cols: int) -> Fit:
    """``fit_rigid_body(td, extra, names, bounds)`` where the effect's own columns (the last
    ones after ``base_cols`` extra columns of kept terms) act at one joint and no kept term
    spans that joint and another: solved at that joint alone (:func:`fit_at_joint`); otherwise the
    whole fit.  ``base`` is the fit without the effect (``fit_rigid_body(td, *base_extra)``)."""
    v = td.valid
    effect = extra[:, :, base_cols:]
    j = confined_joint(effect, v)
    if j is None and not np.any(effect[v]):
        # the effect never acts on these samples (a stop the data do not reach): its columns
        # are zero and it changes no joint's fit
        j = 0
    if j is None:
        return fit_rigid_body(td, extra, names, bounds)
    kept = extra[v][:, :, :base_cols]
    shared = np.any(kept != 0, axis=0)                      # (J, base_cols): which joints each kept term reaches
    if np.any(shared[j] & (shared.sum(axis=0) > 1)):
        return fit_rigid_body(td, extra, names, bounds)
    return fit_at_joint(td, extra, names, bounds, base, j)


def fit_at_joint(td: TorqueData, extra: np.ndarray, extra_names: list, bounds, base: Fit, j: int) -> Fit:
    """The whole torque-balance fit with ``extra`` (N, J, E) (named ``extra_names``, bounded by
    ``bounds``) when only joint j's block of free columns changes from ``base`` (a fit over the
    same rows with the first columns of ``extra``)."""
    cal = td.calibration
    names = list(td.names) + list(extra_names)
    v = td.valid
    P, E = len(td.names), extra.shape[2]
    J = td.residual.shape[1]
    lo, hi = np.concatenate([td.lower, bounds[0]]), np.concatenate([td.upper, bounds[1]])
    # the same row scaling as fit_rigid_body (mechanics._scaled): each joint's residual s.d.
    y_all = td.residual[v]
    scale = max(float(np.std(y_all[:, j])), 1e-9)
    A = np.concatenate([td.regressors[v][:, j, :], extra[v][:, j, :]], axis=1) / scale     # (M, P + E)
    y = y_all[:, j] / scale
    held = np.concatenate([cal.values, np.zeros(E)])
    free = np.array([k >= P or (n.startswith("damping_scale.") and n not in td.fixed) for k, n in enumerate(names)])
    # the free columns acting at joint j, and the effect's own even where they are zero: least
    # squares leaves a column without data at a start of its own choosing, as the whole fit does
    block = free & (np.any(A != 0, axis=0) | (np.arange(len(names)) >= len(base.values)))
    y_f = y - A[:, ~free] @ held[~free]
    x = np.empty(len(names))
    x[: len(base.values)] = base.values                      # every other joint's part, as fitted
    x[len(base.values):] = 0.0
    x[block] = lsq_linear(A[:, block], y_f, bounds=(lo[block], hi[block])).x if block.any() else x[block]
    res_j = y_f - A[:, block] @ x[block]
    residual = base.residual.reshape(-1, J).copy()
    old_j = residual[:, j].copy()
    residual[:, j] = res_j
    rss = base.rss - float(old_j @ old_j) + float(res_j @ res_j)
    se = np.full(len(names), np.nan)
    se[: len(base.stderr)] = base.stderr
    n_free = int(free.sum())
    if block.any():  # Gauss-Markov with the whole fit's s^2 = rss / (n - p); J^T J is block diagonal
        local, cond = covariance(A[:, block], rss * (y.size - block.sum()) / max(y_all.size - n_free, 1), y.size)
        se[block] = local
    else:
        cond = base.condition
    at = [n for n, val, a, b, f in zip(names, x, lo, hi, free)
          if f and ((np.isfinite(a) and val - a < 1e-6) or (np.isfinite(b) and b - val < 1e-6))]
    return Fit(list(names), x, se, rss, y_all.size, cond, at, residual.ravel())
