"""The torque balance refitted at one joint: what lets the mechanical screening scale to a
humanoid's 38 joints.

:func:`mechanics.fit_rigid_body` refits, with an effect's regressors, the joints' damping and
the kept effects' terms over every joint's equations (the inertias held at the calibration).
Those free columns act each on one joint's equations (a joint's damping on its own dof, a
friction or a bumper on its own joint), so the least squares splits into one independent
problem per joint, bounds and all: an effect confined to joint j changes only joint j's part of
the fit.  :func:`fit_at_joints` solves that part alone (an angle offset's: the joints its gravity torque
reaches) and takes every other joint's from the base fit, the same solution as the whole fit
(tests/test_doctor_scaling.py) at a fraction of its cost.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

from identification.base.lsq import Fit, bounded_linear, covariance

from .mechanics import fit_rigid_body
from .torque_balance import TorqueData


#: a column's entries at a joint below this fraction of its largest count as zero (coupled_joints)
COUPLING_FLOOR = 1e-8


def column_reach(extra: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(J, E): which joints each column of ``extra`` (N, J, E) acts on at the ``valid`` samples.
    An angle offset's regressor, a difference of inverse dynamics, leaves ~1e-10 of its size at
    joints it cannot reach (rounding): those are not reached, and leaving them out moves a fit
    by as little."""
    size = np.max(np.abs(extra[valid]), axis=0)
    return size > COUPLING_FLOOR * np.max(size, axis=0, keepdims=True)


def coupled_joints(extra: np.ndarray, valid: np.ndarray, base_cols: int) -> np.ndarray:
    """The joints whose part of the fit an effect changes: those its own columns (``extra``'s
    after the first ``base_cols``, the kept terms) act on at the ``valid`` samples, joined by
    every joint a kept term couples to one of them; joint 0 where the effect never acts (its
    columns are zero and it changes no joint's fit)."""
    reach = column_reach(extra, valid)
    joints = reach[:, base_cols:].any(axis=1)
    if not joints.any():
        joints[0] = True
    kept = reach[:, :base_cols]
    while True:
        grown = joints | kept[:, kept[joints].any(axis=0)].any(axis=1)
        if np.array_equal(grown, joints):
            return np.flatnonzero(joints)
        joints = grown


def reaches_fold(own: np.ndarray, fold_valid: np.ndarray, valid: np.ndarray, size: float | None = None) -> bool:
    """Whether an effect's own regressor columns ``own`` (N, J, E) carry data in a fold's
    samples: more than 1e-6 of their largest value over all valid samples (``size``, if the
    caller has it).  A fold the effect
    reaches only through a filter's far tails (an end stop pressed in the other fold's blocks,
    or only where its joint is left out) cannot fit it: least squares would leave it at a
    start of its own choosing (scipy's trf then warns of invalid values)."""
    size = np.max(np.abs(own[valid]), initial=0.0) if size is None else size
    return bool(np.max(np.abs(own[fold_valid]), initial=0.0) > 1e-6 * size)


def fit_effect(td: TorqueData, extra: np.ndarray, names: list, bounds, base: Fit, base_cols: int,
               stderr: bool = True, shared: dict | None = None) -> Fit:
    """``fit_rigid_body(td, extra, names, bounds)``, solved at the joints the effect's own
    columns (the last ones after ``base_cols`` extra columns of kept terms) change
    (:func:`coupled_joints`, :func:`fit_at_joints`) when those are not all of them.  ``base``
    is the fit without the effect (``fit_rigid_body(td, *base_extra)``).  ``stderr=False``:
    a fit whose values alone are wanted (a cross-validation's); its changed columns' standard
    errors are left NaN, not computed.  ``shared``: a dict the caller keeps for effects fitted
    against the same base, kept terms and torque data (:class:`JointBlock`)."""
    joints = coupled_joints(extra, td.valid, base_cols)
    if joints.size == td.residual.shape[1]:
        return fit_rigid_body(td, extra, names, bounds)
    return fit_at_joints(td, extra, names, bounds, base, joints, stderr, shared)


