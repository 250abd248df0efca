"""The rigid body's calibration and the effects' fits on its torque balance
(torque_balance.TorqueData): linear least squares, bounded, on the parallel-filtered,
decimated samples.

**Base and essential parameters.**  A column that moves exactly with an earlier one (arm2's
shoulder armature and upper-link inertia: both pure shoulder inertia) cannot be told apart
from it and is not fitted (Gautier & Khalil 1990, "Direct calculation of minimum set of
inertial parameters of serial robots", IEEE TRA 6(3)); one the data pin down no better than
ESSENTIAL_SE (a 0.25 % armature on a 3 % inertia error) stays nominal (Pham & Gautier 1991,
"Essential parameters of robots", IEEE CDC), instead of running to its bound.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from identification.base.lsq import Fit, bounded_linear, covariance

from .torque_balance import TorqueData

#: a calibration parameter (relative scale) whose standard error exceeds this stays nominal
ESSENTIAL_SE = 0.2
#: relative norm left after projecting a column on the earlier ones below which it is dependent
DEPENDENT = 1e-4


def calibrate_rigid_body(td: TorqueData, extra: np.ndarray | None = None, extra_names=(), extra_bounds=None) -> Fit:
    """The rigid body's calibration: bounded linear least squares of tau_res = sum theta_k reg_k
    on the parallel-filtered, decimated samples (torque_balance's module docstring).  The parameters the data
    cannot identify are chosen here (``td.fixed``, among the rigid body's own columns, on every
    call) and held at 0 with a NaN standard error.

    With the regressors ``extra`` (N, J, E) of effects already kept, they are fitted jointly:
    an effect the first calibration partly absorbed (an encoder offset taken up as 8 % less
    upper-link mass) hands the inertias back.  Returns the rigid body's part as a Fit (scales
    are relative changes: 0 = nominal), also kept as ``td.calibration``."""
    if td.held_nominal:
        return _nominal_calibration(td)
    A, y = td.decimate(td.regressors), td.decimate(td.residual)
    P = len(td.names)
    names, lo, hi, n_e = list(td.names), td.lower, td.upper, 0
    if extra is not None:
        n_e = extra.shape[2]
        elo, ehi = extra_bounds if extra_bounds is not None else (np.full(n_e, -np.inf), np.full(n_e, np.inf))
        A = np.concatenate([A, td.decimate(extra)], axis=2)
        names, lo, hi = names + list(extra_names), np.concatenate([lo, elo]), np.concatenate([hi, ehi])
    # each joint's rows weighted by 1 / its residual's s.d.: first before the fit, then (one
    # pass of feasible weighted least squares) after it.  The first weights alone let an effect
    # much larger than the noise (an encoder offset's gravity torque) down-weight its joint's
    # rows even once the effect is modelled, and a mass it identifies then looks unidentifiable
    scale = None
    for _ in range(2):
        A2, y2, scale = _scaled(A, y, scale)
        td.fixed = _unidentified(A2, y2, names, lo, hi, n_e)
        free = np.array([n not in td.fixed for n in names])
        fit = _bounded_fit(A2, y2, names, lo, hi, free, np.zeros(len(names)))
        scale = scale * np.std(fit.residual.reshape(-1, len(scale)), axis=0)
    td.calibration = replace(fit, names=names[:P], values=fit.values[:P], stderr=fit.stderr[:P],
                             at_bound=[n for n in fit.at_bound if n in td.names])
    return td.calibration


def hold_nominal(td: TorqueData, why: str) -> Fit:
    """Hold ``td``'s rigid body at its nominal masses, damping and armature from now on
    (``calibrate_rigid_body`` then returns zeros, every parameter ``fixed`` with ``why``)."""
    td.held_nominal = why
    return _nominal_calibration(td)


def _nominal_calibration(td: TorqueData) -> Fit:
    P = len(td.names)
    td.fixed = {n: td.held_nominal for n in td.names}
    td.calibration = Fit(list(td.names), np.zeros(P), np.full(P, np.nan), 0.0, 0, 1.0, [], np.zeros(0))
    return td.calibration


def fit_rigid_body(td: TorqueData, extra: np.ndarray | None = None, extra_names=(), extra_bounds=None) -> Fit:
    """The torque balance with effect regressors ``extra`` (N, J, E) on the raw samples.

    An effect's torque can be sharp (a bumper's impact lasts a few samples), which the
    calibration's low-pass would smear into something a wrong stiffness and damping fit as
    well, so effects are fitted on the unfiltered samples.  There the noise in the angles'
    second derivative biases the inertias, so the inertial terms (mass and armature scales)
    are held at the calibration's values (``calibrate_rigid_body``, run first if it has not
    been); the joints' damping, which an effect such as friction may have taken up, is
    refitted with the effect.  Without ``extra`` this is the calibrated model's raw fit, the
    baseline effects are scored against.  Values in the order of ``td.names`` then
    ``extra_names``; held parameters have a NaN standard error."""
    cal, names, lo, hi, held, free = _effect_fit_terms(td, extra, extra_names, extra_bounds)
    v, refit = td.valid, free[: len(td.names)]
    # the held columns (the inertias: most of a humanoid's hundreds) enter as the torque they
    # predict, without a copy of the (N, J, P) regressors: scaled, sliced and copied, those
    # copies were the doctor's peak memory on humanoid38 (4263 MiB on a null case, 3358 without)
    y = td.residual[v] - (td.regressors @ np.where(refit, 0.0, cal.values))[v]
    A = td.regressors[:, :, refit][v]
    if extra is not None:
        A = np.concatenate([A, extra[v]], axis=2)
    scale = joint_scale(td.residual[v])
    A2, y_f = (A / scale[None, :, None]).reshape(y.size, A.shape[2]), (y / scale).ravel()
    return _solve_free(A2, y_f, names, lo, hi, free, held)


def fit_rigid_body_reference(td: TorqueData, extra: np.ndarray | None = None, extra_names=(),
                             extra_bounds=None) -> Fit:
    """:func:`fit_rigid_body` as written first, with every column in one scaled matrix (its
    memory several copies of the regressors): the reference it is tested against."""
    _, names, lo, hi, held, free = _effect_fit_terms(td, extra, extra_names, extra_bounds)
    v = td.valid
    A = td.regressors[v] if extra is None else np.concatenate([td.regressors[v], extra[v]], axis=2)
    A2, y2, _ = _scaled(A, td.residual[v])
    return _bounded_fit(A2, y2, names, lo, hi, free, held)


def _effect_fit_terms(td: TorqueData, extra, extra_names, extra_bounds):
    """(calibration, names, lower and upper bounds, held values, free mask) of an effect fit
    over the calibration's columns then ``extra``'s (E columns, unbounded unless
    ``extra_bounds``): the damping and the effect free, the inertias held at the calibration."""
    cal = td.calibration if td.calibration is not None else calibrate_rigid_body(td)
    names = list(td.names) + list(extra_names)
    lo, hi = td.lower, td.upper
    n_e = 0 if extra is None else extra.shape[2]
    if n_e:
        elo, ehi = extra_bounds if extra_bounds is not None else (np.full(n_e, -np.inf), np.full(n_e, np.inf))
        lo, hi = np.concatenate([lo, elo]), np.concatenate([hi, ehi])
    held = np.concatenate([cal.values, np.zeros(n_e)])
    free = np.concatenate([td.refitted_beside_effects(), np.ones(n_e, bool)])
    return cal, names, lo, hi, held, free


def joint_scale(y: np.ndarray) -> np.ndarray:
    """(J,) each joint's torque residual's s.d. (N, J) [N m]: its rows' divisor in the fits."""
    return np.maximum(np.array([np.std(y[:, j]) for j in range(y.shape[1])]), 1e-9)


