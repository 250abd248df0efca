"""A recording prepared for identification: aligned, smoothed, differentiated, with the
model quantities (actuator lengths, chamber volumes) the equations need.

Timing (DESIGN.md recordings, paper 002 DAQ): a sensor row k is the mean over the control
period ending at time[k], i.e. centred half a period earlier; a command row k is held over
[time[k], time[k+1]).  Sensor-derived quantities are therefore placed at ``t_sensor``.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import mujoco
import numpy as np
from scipy.interpolate import CubicSpline

from pneumatics.errors import RecordingError
from pneumatics.recording import Recording, validate
from pneumatics.recording_checks import check_for_robot
from pneumatics.robot import Robot

from identification.base.smoothing import (discrepancy_lambda, noise_sd, smooth_derivatives, smoothing_spline,
                                          spline_cutoff_hz)

FINE_DT = 1e-3
#: rows each prepared part (fitted or held out) needs: the smoothing splines, the 30-sample
#: replay windows and the 100-sample bootstrap blocks of the doctor (2 s at 100 Hz)
MIN_ROWS = 200
#: the slowest sample rate the doctor is known to read right: on the published null case
#: (arm2, measured 2026-11-25) it found nothing at 100, 50 and 20 Hz; at 10 Hz it named a
#: piston leak that is not there and ran ten times longer (each sample spans 100 fine steps)
MIN_RATE_HZ = 20.0


@dataclass
class Experiment:
    """Shapes: N samples, J joints, C chambers (a0, b0, a1, b1, ...), F fine (1 ms) steps."""

    robot: Robot
    rec: Recording
    t: np.ndarray            # (N,) sample times [s]
    t_sensor: np.ndarray     # (N,) times the (averaged) sensor values stand for
    q: np.ndarray            # (N, J) measured angles
    q_s: np.ndarray          # (N, J) smoothed
    qd: np.ndarray           # (N, J) from the smoothing spline
    qdd: np.ndarray          # (N, J)
    p: np.ndarray            # (N, C) measured pressures [Pa]
    u: np.ndarray            # (N, C) valve commands [V]
    averaged: bool
    p_at_t: np.ndarray = field(default=None)       # (N, C) pressures at the sample times t
    fine_t: np.ndarray = field(default=None)       # (F,) 1 ms grid from t[0]
    fine_length: np.ndarray = field(default=None)  # (F, n_act) actuator lengths on the grid
    fine_q: np.ndarray = field(default=None)       # (F, J)
    breaks: tuple = ()                              # sample indices where a pooled recording starts
    q_cutoff_hz: float = np.inf                     # the angle splines' half-amplitude frequency (lowest joint)
    clock: np.ndarray = field(default=None)         # (N,) each sample's time on its own recording's clock [s]
    q_light: np.ndarray = field(default=None)       # (N, J) angles lightly smoothed (residuals at half the noise)
    qd_light: np.ndarray = field(default=None)      # (N, J) their velocities
    q_lam: np.ndarray = field(default=None)         # (R, J) each pooled recording's angle-spline lambda
    #: each chamber's share of the supply flow at the measured pressures, kept between replays
    #: (supply_shares.SupplyShares; made on first use; a copy's own data are told apart by identity)
    supply_shares: object = field(default=None, repr=False, compare=False)
    #: the rigid body's replays' observed 1 ms pressures and velocities, kept between replays
    #: (state_observer.observed_states; a copy shares the list, its entries told apart by
    #: the identity of the arrays they were made from)
    observer_cache: list = field(default_factory=list, repr=False, compare=False)

    def like_q_s(self, x: np.ndarray, j: int) -> np.ndarray:
        """x (N,) smoothed as joint j's angle was (its spline's lambda, per pooled recording).

        The torque balance's equation error is, to first order, the angle spline's filter
        applied to the missing torque (it enters through the smoothed angle's second
        derivative).  A torque sharp in the angle (a bumper the arm presses by a millimetre
        of a radian) computed from the smoothed angle is not: the spline first spreads and
        lowers the overshoot, and the hinge then cuts it.  Evaluated on the lightly smoothed
        angle and passed through the same spline, its regressor matches the equation error
        (continuous-time identification passes regressors and output through one filter:
        Garnier & Wang, eds., *Identification of Continuous-time Models from Sampled Data*,
        Springer 2008)."""
        out = np.empty_like(x, dtype=float)
        bounds = (0, *self.breaks, x.shape[0])
        for r, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
            out[a:b] = smoothing_spline(self.t_sensor[a:b], x[a:b], self.q_lam[r, j])(self.t_sensor[a:b])
        return out

    def clock_at(self, fine: bool = False) -> np.ndarray:
        """Recording time [s] of each sample (fine: of each 1 ms grid point): the clock a
        warming-up pressure sensor drifts by (pressure_sensor_offset, warm_up_drift form)."""
        clock = self.t if self.clock is None else self.clock
        return np.interp(self.fine_t, self.t, clock) if fine else clock

    @property
    def rate_hz(self) -> float:
        return float(1.0 / np.median(np.diff(self.t)))

    @property
    def n_sub(self) -> int:
        return int(round(1.0 / (self.rate_hz * FINE_DT)))


def fine_pressures(exp: Experiment, mods, chambers=None) -> np.ndarray:
    """(F, n) the measured pressures [Pa] of ``chambers`` (default all) on the 1 ms grid, with
    the chamber model's (``mods``) sensor offsets removed: their light spline's values at the
    sample times (``p_at_t``) interpolated by a cubic spline within each pooled recording
    (de Boor, *A Practical Guide to Splines*, 1978, ch. IV: the error of cubic interpolation
    falls as h^4, a straight line's as h^2), a straight line across the joins.

    Humanoid38 limit-cycles at 9-14 Hz, sampled at 100 Hz: on a 30 s recording of the nominal
    robot under its PIDF, with its sensors' noise and DAQ means (development probe, 2026-12-07),
    straight lines between the samples missed the simulator's own 1 ms pressures by 7.4 kPa rms,
    the cubic by 5.3 kPa, and the rigid body replayed from the recorded state with the cubic's
    forces (angle_replay, 0.2 s windows) followed the angles closer: the 38 joints' summed
    squared NRMSE 0.30 against 0.38 (0.05 from the simulator's true state and pressures)."""
    cs = np.arange(exp.p_at_t.shape[1]) if chambers is None else np.asarray(chambers, int)
    p_t = exp.p_at_t[:, cs]
    p = np.empty((exp.fine_t.size, cs.size))
    joins = np.ones(exp.fine_t.size, bool)
    bounds = (0, *exp.breaks, exp.t.size)
    for a, b in zip(bounds[:-1], bounds[1:]):
        f0, f1 = (int(round((exp.t[i] - exp.fine_t[0]) / FINE_DT)) for i in (a, b - 1))
        rows = slice(f0, f1 + 1)
        p[rows] = (CubicSpline(exp.t[a:b], p_t[a:b])(exp.fine_t[rows]) if b - a >= 4 else
                   np.column_stack([np.interp(exp.fine_t[rows], exp.t[a:b], p_t[a:b, k]) for k in range(cs.size)]))
        joins[rows] = False
    if joins.any():
        p[joins] = np.column_stack([np.interp(exp.fine_t[joins], exp.t, p_t[:, k]) for k in range(cs.size)])
    offset = mods.sensor_offsets(exp.clock_at(fine=True))
    return p if offset is None else p - offset[..., cs]


def prepare(robot: Robot, rec: Recording, *, averaged: bool | None = None, checked: bool = False) -> Experiment:
    """Validate ``rec`` against ``robot`` and prepare it (raises RecordingError on bad data).
    ``checked``: the whole recording ``rec`` was cut from already passed these checks
    (``validate`` and recording_checks.check_for_robot), so they are not repeated (nor their
    warnings, which would name the slice instead of the user's file)."""
    if not checked:
        validate(rec, robot.joint_names, robot.actuator_names, model_name=robot.name)
        check_for_robot(rec, robot)  # gauge pressures, degrees, values the robot cannot produce
    t = rec.time
    if t.size < MIN_ROWS:
        raise RecordingError(f"{rec.source}: {t.size} rows is too short to diagnose (need >= {MIN_ROWS}, "
                             f"{MIN_ROWS / rec.rate_hz:.3g} s at its {rec.rate_hz:.4g} Hz)")
    dt = np.diff(t)
    if np.max(dt) > 1.5 * np.median(dt) or np.min(dt) < 0.5 * np.median(dt):
        i = int(np.argmax(np.abs(dt - np.median(dt))))
        raise RecordingError(f"{rec.source}: the sample rate is not uniform (step {dt[i]:.4g} s at t = {t[i]:.3f} s, "
                             f"median {np.median(dt):.4g} s); resample or split the recording at the gap")
    rate = 1.0 / np.median(dt)
    if rate < MIN_RATE_HZ * (1 - 1e-6):
        raise RecordingError(f"{rec.source}: sample rate {rate:.4g} Hz is below the {MIN_RATE_HZ:g} Hz the doctor "
                             f"needs (at 10 Hz it named effects that were not there)")
    if rate * FINE_DT > 1.0 + 1e-6:
        raise RecordingError(f"{rec.source}: sample rate {rate:.4g} Hz is above 1 kHz, the fine grid of the replays; "
                             f"average or decimate it to 1 kHz or a whole fraction of it (500, 200, 100 Hz, ...)")
    if abs(rate * FINE_DT * round(1.0 / (rate * FINE_DT)) - 1.0) > 1e-3:
        raise RecordingError(f"{rec.source}: sample rate {rate:.4g} Hz is not a whole fraction of 1 kHz "
                             f"(1000, 500, 200, 100, 50, 20 Hz, ...); resample it")
    if averaged is None:
        averaged = bool(rec.meta.get("daq_averaging", True))
    shift = 0.5 / rate if averaged else 0.0
    ts = t - shift
    joints, acts = robot.joint_names, robot.actuator_names
    q = rec.matrix("q", joints)
    p = np.column_stack([rec[f"p_{c}.{a}"] for a in acts for c in ("a", "b")])
    u = np.column_stack([rec[f"u_{c}.{a}"] for a in acts for c in ("a", "b")])
    lams = [discrepancy_lambda(ts, q[:, j]) for j in range(len(joints))]
    d = [smooth_derivatives(ts, q[:, j], order=2, lam=lam) for j, lam in enumerate(lams)]
    q_s = np.column_stack([x[0] for x in d])
    qd = np.column_stack([x[1] for x in d])
    qdd = np.column_stack([x[2] for x in d])
    light = [light_spline(ts, q[:, j]) for j in range(len(joints))]
    exp = Experiment(robot, rec, t, ts, q, q_s, qd, qdd, p, u, averaged,
                     q_light=np.column_stack([s(ts) for s in light]),
                     qd_light=np.column_stack([s.derivative(1)(ts) for s in light]), q_lam=np.array([lams]))
    exp.q_cutoff_hz = min(spline_cutoff_hz(lam, 1.0 / rate) for lam in lams)
    # pressures at the sample instants (window starts of the replays): a light smoothing
    # spline through the DAQ means, evaluated half a period later than they stand
    exp.p_at_t = np.column_stack([light_spline(ts, p[:, c])(t) for c in range(p.shape[1])])
    _fine_geometry(exp, light)
    return exp


def with_pressures(exp: Experiment, p: np.ndarray) -> Experiment:
    """A copy of ``exp`` whose measured pressures are ``p`` (N, C) [Pa], with the pressures at
    the sample times (``p_at_t``) made from them as :func:`prepare` makes them, per pooled
    recording."""
    p_at_t = np.empty_like(p)
    bounds = (0, *exp.breaks, p.shape[0])
    for a, b in zip(bounds[:-1], bounds[1:]):
        for c in range(p.shape[1]):
            p_at_t[a:b, c] = light_spline(exp.t_sensor[a:b], p[a:b, c])(exp.t[a:b])
    return dataclasses.replace(exp, p=p, p_at_t=p_at_t)


def light_spline(t, y, fraction: float = 0.5):
    """A smoothing spline leaving residuals at ``fraction`` of the noise level: it removes
    most of the noise but, unlike a spline at the full noise level, hardly attenuates fast
    motions (which would bias the chamber stiffness and so the fitted dead volumes)."""
    return smoothing_spline(t, y, lam=discrepancy_lambda(t, y, fraction * noise_sd(y)))


def _fine_geometry(exp: Experiment, light: list):
    """Actuator lengths on the 1 ms grid from lightly smoothed angles."""
    robot = exp.robot
    n_f = int(round((exp.t[-1] - exp.t[0]) / FINE_DT)) + 1
    fine_t = exp.t[0] + np.arange(n_f) * FINE_DT
    fine_q = np.column_stack([s(fine_t) for s in light])
    exp.fine_t, exp.fine_q = fine_t, fine_q
    exp.fine_length = actuator_lengths(robot, fine_q)


def with_true_lengths(exp: Experiment, offset_rad: np.ndarray, scale_error: np.ndarray) -> Experiment:
    """``exp`` with its actuator lengths on the 1 ms grid (what the pressure replays read of the
    motion) taken at the true angles of sensors that read q + offset + scale_error q
    (effects.angle_sensor_offset); the angles stay as read."""
    import dataclasses

    from pneumatics.effects.angle_sensor_offset import true_angle

    q = true_angle(exp.fine_q, np.asarray(offset_rad, float), np.asarray(scale_error, float))
    return dataclasses.replace(exp, fine_length=actuator_lengths(exp.robot, q))


def actuator_lengths(robot: Robot, q: np.ndarray) -> np.ndarray:
    """(F, n_act) actuator lengths at joint positions q (F, J), as MuJoCo computes them."""
    m = robot.model
    ids = robot.actuator_ids
    jt = int(mujoco.mjtTrn.mjTRN_JOINT)
    if all(int(m.actuator_trntype[i]) == jt for i in ids):  # fast path: L = gear * q
        out = np.empty((q.shape[0], ids.size))
        for k, i in enumerate(ids):
            jnt = m.actuator_trnid[i, 0]
            col = robot.joint_names.index(m.joint(jnt).name)
            out[:, k] = m.actuator_gear[i, 0] * q[:, col]
        return out
    d = mujoco.MjData(m)
    adr = robot.qpos_index
    out = np.empty((q.shape[0], ids.size))
    for f in range(q.shape[0]):
        d.qpos[adr] = q[f]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_tendon(m, d)
        mujoco.mj_transmission(m, d)
        out[f] = d.actuator_length[ids]
    return out


def split(rec: Recording, holdout_fraction: float = 0.3) -> tuple[Recording, Recording]:
    """(fit part, held-out part): the last ``holdout_fraction`` of the recording held out."""
    t_cut = rec.time[0] + (1 - holdout_fraction) * (rec.time[-1] - rec.time[0])
    return rec.slice(rec.time[0], t_cut), rec.slice(t_cut, rec.time[-1] + 1.0)


def pool(exps: list[Experiment]) -> Experiment:
    """Several prepared recordings as one experiment: each is shifted in time to follow the
    previous one by one sample period, so that every array stays on one uniform grid, and the
    joins are listed in ``breaks`` (replay windows and torque samples never straddle one).
    Smoothing and differentiation were done per recording, so no spline crosses a join."""
    if len(exps) == 1:
        return exps[0]
    rates = [e.rate_hz for e in exps]
    if max(rates) - min(rates) > 1e-6 * max(rates):
        raise RecordingError("recordings to pool must share one sample rate; got "
                             + ", ".join(f"{e.rec.source}: {r:.4g} Hz" for e, r in zip(exps, rates)))
    dt = 1.0 / rates[0]
    n_sub = exps[0].n_sub
    per_sample = ("q", "q_s", "qd", "qdd", "p", "u", "p_at_t", "fine_q", "fine_length", "q_light", "qd_light", "q_lam")
    parts = {k: [] for k in ("t", "clock", "t_sensor", *per_sample)}
    breaks, n, t_next = [], 0, exps[0].t[0]
    for k, e in enumerate(exps):
        shift = t_next - e.t[0]
        if k:
            breaks.append(n)
            # the 1 ms points inside the joining sample period: hold the next recording's start
            parts["fine_q"].append(np.repeat(e.fine_q[:1], n_sub - 1, axis=0))
            parts["fine_length"].append(np.repeat(e.fine_length[:1], n_sub - 1, axis=0))
        parts["t"].append(e.t + shift)
        parts["clock"].append(e.clock_at())
        parts["t_sensor"].append(e.t_sensor + shift)
        for key in per_sample:
            parts[key].append(getattr(e, key))
        n += e.t.size
        t_next = e.t[-1] + shift + dt
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    first = exps[0]
    out = Experiment(first.robot, first.rec, cat["t"], cat["t_sensor"], cat["q"], cat["q_s"], cat["qd"], cat["qdd"],
                     cat["p"], cat["u"], first.averaged, cat["p_at_t"],
                     cat["t"][0] + np.arange(cat["fine_q"].shape[0]) * FINE_DT, cat["fine_length"], cat["fine_q"],
                     tuple(breaks), min(e.q_cutoff_hz for e in exps), cat["clock"],
                     cat["q_light"], cat["qd_light"], cat["q_lam"])
    expected = int(round((out.t[-1] - out.t[0]) / FINE_DT)) + 1
    if out.fine_t.size != expected:  # each recording's grid must span whole milliseconds
        raise RecordingError(f"pooling: fine grid of {out.fine_t.size} points, expected {expected}")
    return out