def fit_at_joints(td: TorqueData, extra: np.ndarray, extra_names: list, bounds, base: Fit,
                  joints: np.ndarray, stderr: bool = True, shared: dict | None = None) -> Fit:
    """The whole torque-balance fit with ``extra`` (N, J, E) (named ``extra_names``, bounded by
    ``bounds``) when only the blocks of free columns of ``joints`` change from ``base`` (a fit
    over the same rows with the first columns of ``extra``; no free column couples one of
    ``joints`` to another joint); ``stderr=False``: see :func:`fit_effect`.  The rows and the
    factors every effect at these joints shares come from ``shared`` where an earlier effect
    left them (:class:`JointBlock`; one joint set kept at a time)."""
    names = list(td.names) + list(extra_names)
    P, nb = len(td.names), len(base.values)
    J, S = td.residual.shape[1], len(joints)
    key = (tuple(int(j) for j in joints), id(base), id(td))
    blk = shared.get(key) if shared is not None else None
    if blk is None:
        blk = joint_block(td, extra, base, joints)
        if shared is not None:
            shared.clear()
            shared[key] = blk
    lo, hi = np.concatenate([td.lower, bounds[0]]), np.concatenate([td.upper, bounds[1]])
    rows = np.flatnonzero(td.valid)
    own = extra[np.ix_(rows, joints, np.arange(nb - P, extra.shape[2]))] / blk.scale[None, :, None]
    own = own.reshape(-1, len(names) - nb)                                           # (M S, E)
    # the effect's own columns are fitted even where they are zero: least squares leaves a
    # column without data at a start of its own choosing, as the whole fit does
    block = np.concatenate([blk.shared_block, np.ones(len(names) - nb, bool)])
    x = np.empty(len(names))
    x[:nb] = base.values                                     # every other joint's part, as fitted
    x[nb:] = 0.0
    R, z, q1 = block_factor(blk, own)
    if block.any():
        x[block] = bounded_linear(R, z, lo[block], hi[block])
    fitted = R @ x[block]                                    # the block's columns are [q0 | q1] R
    k = blk.q0.shape[1]
    res = (blk.y_f - blk.q0 @ fitted[:k] - q1 @ fitted[k:]).reshape(-1, S)
    residual = base.residual.reshape(-1, J).copy()
    old = residual[:, joints]
    residual[:, joints] = res
    rss = base.rss - float(np.sum(old ** 2)) + float(np.sum(res ** 2))
    se = np.full(len(names), np.nan)
    se[: len(base.stderr)] = base.stderr
    free = np.concatenate([td.refitted_beside_effects(), np.ones(len(names) - P, bool)])
    n_free, n_rows, n_all = int(free.sum()), blk.y_f.size, int(td.valid.sum()) * J
    if block.any() and stderr:  # Gauss-Markov with the whole fit's s^2 = rss / (n - p); J^T J is block diagonal
        local, cond = covariance(R, rss * (n_rows - block.sum()) / max(n_all - n_free, 1), n_rows)
        se[block] = local
    else:
        cond = base.condition
        se[block] = np.nan  # not computed (stderr=False)
    at = [n for n, val, a, b, f in zip(names, x, lo, hi, free)
          if f and ((np.isfinite(a) and val - a < 1e-6) or (np.isfinite(b) and b - val < 1e-6))]
    return Fit(list(names), x, se, rss, n_all, cond, at, residual.ravel())


@dataclass
class JointBlock:
    """What every effect fitted at the same joints against the same base fit and kept terms
    shares in :func:`fit_at_joints`: the rows (valid samples of ``joints``, each joint's scaled
    by its residual's s.d.), the part of them the columns held or not acting there predict,
    taken out (``y_f``), and the QR factors of the free columns acting there (the joints'
    damping, the kept terms), in which an effect's own columns are then added by one
    projection (:func:`block_factor`).  On humanoid38 the regressor slice it is made from holds
    the joints' samples times every body column acting at them: made once per joint set, not
    once per effect."""
    scale: np.ndarray          # (S,) each joint's residual s.d. [N m]
    y_f: np.ndarray            # (M S,) scaled residual less the non-block columns' part
    q0: np.ndarray             # (M S, k) orthonormal basis of the shared block columns
    r0: np.ndarray             # (k, k) their triangular factor
    z0: np.ndarray             # (k,) q0^T y_f
    shared_block: np.ndarray   # (len(names) - E,) bool: which non-effect columns are in the block