def _scaled(A, y, scale=None):
    """(A2 (M J, P), y2 (M J,), scale (J,)): each joint's rows divided by ``scale``, by default
    its residual's s.d."""
    scale = joint_scale(y) if scale is None else np.maximum(scale, 1e-9)
    return (A / scale[None, :, None]).reshape(-1, A.shape[2]), (y / scale).ravel(), scale


def _bounded_fit(A2, y2, names, lo, hi, free, held) -> Fit:
    """Bounded least squares (bounded_linear) on the ``free`` columns, the others at their
    ``held`` values (NaN stderr)."""
    y_f = y2 - A2[:, ~free] @ np.asarray(held, float)[~free]
    return _solve_free(A2[:, free], y_f, names, lo, hi, free, held)


def _solve_free(A_free, y_f, names, lo, hi, free, held) -> Fit:
    """Bounded least squares (bounded_linear) of ``y_f`` (the rows less the held columns' part)
    on ``A_free`` (the ``free`` columns only); the others at their ``held`` values (NaN stderr)."""
    x = np.array(held, float)
    se = np.full(len(names), np.nan)
    if not free.any():  # everything held (every damping unidentifiable, no effect terms)
        return Fit(names, x, se, float(y_f @ y_f), y_f.size, 1.0, [], y_f)
    x[free] = bounded_linear(A_free, y_f, lo[free], hi[free])
    res = y_f - A_free @ x[free]
    rss = float(res @ res)
    se[free], cond = covariance(A_free, rss, y_f.size)
    at = [n for n, v, a, b, f in zip(names, x, lo, hi, free)
          if f and ((np.isfinite(a) and v - a < 1e-6) or (np.isfinite(b) and b - v < 1e-6))]
    return Fit(names, x, se, rss, y_f.size, cond, at, res)


