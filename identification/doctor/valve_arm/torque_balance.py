"""The rigid body's torque balance on a recording: the torque the cylinders made and what
inverse dynamics needs (paper 002 eqs. 1-5 in MuJoCo form),

    tau_res = J^T F(p_measured) - mj_inverse(q, qd, qdd)

with q smoothed and differentiated by splines, and the calibration's regressors (per moving
body a mass-and-inertia scale, per joint damping and armature): the finite differences of the
inverse dynamics -- exact, since it is linear in each.  The fits on these data are in
mechanics.py.

**Parallel filtering and decimation** (Gautier & Khalil; Swevers et al. 2007, "Dynamic model
identification for industrial robots", IEEE CSM 27(5)).  The spline attenuates the fast part
of the accelerations, the measured torque keeps it, and the noise left in q-double-dot makes
the regressors errors-in-variables; both biased the inertias by 5-15 % on arm2 recordings with
the model's own 0.05 deg angle noise.  The torque and every regressor column pass the same
zero-phase low-pass (a model linear in its parameters stays linear), well inside the band where
the spline is exact, and are then sampled at about 2.5x the cut-off so that the residual
samples are nearly independent and the standard errors mean what they say.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np
from scipy.signal import butter, sosfiltfilt

from identification.base.lsq import Fit
from pneumatics.chamber import actuator_force

from .data import Experiment

#: the parallel low-pass sits at this fraction of the angle splines' half-amplitude frequency,
#: where the spline passes q-double-dot within 0.2 % (H = 1 / (1 + 0.2^4), smoothing.spline_cutoff_hz).
#: It must be that close: arm2's upper link is a fifth of the shoulder's inertia, so a 1 %
#: error in the total is 5 % on its scale (0.35 of the cut-off left +1..4 % there, 0.2 under 1 %)
PARALLEL_FRACTION = 0.2
#: decimated samples per cut-off period / 2 (2.5: Nyquist of the decimated data 1.25x the cut-off)
DECIMATION_MARGIN = 2.5
#: the blocks of the torque balance's two-fold cross-validation [s]: longer than an impact's
#: transient or a breakaway, shorter than the excursions of a 60 s hand-moved reference
FOLD_BLOCK_S = 2.0


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
    rate_hz: float = 100.0
    lowpass_hz: float = np.inf  # the parallel filter's cut-off (inf: none, noise-free angles)
    breaks: tuple = ()          # sample indices where a pooled recording starts
    fixed: dict = None          # calibration parameters kept nominal -> why (calibrate_rigid_body)
    calibration: Fit = None     # calibrate_rigid_body's result, whose inertias the effect fits hold
    joint_ok: np.ndarray = None  # (N, J) False where a joint's equation is left out (a coupled joint near its limit)
    dtau_drate: np.ndarray = None  # (N, J, J) d tau_inv / d g_k: joint k's rates read (1 + g_k) times (angle sensor gain)
    held_nominal: str = ""      # why the rigid body is held at its nominal values ("": calibrated; hold_nominal)
    #: (J, P) regressor_reach's answer, made at its first call (a replace()d copy makes its own)
    _reach: np.ndarray = field(default=None, init=False, repr=False, compare=False)

    def mask(self, x: np.ndarray) -> np.ndarray:
        """x (N, J, ...) with the equations ``joint_ok`` leaves out set to zero (a zero row of
        torque and regressors drops out of every least-squares fit)."""
        if self.joint_ok is None or self.joint_ok.all():
            return x
        return np.where(self.joint_ok.reshape(self.joint_ok.shape + (1,) * (x.ndim - 2)), x, 0.0)

    def regressor_reach(self) -> np.ndarray:
        """(J, P): which regressor columns are non-zero at each joint's ``valid`` samples (a
        body's inertias reach the joints it hangs from, a joint's damping its own)."""
        if self._reach is None:
            self._reach = np.any(self.regressors[self.valid] != 0, axis=0)
        return self._reach

    @property
    def residual(self) -> np.ndarray:
        return self.tau_act - self.tau_inv

    def refitted_beside_effects(self) -> np.ndarray:
        """(P,) which calibration columns an effect's fit refits beside it: the joints' damping
        not kept nominal (an effect such as friction may have taken it up); the inertias stay
        at the calibration (fit_rigid_body)."""
        fixed = self.fixed or {}
        return np.array([n.startswith("damping_scale.") and n not in fixed for n in self.names], bool)

    def decimate(self, x: np.ndarray) -> np.ndarray:
        """x (N, ...) low-passed like the torque (zero phase, per pooled recording) and taken at
        every D-th valid sample away from the filter's reach of an invalid one: (M, ...)."""
        if not np.isfinite(self.lowpass_hz):
            return x[self.valid]
        sos = butter(4, self.lowpass_hz / (0.5 * self.rate_hz), output="sos")
        # invalid samples (near a joint limit, where MuJoCo's inverse dynamics adds the limit's
        # constraint force) set to zero in torque and regressors alike: the balance still holds
        # sample by sample, and their torques, often 100x the rest, cannot leak through the
        # filter's tails into the samples kept
        x = np.where(self.valid.reshape((-1,) + (1,) * (x.ndim - 1)), x, 0.0)
        y = np.empty_like(x)
        bounds = (0, *self.breaks, x.shape[0])
        for a, b in zip(bounds[:-1], bounds[1:]):
            y[a:b] = sosfiltfilt(sos, x[a:b], axis=0)
        if self.joint_ok is not None and x.ndim >= 2 and not self.joint_ok.all():
            # a joint's equations within the filter's reach of its left-out ones mix in their zeros
            reach = int(np.ceil(self.rate_hz / self.lowpass_hz))
            kernel = np.ones(2 * reach + 1)
            near = np.stack([np.convolve((~ok).astype(float), kernel, "same") > 0 for ok in self.joint_ok.T], axis=1)
            y = np.where(near.reshape(near.shape + (1,) * (x.ndim - 2)), 0.0, y)
        return y[self.decimation_index()]

    def two_fold(self) -> list:
        """[(fit on, test on)] x 2: the valid samples split into alternating FOLD_BLOCK_S
        blocks, each set to be predicted by a fit to the other (two-fold cross-validation).
        Blocks, not halves: a regime the motion visits in one half only (a bumper pressed
        during the first half's excursions) would otherwise be tested where it never occurs."""
        half = (np.arange(self.valid.size) // max(1, int(round(FOLD_BLOCK_S * self.rate_hz)))) % 2 == 0
        return [(replace(self, valid=self.valid & part), replace(self, valid=self.valid & ~part)) for part in (half, ~half)]

    def decimation_index(self) -> np.ndarray:
        """Indices (M,) of the samples a filtered fit uses (see ``decimate``)."""
        reach = int(np.ceil(self.rate_hz / self.lowpass_hz))  # >99.9 % of the filter's impulse response
        bad = ~self.valid.copy()
        for b in (0, *self.breaks, bad.size):
            bad[max(b - 1, 0):b + 1] = True
        near = np.convolve(bad.astype(float), np.ones(2 * reach + 1), "same") > 0
        step = max(1, int(self.rate_hz / (DECIMATION_MARGIN * self.lowpass_hz)))
        keep = np.zeros_like(near)
        keep[::step] = True
        return np.flatnonzero(keep & ~near)


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


def own_dof_regressor(model, attr: str, j: int, dadr, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray | None:
    """(N, J) d tau_inverse / d(scale) of joint j's ``attr`` ("dof_damping" or "dof_armature")
    scaled by 1 + scale (None where it is 0): MuJoCo's inverse dynamics adds the damping's
    b qd and the armature's a qdd at that dof alone (qfrc_inverse = M qacc + c - qfrc_passive -
    qfrc_constraint, the armature on M's diagonal; MuJoCo documentation, "Inverse dynamics"),
    so the column is b qd_j or a qdd_j (the inverse dynamics of the model with it doubled less
    the nominal's, :func:`finite_difference_regressor`, to round-off; tests/test_rigid_body_calibration.py)."""
    nominal = float(getattr(model, attr)[dadr[j]])
    if nominal <= 0:
        return None
    reg = np.zeros(qd.shape)
    reg[:, j] = nominal * (qd[:, j] if attr == "dof_damping" else qdd[:, j])
    return reg


def finite_difference_regressor(model, attr: str, j: int, qadr, dadr, q, qd, qdd) -> np.ndarray:
    """:func:`own_dof_regressor` the long way: the inverse dynamics with joint j's ``attr``
    doubled less the nominal model's."""
    m2 = _copy(model)
    getattr(m2, attr)[dadr[j]] *= 2.0
    return _inverse(m2, qadr, dadr, q, qd, qdd)[0] - _inverse(model, qadr, dadr, q, qd, qdd)[0]


def torque_data(exp: Experiment, limit_margin_rad: float = np.radians(4.0), edge: int = 10,
                held_nominal: str = "") -> TorqueData:
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
        # armature: the pistons' reflected inertia is poorly known and weakly identifiable
        for attr, lo_, hi_ in (("dof_damping", -0.3, 0.3), ("dof_armature", -0.5, 2.0)):
            reg = own_dof_regressor(model, attr, j, dadr, exp.qd, exp.qdd)
            if reg is None:
                continue
            names.append(f"{attr.split('_')[1]}_scale.{jn}")
            regs.append(reg)
            lo.append(lo_)
            hi.append(hi_)
    # tau_inv's change per unit of joint k's angle, and per unit gain of its rates: an angle
    # sensor's gain error scales the rates differentiated from its angles as well
    # (effects.angle_sensor_offset, offset_and_scale form)
    dtau_dq = np.empty((tau_inv.shape[0], len(dadr), len(dadr)))
    dtau_drate = np.empty_like(dtau_dq)
    for k in range(len(dadr)):
        step = np.zeros(len(dadr))
        step[k] = 1e-5
        plus, _ = _inverse(model, qadr, dadr, exp.q_s + step, exp.qd, exp.qdd)
        dtau_dq[:, :, k] = (plus - tau_inv) / 1e-5
        plus, _ = _inverse(model, qadr, dadr, exp.q_s, exp.qd * (1.0 + step), exp.qdd * (1.0 + step))
        dtau_drate[:, :, k] = (plus - tau_inv) / 1e-5
    rng_ = robot.joint_range()
    near = (exp.q_s < rng_[:, 0] + limit_margin_rad) | (exp.q_s > rng_[:, 1] - limit_margin_rad)   # (N, J)
    # a joint's equation is left out while a joint it is coupled to through the mass matrix is
    # near its limit (MuJoCo's inverse dynamics then holds the limit's force and the impact's
    # poorly smoothed acceleration); on arm2 every joint is coupled to every other, on a
    # humanoid a limb's joint to its chain alone, so one joint at a limit does not drop the rest
    joint_ok = ~((near.astype(float) @ mass_coupled_joints(model, dadr).T.astype(float)) > 0)
    valid = joint_ok.any(axis=1)
    for b in (0, *exp.breaks, valid.size):  # the ends of every pooled recording
        valid[max(b - edge, 0):b + edge] = False
    joint_ok &= valid[:, None]
    lowpass = PARALLEL_FRACTION * exp.q_cutoff_hz
    if lowpass >= 0.4 * exp.rate_hz:  # noise-free angles: the spline interpolates, nothing to match
        lowpass = np.inf
    td = TorqueData(tau_act, tau_inv, np.stack(regs, axis=2), names, np.array(lo), np.array(hi), valid, dtau_dq,
                    dtau_dp, exp.rate_hz, lowpass, tuple(exp.breaks), joint_ok=joint_ok, held_nominal=held_nominal)
    td.tau_act, td.tau_inv, td.regressors = td.mask(tau_act), td.mask(tau_inv), td.mask(td.regressors)
    td.dtau_dq, td.dtau_dp, td.dtau_drate = td.mask(dtau_dq), td.mask(dtau_dp), td.mask(dtau_drate)
    return td


def with_pressures(td: TorqueData, made_from: Experiment, exp: Experiment, held_nominal: str = "") -> TorqueData | None:
    """torque_data(exp) derived from ``td`` = torque_data(made_from), when ``exp`` is the same
    motion of the same robot read with other pressures (sensor_offsets.corrected shares the angle
    arrays); None otherwise.  The force law is linear in the pressures (chamber.py: F = A_a p_a -
    A_b p_b - (A_a - A_b) p_room), so the actuator torques change by dtau_dp . (p - p_before)
    and nothing else changes: the inverse dynamics, its regressors and derivatives depend on the
    motion alone (on humanoid38 about 190 passes over the recording, 20 s each time).  Masked
    rows stay zero in both terms."""
    same = (exp.robot is made_from.robot and exp.q_s is made_from.q_s and exp.qd is made_from.qd
            and exp.qdd is made_from.qdd)
    if not same or td.fixed is not None or td.calibration is not None:
        return None
    tau_act = td.tau_act + np.einsum("njc,nc->nj", td.dtau_dp, exp.p - made_from.p)
    return replace(td, tau_act=tau_act, held_nominal=held_nominal)


def mass_coupled_joints(model, dof_index: np.ndarray) -> np.ndarray:
    """(J, J) bool: joints j and k share mass-matrix entries (one's dof is an ancestor of the
    other's in the kinematic tree, MuJoCo's dof_parentid), or j == k."""
    ancestors = []
    for d in dof_index:
        chain, p = set(), int(model.dof_parentid[d])
        while p >= 0:
            chain.add(p)
            p = int(model.dof_parentid[p])
        ancestors.append(chain)
    dofs = [int(d) for d in dof_index]
    return np.array([[j == k or dofs[k] in ancestors[j] or dofs[j] in ancestors[k] for k in range(len(dofs))]
                     for j in range(len(dofs))])


def _copy(model):
    return copy.copy(model)