def block_factor(blk: JointBlock, own: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(R, Q^T y_f, q1) of [shared block columns | ``own`` (M S, E)] with Q = [q0 | q1]: ``own``
    projected off q0 twice (classical Gram-Schmidt with reorthogonalisation, "twice is enough",
    Giraud et al. 2005) and the rest factored, so R^T R is the block's Gram matrix and
    |A x - y_f|^2 = |R x - Q^T y_f|^2 + |y_f|^2 - |Q^T y_f|^2 (lsq.bounded_linear)."""
    q0, r0 = blk.q0, blk.r0
    c = q0.T @ own
    perp = own - q0 @ c
    c2 = q0.T @ perp
    perp -= q0 @ c2
    q1, r1 = np.linalg.qr(perp)
    k, e = r0.shape[1], own.shape[1]
    R = np.zeros((k + e, k + e))
    R[:k, :k], R[:k, k:], R[k:, k:] = r0, c + c2, r1
    return R, np.concatenate([blk.z0, q1.T @ blk.y_f]), q1


def joint_block(td: TorqueData, extra: np.ndarray, base: Fit, joints: np.ndarray) -> JointBlock:
    """The :class:`JointBlock` of ``joints`` for effects whose columns follow ``extra``'s kept
    terms (``len(base.values) - len(td.names)`` columns) and the base fit ``base``."""
    P, n_kept = len(td.names), len(base.values) - len(td.names)
    v = td.valid
    y_all = td.residual[v]
    scale = np.maximum(np.std(y_all[:, joints], axis=0), 1e-9)
    # only the regressor columns non-zero at these joints (a humanoid's arm joint: its own
    # bodies' of the 38 joints'): the others add nothing to these rows, whose slices are taken
    # at the valid samples alone
    cols = np.flatnonzero(td.regressor_reach()[joints].any(axis=0))
    rows = np.flatnonzero(v)
    A = np.concatenate([td.regressors[np.ix_(rows, joints, cols)], extra[np.ix_(rows, joints, np.arange(n_kept))]],
                       axis=2) / scale[None, :, None]
    A = A.reshape(-1, cols.size + n_kept)                                            # (M S, |cols| + kept)
    y = (y_all[:, joints] / scale).ravel()
    free = np.concatenate([td.refitted_beside_effects(), np.ones(n_kept, bool)])
    # the free columns acting at these joints (a kept term's rounding there does not count: it
    # stays at its base value)
    acts = np.zeros(P + n_kept, bool)
    acts[cols] = True
    acts[P:] = column_reach(extra[:, :, :n_kept], v)[joints].any(axis=0) if n_kept else acts[P:]
    block = free & acts
    sub = np.concatenate([cols, P + np.arange(n_kept)])
    held = np.concatenate([td.calibration.values, np.zeros(n_kept)])
    x = np.where(free, base.values, held)
    in_block = block[sub]
    y_f = y - A[:, ~in_block] @ x[sub][~in_block]
    q0, r0 = np.linalg.qr(A[:, in_block])
    return JointBlock(scale, y_f, q0, r0, q0.T @ y_f, block)


@dataclass
class FoldAtJoint:
    """One fold of the two-fold cross-validation of an effect at joint j, with everything that
    does not depend on the effect computed once (an end stop's place is chosen on a grid of
    24 stops a side, each fitted in both folds: on humanoid38 the fits' set-up, repeated,
    cost more than their least squares)."""

    fit_valid: np.ndarray    # (N,) the samples fitted
    scale: float             # joint j's rows divided by this (its residual's s.d., as fit_at_joints)
    A: np.ndarray            # (M, B) the base's free columns acting at joint j, scaled
    y: np.ndarray            # (M,) joint j's residual less the held columns, scaled
    lower: np.ndarray        # (B,) their bounds
    upper: np.ndarray
    base_values: np.ndarray  # (B,) their values in the base fit
    test_valid: np.ndarray   # (N,) the samples predicted
    test_regressors: np.ndarray  # (M_t, J, B) those columns at the predicted samples
    base_residual: np.ndarray    # (M_t, J) the base fit's residual there


def folds_at_joint(td: TorqueData, j: int, folds: list) -> list[FoldAtJoint]:
    """:class:`FoldAtJoint` of each fold ``(fit on, test on, base fit on the first, its residual
    on the second's valid samples)`` for effects acting at joint ``j`` alone (fit_at_joints'
    problem with ``joints = [j]`` and no kept terms)."""
    cal = td.calibration
    free = td.refitted_beside_effects()
    out = []
    for fit_on, test_on, base, base_res in folds:
        v = fit_on.valid
        scale = max(float(np.std(td.residual[v, j])), 1e-9)
        A = td.regressors[v, j] / scale                                       # (M, P)
        block = free & np.any(A != 0, axis=0)
        held = np.where(free, base.values, cal.values)
        y = td.residual[v, j] / scale - A[:, ~block] @ held[~block]
        out.append(FoldAtJoint(v, scale, A[:, block], y, td.lower[block], td.upper[block], base.values[block],
                               test_on.valid, td.regressors[:, :, block][test_on.valid], base_res))
    return out


def two_fold_rss_at(j: int, extra: np.ndarray, bounds, folds: list[FoldAtJoint], valid: np.ndarray) -> float:
    """Residual sum of squares of the torque balance with an effect's columns ``extra`` (N, J, E),
    acting at joint ``j`` alone, each fold's test samples predicted by a fit to its other samples
    (the sum over both folds of :func:`fit_effect` then the test residual).  The least squares
    is BVLS (Stark & Parker 1995), exact for these few columns where trf stops at its tolerance;
    a fold the effect does not reach (:func:`reaches_fold`) keeps the base's test residual."""
    size = np.max(np.abs(extra[valid]), initial=0.0)
    total = 0.0
    for f in folds:
        if not reaches_fold(extra, f.fit_valid, valid, size):
            total += float(np.sum(f.base_residual ** 2))
            continue
        A = np.concatenate([f.A, extra[f.fit_valid, j] / f.scale], axis=1)
        lo, hi = np.concatenate([f.lower, bounds[0]]), np.concatenate([f.upper, bounds[1]])
        x = lsq_linear(A, f.y, bounds=(lo, hi), method="bvls").x
        B = f.base_values.size
        res = (f.base_residual - np.einsum("njb,b->nj", f.test_regressors, x[:B] - f.base_values)
               - np.einsum("nje,e->nj", extra[f.test_valid], x[B:]))
        total += float(np.sum(res ** 2))
    return total
