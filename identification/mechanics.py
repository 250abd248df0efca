"""The rigid body's equation error: the torque the cylinders made minus what inverse dynamics
needs (paper 002 eqs. 1-5 in MuJoCo form).

    tau_res = J^T F(p_measured) - mj_inverse(q, qd, qdd)

with q smoothed and differentiated by splines.  Calibration regressors (per moving body a
mass-and-inertia scale, per joint damping and armature) are the finite differences of the
inverse dynamics — exact, since it is linear in each — so calibration is linear least squares.
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.optimize import lsq_linear

from pneumatics.chamber import actuator_force

from .data import Experiment
from .lsq import Fit, _covariance


@dataclass
class TorqueData:
    """Per sample n and joint j: tau_act (N, J), tau_inv (N, J), regressors (N, J, P) and
    their names; ``valid`` (N,) excludes samples near the joint limits and the ends."""

    tau_act: np.ndarray
    tau_inv: np.ndarray
    regressors: np.ndarray
    names: list
    lower: np.ndarray
    upper: np.ndarray
    valid: np.ndarray
    dtau_dq: np.ndarray = None  # (N, J, J) d tau_inv / d q_k (angle offsets)
    dtau_dp: np.ndarray = None  # (N, J, C) d tau_act / d p_c per Pa measured (pressure-sensor offsets)

    @property
    def residual(self) -> np.ndarray:
        return self.tau_act - self.tau_inv


def _inverse(model, qadr, dadr, q, qd, qdd, ids=None, forces=None, moments=False):
    """Inverse-dynamics torques (N, J); with ``forces`` (N, A) also the actuators' joint torques
    (N, J); with ``moments`` also d tau / d F of every actuator (N, J, A)."""
    d = mujoco.MjData(model)
    n = q.shape[0]
    out = np.empty((n, len(dadr)))
    act = np.empty((n, len(dadr))) if forces is not None else None
    mom = np.empty((n, len(dadr), len(ids))) if moments else None
    for k in range(n):
        d.qpos[qadr] = q[k]
        d.qvel[dadr] = qd[k]
        d.qacc[dadr] = qdd[k]
        mujoco.mj_inverse(model, d)
        out[k] = d.qfrc_inverse[dadr]
        if forces is not None:
            d.ctrl[:] = 0
            d.ctrl[ids] = forces[k]
            mujoco.mj_fwdActuation(model, d)
            act[k] = d.qfrc_actuator[dadr]
            if moments:  # the force law is linear: one unit force per actuator gives its moment arms
                for i, a in enumerate(ids):
                    d.ctrl[:] = 0
                    d.ctrl[a] = 1.0
                    mujoco.mj_fwdActuation(model, d)
                    mom[k, :, i] = d.qfrc_actuator[dadr]
    if moments:
        return out, act, mom
    return out, act


def torque_data(exp: Experiment, limit_margin_rad: float = np.radians(4.0), edge: int = 10) -> TorqueData:
    robot = exp.robot
    model = robot.model
    # equality constraints (e.g. a brace) are off in recordings of the free robot
    qadr, dadr = robot.qpos_index, robot.dof_index
    forces = actuator_force(robot.tables, exp.p)
    tau_inv, tau_act, moment = _inverse(model, qadr, dadr, exp.q_s, exp.qd, exp.qdd, robot.actuator_ids, forces,
                                        moments=True)
    # F = A_a p_a - A_b p_b - ... (actuator_force): a measured pressure p_c = true + offset adds
    # moment * (+A_a | -A_b) * offset to the actuator torque
    tab = robot.tables
    dtau_dp = np.empty(moment.shape[:2] + (2 * moment.shape[2],))
    dtau_dp[:, :, 0::2] = moment * np.asarray(tab.area_a)
    dtau_dp[:, :, 1::2] = -moment * np.asarray(tab.area_b)
    names, regs, lo, hi = [], [], [], []
    base = tau_inv
    # mass-and-inertia scale per body that moves with a joint
    for b in range(1, model.nbody):
        if model.body_dofnum[b] == 0 and model.body_weldid[b] == 0:
            continue
        if model.body_mass[b] <= 0:
            continue
        m2 = _copy(model)
        m2.body_mass[b] *= 2.0
        m2.body_inertia[b] *= 2.0
        reg, _ = _inverse(m2, qadr, dadr, exp.q_s, exp.qd, exp.qdd)
        names.append(f"mass_scale.{model.body(b).name}")
        regs.append(reg - base)  # d tau / d(scale) for a scale change of +1
        lo.append(-0.35)
        hi.append(0.35)
    for j, jn in enumerate(robot.joint_names):
        dof = dadr[j]
        # armature: the pistons' reflected inertia is poorly known and weakly identifiable
        for field, lo_, hi_ in (("dof_damping", -0.3, 0.3), ("dof_armature", -0.5, 2.0)):
            nominal = getattr(model, field)[dof]
            if nominal <= 0:
                continue
            m2 = _copy(model)
            getattr(m2, field)[dof] *= 2.0
            reg, _ = _inverse(m2, qadr, dadr, exp.q_s, exp.qd, exp.qdd)
            names.append(f"{field.split('_')[1]}_scale.{jn}")
            regs.append(reg - base)
            lo.append(lo_)
            hi.append(hi_)
    dtau_dq = np.empty((tau_inv.shape[0], len(dadr), len(dadr)))
    for k in range(len(dadr)):
        dq = np.zeros(len(dadr))
        dq[k] = 1e-5
        plus, _ = _inverse(model, qadr, dadr, exp.q_s + dq, exp.qd, exp.qdd)
        dtau_dq[:, :, k] = (plus - tau_inv) / 1e-5
    rng_ = robot.joint_range()
    near = np.any((exp.q_s < rng_[:, 0] + limit_margin_rad) | (exp.q_s > rng_[:, 1] - limit_margin_rad), axis=1)
    valid = ~near
    for b in (0, *exp.breaks, valid.size):  # the ends of every pooled recording
        valid[max(b - edge, 0):b + edge] = False
    return TorqueData(tau_act, tau_inv, np.stack(regs, axis=2), names, np.array(lo), np.array(hi), valid, dtau_dq,
                      dtau_dp)


def _copy(model):
    import copy
    return copy.copy(model)


def fit_rigid_body(td: TorqueData, extra: np.ndarray | None = None, extra_names=(), extra_bounds=None):
    """Bounded linear least squares of tau_res = sum theta_k reg_k (+ extra regressors).

    ``extra`` (N, J, E) adds effect regressors (e.g. friction).  Returns a Fit (scales are
    relative changes: 0 = nominal)."""
    v = td.valid
    A = td.regressors[v]
    lo, hi = td.lower, td.upper
    names = list(td.names)
    if extra is not None:
        A = np.concatenate([A, extra[v]], axis=2)
        names += list(extra_names)
        elo, ehi = extra_bounds if extra_bounds is not None else (np.full(extra.shape[2], -np.inf), np.full(extra.shape[2], np.inf))
        lo, hi = np.concatenate([lo, elo]), np.concatenate([hi, ehi])
    y = td.residual[v]
    scale = np.array([max(np.std(y[:, j]), 1e-9) for j in range(y.shape[1])])
    A2 = (A / scale[None, :, None]).reshape(-1, A.shape[2])
    y2 = (y / scale).ravel()
    r = lsq_linear(A2, y2, bounds=(lo, hi))
    res = y2 - A2 @ r.x
    rss = float(res @ res)
    se, cond = _covariance(A2, rss, y2.size)
    at = [n for n, x, a, b in zip(names, r.x, lo, hi) if (np.isfinite(a) and x - a < 1e-6) or (np.isfinite(b) and b - x < 1e-6)]
    return Fit(names, r.x, se, rss, y2.size, cond, at, res)