def _unidentified(A2, y2, names, lo, hi, n_effects: int = 0) -> dict:
    """:func:`unidentified_columns` of the scaled rows ``A2`` (M J, P), ``y2`` (M J,), solved
    on A2's triangular factor: with A2 = Q R, every column's distance from the span of others,
    every bounded fit and its Gauss-Markov errors are R's, once the part of y2 outside A2's
    columns (|y2|^2 - |Q^T y2|^2) is added to each residual sum of squares and the rows are
    counted as A2's (identification.base.lsq.bounded_linear).  One QR instead of a least-squares
    solve over every row per column and per dropped parameter: on humanoid38 (over a hundred
    columns) these solves were most of each calibration of the rigid body."""
    Q, R = np.linalg.qr(A2)
    z = Q.T @ y2
    return unidentified_columns(R, z, names, lo, hi, n_effects, max(float(y2 @ y2 - z @ z), 0.0), y2.size)


def unidentified_columns(A, y, names, lo, hi, n_effects: int = 0, outside_rss: float = 0.0,
                         n_rows: int | None = None) -> dict:
    """Calibration parameters kept nominal -> the reason: first those whose column is a
    combination of earlier ones (the order of ``names``: bodies before joint terms), then,
    one at a time, the one with the largest standard error while that exceeds ESSENTIAL_SE.
    The last ``n_effects`` columns (kept effects) are always fitted, never chosen here.
    ``outside_rss`` is added to every fit's residual sum of squares and ``n_rows`` (default
    y's length) counts its rows: :func:`_unidentified` passes A's triangular factor; with the
    defaults this is the same on the rows themselves, the reference it is tested against."""
    fixed = {}
    kept = list(range(len(names) - n_effects, len(names)))
    for k, n in enumerate(names[:len(names) - n_effects]):
        col = A[:, k]
        norm = np.linalg.norm(col)
        if kept:
            Q = A[:, kept]
            coef, *_ = np.linalg.lstsq(Q, col, rcond=None)
            left = np.linalg.norm(col - Q @ coef)
        else:
            left = norm
        if norm == 0 or left < DEPENDENT * norm:
            twin = names[kept[int(np.argmax(np.abs(coef) * np.linalg.norm(Q, axis=0)))]] if kept else "nothing"
            fixed[n] = f"moves exactly with {twin} (not separable; fitted as part of it)"
            continue
        kept.append(k)
    while True:
        free = np.array([n not in fixed for n in names])
        if not free.any():
            return fixed
        x = bounded_linear(A[:, free], y, lo[free], hi[free])
        res = y - A[:, free] @ x
        se = np.full(len(names), -np.inf)
        se[free] = covariance(A[:, free], float(res @ res) + outside_rss, n_rows or y.size)[0]
        se[len(names) - n_effects:] = -np.inf
        worst = int(np.argmax(se))
        if se[worst] <= ESSENTIAL_SE:
            return fixed
        fixed[names[worst]] = f"not identifiable from these motions (standard error {se[worst]:.2g})"
