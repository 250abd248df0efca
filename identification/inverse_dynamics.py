"""Inverse dynamics of the 2-DOF arm by linear regression (paper 002 §IV-A, eqs. 1-5).

The model predicts each joint's chamber pressure difference d_i = p_i^+ - p_i^- from the
joint positions, velocities and accelerations, with eight lumped parameters w::

    M(q)   = [[w1 + w2 cos 2q2, 0], [0, w3]]                                  (eq. 1)
    n(q,qd)= w2 [-2 sin 2q2 qd1 qd2, sin 2q2 qd1^2]                           (eq. 2)
    g(q)   = w4 [sin q1 cos q2, cos q1 sin q2]                                (eq. 3)
    b(qd)  = [w5 qd1, w6 qd2]                                                 (eq. 4)
    tau    = M qdd + n + g + b + [w7, w8]      (offsets: sensor calibration)  (eq. 5)

Every w enters linearly, so ordinary least squares gives the global optimum.  The paper's
arm has the same cylinder on both joints, so it regresses d directly ("a scaling factor is
not needed").  arm2's cylinders differ (bore 20 vs 16 mm, moment arm 30 vs 25 mm), so the
torque-to-pressure scale differs by ~1.9x between joints and the shared w2, w4 could not fit
both; we therefore divide each joint's row by its known geometric gain
G_i = r_i A_i^+ [m^3] (moment arm x chamber-a piston area: tau_i ~= G_i d_i), which keeps
the eight parameters in torque units (kg m^2, N m, N m s) and the fit linear.  The rod makes
the true torque r (A^+ p^+ - A^- p^- - (A^+ - A^-) p_room), not exactly G d: that part is
unmodelled, as it is on the real robot, and lowers R^2.

Velocities and accelerations come from smoothing splines of the measured angles
(:mod:`identification.base.smoothing`); samples near the joint limits (end-stop torques the
model does not have) and at the recording's edges (spline end effects) are left out.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pneumatics.errors import PneumasimError
from pneumatics.recording import Recording

from identification.base import lsq
from identification.base.smoothing import smooth_derivatives

PARAM_NAMES = ("w1_inertia_kg_m2", "w2_inertia_coupling_kg_m2", "w3_inertia_elbow_kg_m2", "w4_gravity_n_m",
               "w5_viscous_shoulder_n_m_s", "w6_viscous_elbow_n_m_s", "w7_offset_shoulder_n_m",
               "w8_offset_elbow_n_m")
JOINTS = ("shoulder", "elbow")


def regressor(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """Torque regressor Y with tau = Y w (eqs. 1-5).

    Args: q, qd, qdd: (N, 2) joint positions [rad], velocities [rad/s], accelerations [rad/s^2].
    Returns: (N, 2, 8) rows for (shoulder, elbow).
    """
    q, qd, qdd = (np.atleast_2d(np.asarray(a, float)) for a in (q, qd, qdd))
    n = q.shape[0]
    s2, c2 = np.sin(2 * q[:, 1]), np.cos(2 * q[:, 1])
    y = np.zeros((n, 2, 8))
    y[:, 0, 0] = qdd[:, 0]
    y[:, 0, 1] = c2 * qdd[:, 0] - 2 * s2 * qd[:, 0] * qd[:, 1]
    y[:, 0, 3] = np.sin(q[:, 0]) * np.cos(q[:, 1])
    y[:, 0, 4] = qd[:, 0]
    y[:, 0, 6] = 1.0
    y[:, 1, 1] = s2 * qd[:, 0] ** 2
    y[:, 1, 2] = qdd[:, 1]
    y[:, 1, 3] = np.cos(q[:, 0]) * np.sin(q[:, 1])
    y[:, 1, 5] = qd[:, 1]
    y[:, 1, 7] = 1.0
    return y


def torque_gain(robot) -> np.ndarray:
    """(2,) G_i = moment arm x chamber-a area [m^3] of each joint's cylinder (tau ~= G d).

    Needs joint transmissions (constant moment arm = MJCF gear), as arm2 has."""
    m = robot.model
    out = []
    for joint in JOINTS:
        if joint not in robot.actuator_names:
            raise PneumasimError(f"{robot.name}: the arm inverse dynamics needs actuators named {JOINTS}; "
                                 f"the model has {robot.actuator_names}")
        k = robot.actuator_names.index(joint)
        i = robot.actuator_ids[k]
        out.append(m.actuator_gear[i, 0] * robot.fluid.actuators[k].area_a)
    return np.array(out)


@dataclass
class InverseDynamics:
    """Fitted model: ``params`` (8,) in PARAM_NAMES order, ``gain_m3`` (2,) G_i."""

    params: np.ndarray
    gain_m3: np.ndarray
    stderr: np.ndarray = field(default_factory=lambda: np.full(8, np.nan))

    def torque(self, q, qd, qdd) -> np.ndarray:
        """(N, 2) joint torques [N m] of the model."""
        return regressor(q, qd, qdd) @ self.params

    def pressure_difference(self, q, qd, qdd) -> np.ndarray:
        """(N, 2) predicted d = p^+ - p^- [Pa] (eq. 5 divided by G)."""
        return self.torque(q, qd, qdd) / self.gain_m3

    def to_dict(self) -> dict:
        return {"params": dict(zip(PARAM_NAMES, map(float, self.params))),
                "stderr": dict(zip(PARAM_NAMES, map(float, self.stderr))),
                "gain_m3": list(map(float, self.gain_m3))}

    @classmethod
    def from_dict(cls, d: dict) -> InverseDynamics:
        try:
            params = np.array([float(d["params"][n]) for n in PARAM_NAMES])
            gain = np.array(d["gain_m3"], float)
        except KeyError as e:
            raise PneumasimError(f"inverse-dynamics parameters: missing key {e}; expected params "
                                 f"{PARAM_NAMES} and gain_m3") from None
        se = d.get("stderr", {})
        return cls(params, gain, np.array([float(se.get(n, np.nan)) for n in PARAM_NAMES]))

    def save(self, path: str | Path):
        from pneumatics.io import atomic_write_json

        atomic_write_json(Path(path), self.to_dict())

    @classmethod
    def load(cls, path: str | Path) -> InverseDynamics:
        return cls.from_dict(json.loads(Path(path).read_text()))


@dataclass
class Samples:
    """Regression data from one recording: q, qd, qdd, d each (N, 2), time (N,)."""

    time: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    d: np.ndarray

    def subset(self, mask: np.ndarray) -> Samples:
        return Samples(self.time[mask], self.q[mask], self.qd[mask], self.qdd[mask], self.d[mask])


def samples(rec: Recording, joint_range: np.ndarray, *, limit_margin_rad: float = np.radians(3.0),
            edge: int = 10) -> Samples:
    """Smoothed derivatives and pressure differences of a recording, end stops left out.

    Args:
      rec: with columns q.<joint>, p_a.<joint>, p_b.<joint> for shoulder and elbow.
      joint_range: (2, 2) limits [rad]; samples within ``limit_margin_rad`` of one are dropped.
      edge: samples dropped at each end (spline end effects).
    """
    for col in [f"{p}.{j}" for j in JOINTS for p in ("q", "p_a", "p_b")]:
        if col not in rec:
            raise PneumasimError(f"{rec.source}: inverse dynamics needs column {col!r}")
    if len(rec) < 2 * edge + 20:
        raise PneumasimError(f"{rec.source}: {len(rec)} rows is too short for the inverse-dynamics fit")
    t = rec.time
    ders = [smooth_derivatives(t, rec[f"q.{j}"], 2) for j in JOINTS]
    q = np.column_stack([x[0] for x in ders])
    qd = np.column_stack([x[1] for x in ders])
    qdd = np.column_stack([x[2] for x in ders])
    d = np.column_stack([rec[f"p_a.{j}"] - rec[f"p_b.{j}"] for j in JOINTS])
    jr = np.asarray(joint_range, float)
    raw_q = rec.matrix("q", JOINTS)
    ok = np.all((raw_q > jr[:, 0] + limit_margin_rad) & (raw_q < jr[:, 1] - limit_margin_rad), axis=1)
    ok[:edge] = False
    ok[-edge:] = False
    return Samples(t, q, qd, qdd, d).subset(ok)


def concat(parts: list[Samples]) -> Samples:
    return Samples(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("time", "q", "qd", "qdd", "d")))


def fit(data: Samples | list[Samples], gain_m3: np.ndarray) -> InverseDynamics:
    """Least squares of d_i = (Y_i w) / G_i over all samples and both joints."""
    data = concat(data) if isinstance(data, list) else data
    if data.time.size < 20:
        raise PneumasimError(f"inverse dynamics: only {data.time.size} usable samples (away from the "
                             "joint limits); need a longer recording")
    y = regressor(data.q, data.qd, data.qdd) / np.asarray(gain_m3)[None, :, None]
    a = y.reshape(-1, 8)
    b = data.d.reshape(-1)
    f = lsq.linear(a, b, PARAM_NAMES)
    return InverseDynamics(f.values, np.asarray(gain_m3, float), f.stderr)


def r2(model: InverseDynamics, data: Samples | list[Samples]) -> dict:
    """R^2 of predicted vs measured d: ``pooled`` (both joints, each about its own mean, as
    the paper's single figure) and per joint."""
    data = concat(data) if isinstance(data, list) else data
    pred = model.pressure_difference(data.q, data.qd, data.qdd)
    sse = ((data.d - pred) ** 2).sum(axis=0)
    sst = ((data.d - data.d.mean(axis=0)) ** 2).sum(axis=0)
    out = {"pooled": float(1 - sse.sum() / sst.sum())}
    out.update({j: float(1 - e / s) for j, e, s in zip(JOINTS, sse, sst)})
    return out


def param_cv(params: np.ndarray) -> np.ndarray:
    """(8,) coefficient of variation std/|mean| of each parameter over datasets (rows)."""
    p = np.asarray(params, float)
    return p.std(axis=0, ddof=1) / np.maximum(np.abs(p.mean(axis=0)), 1e-300)
