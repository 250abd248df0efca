"""Calibration first: fit the nominal model's own parameters before blaming missing physics.

* Chambers: per chamber, scales of the valve's supply and exhaust areas and of the dead
  volume, by short pressure replays (:mod:`identification.doctor.valve_arm.pneumatic`), bounded to
  [1/1.35, 1.35] — a real robot's ±10 % with room to spare, not enough to mimic an effect.
* Rigid body: per moving body a mass-and-inertia scale, per joint the damping and the
  armature, by linear least squares on the inverse-dynamics torque (:mod:`mechanics`),
  bounded to +-35 % (damping +-30 %: more is viscous_friction, armature -50..+200 %:
  the pistons' reflected inertia is poorly known).

Both return an :class:`identification.base.lsq.Fit` with standard errors.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import lil_matrix

from identification.base import lsq
from .pneumatic import Windows, replay
from .pneumatic_mods import PneumaticMods

SCALE_BOUND = 1.35


def pressure_sigma(exp) -> float:
    """Noise floor of the pressure sensors [Pa] (robust, from the data)."""
    from identification.base.smoothing import noise_sd
    return float(np.median([noise_sd(exp.p[:, c]) for c in range(exp.p.shape[1])]))


def chamber_params(mods: PneumaticMods) -> np.ndarray:
    return np.log(np.concatenate([mods.supply_scale, mods.exhaust_scale, mods.dead_volume_scale]))


def with_chamber_params(mods: PneumaticMods, x: np.ndarray) -> PneumaticMods:
    C = mods.supply_scale.size
    s = np.exp(x)
    return mods.copy(supply_scale=s[:C], exhaust_scale=s[C:2 * C], dead_volume_scale=s[2 * C:])


def chamber_names(robot) -> list[str]:
    names = [f"{a}.{c}" for a, c in robot.chamber_names]
    return ([f"supply_area_scale.{n}" for n in names] + [f"exhaust_area_scale.{n}" for n in names]
            + [f"dead_volume_scale.{n}" for n in names])


#: upper bound of a dead-volume scale when the hypothesis under test is a line (tube) whose
#: volume adds to the chamber's: up to 3x (arm2: 3-4 cm^3 chambers, tubes of 1-8 cm^3)
LINE_VOLUME_BOUND = 3.0


def fit_chambers(exp, win: Windows, mods: PneumaticMods | None = None, sigma: float | None = None,
                 extra=None, wide_dead_volume=(), chambers=None):
    """Fit per-chamber area and dead-volume scales; ``extra`` = (names, x0, lo, hi, apply,
    sparsity_rows) adds effect parameters fitted jointly; the chambers ``wide_dead_volume`` may
    grow their dead volume up to LINE_VOLUME_BOUND (a tube's volume).  ``chambers``: whole
    cylinders' chambers (pneumatic.cylinder_chambers) whose scales alone are fitted, on their
    own replays, the others held at ``mods``'s (where pneumatic.chambers_independent holds:
    the others' replays do not change).  Returns (mods, Fit)."""
    C = exp.robot.tables.n_chambers
    mods = mods or PneumaticMods.nominal(C)
    sigma = sigma or pressure_sigma(exp)
    W, H = win.starts.size, win.horizon
    free = np.arange(C) if chambers is None else np.asarray(chambers, int)
    n = free.size
    at = {int(c): i for i, c in enumerate(free)}  # a free chamber's column in the replay
    scale_index = np.concatenate([k * C + free for k in range(3)])  # into chamber_params' (3 C,)
    all_names = chamber_names(exp.robot)
    names = [all_names[i] for i in scale_index]
    x_all = chamber_params(mods)
    x0 = x_all[scale_index]
    lo = np.full(x0.size, -np.log(SCALE_BOUND))
    hi = np.full(x0.size, np.log(SCALE_BOUND))
    # a line found earlier keeps its widened dead volume in later fits
    wide = {at[c] for c in wide_dead_volume if c in at} | {i for i in range(n) if x0[2 * n + i] > np.log(SCALE_BOUND)}
    for i in wide:
        hi[2 * n + i] = np.log(LINE_VOLUME_BOUND)
    n_base = x0.size
    # residual layout (W, H, n): chamber i's residuals depend on its own three scales
    sparsity = lil_matrix((W * H * n, n_base + (len(extra[1]) if extra else 0)), dtype=int)
    rows_of = [np.arange(W * H) * n + i for i in range(n)]
    for i in range(n):
        for k in range(3):
            sparsity[rows_of[i], k * n + i] = 1
    if extra:
        e_names, e_x0, e_lo, e_hi, apply, e_rows = extra
        names = names + list(e_names)
        x0 = np.concatenate([x0, e_x0])
        lo = np.concatenate([lo, e_lo])
        hi = np.concatenate([hi, e_hi])
        for j, touched in enumerate(e_rows):
            for c in touched:
                sparsity[rows_of[at[c]], n_base + j] = 1

    def build(x):
        full = x_all.copy()
        full[scale_index] = x[:n_base]
        m = with_chamber_params(mods, full)
        if extra:
            m = extra[4](m, x[n_base:])
        return m

    def residual(x):
        pred, meas = replay(exp, win, build(x), chambers)
        return ((pred - meas) / sigma).ravel()

    fit = lsq.nonlinear(residual, x0, names, lo, hi, jac_sparsity=sparsity.tocsr(), max_nfev=40,
                        diff_step=1e-4)
    return build(fit.values), fit
