"""The closed loop of :func:`pneumatics.runner.run` for the built-in PID / PIDF / model-based
PIDF, compiled: whole control periods without Python.

In Python a control period costs about 60 us on top of the physics (DAQ means, noise, the
PIDF's dozen small numpy operations, the reference looked up twice, the recorded row), twice
arm2's ten physics steps.  Here each period is one pass of a compiled loop over rows:

    sensors    the DAQ mean over the period (or the instant values), plus white noise
               pre-drawn from the run's generator in the order the Python path draws it
    law        controllers.pid.PIDF.effort (eq. 13, derivative filter, integral clamp) and
               eq. 14/15, or controllers.model_based.ModelBasedPIDF (eqs. 16-17) with its
               feedforward table interpolated as numpy.interp does
    command    pneumatics.command_kernel.command_step (clip, hysteresis, valve areas)
    record     the row written into preallocated arrays
    physics    pneumatics.kernel.period_steps over the period; its last step's pressures
               wait for the next period's first mj_step1 (period_start), which computes the
               actuator lengths anyway, instead of a kinematics pass of their own

The readable reference is the Python path (pneumatics/runner.py with controllers/pid.py and
controllers/model_based.py): the same arithmetic in the same order, so the two recordings are
the same bit for bit (tests/test_compiled_control.py).  A controller gets this path only if it
is exactly one of those classes with a :class:`~controllers.reference.JointReference`;
subclasses and user controllers keep the Python path.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from pneumatics.command_kernel import OK, CLIPPED, command_step
from pneumatics.kernel import period_start, period_steps

from .model_based import ModelBasedPIDF, feedforward_table
from .pid import BAR, COMMAND_MAX_V, COMMAND_MIN_V, PIDF
from .reference import JointReference

PIDF_LAW, MODEL_BASED_LAW = 0, 1


@dataclass
class CompiledPIDF:
    """A PIDF-family controller as arrays for :func:`run_rows`, its state kept in ``state``
    (rows: integral, filtered derivative, last error; ``started[0]`` = 1 after the first row)."""

    controller: PIDF
    law: tuple
    state: np.ndarray
    started: np.ndarray

    def run_rows(self, k0: int, k1: int, run: tuple, record: tuple) -> tuple[int, int]:
        """Rows k0..k1-1 of a run (see :func:`run_rows`); returns (rows done, status)."""
        return run_rows(k0, k1, *run, self.law, self.state, self.started, *record)

    def finish(self):
        """Leave the controller in the state the Python path would (its integral, filter, last error)."""
        if self.started[0]:
            c = self.controller
            c._integral, c._deriv, c._last_err = (self.state[i].copy() for i in range(3))


def compile_controller(controller, n_joint: int) -> CompiledPIDF | None:
    """The compiled form of ``controller`` (on a robot of ``n_joint`` joints), or None where
    only the Python path can run it (another class, another reference, other shapes)."""
    kind = {PIDF: PIDF_LAW, ModelBasedPIDF: MODEL_BASED_LAW}.get(type(controller))
    if kind is None or type(controller.ref) is not JointReference:
        return None
    ref = controller.ref
    null = np.ascontiguousarray(controller.null_v, float)
    if ref.q.shape[1] != n_joint or null.shape != (2 * n_joint,):
        return None
    c = controller.cfg
    gains = c.as_vector(n_joint)  # kp, kd, ki, kf, each broadcast to (n_joint,)
    kp, kd, ki, kf = (np.ascontiguousarray(g) for g in gains)
    limit = c.integral_limit_v / np.maximum(ki, 1e-12)  # as PIDF.effort
    dt = 1.0 / c.rate_hz
    alpha = dt / (c.deriv_filter_s + dt)
    if kind == MODEL_BASED_LAW:
        if controller._table is None:
            controller._table = feedforward_table(controller.ref, controller.model)
        ff_time, ff_pa = (np.ascontiguousarray(a, float) for a in controller._table)
        if ff_pa.ndim != 2 or ff_pa.shape[1] != n_joint:
            return None
        lead = float(controller.lead_s)
    else:
        ff_time, ff_pa, lead = np.zeros(1), np.zeros((1, n_joint)), 0.0
    law = (kind, kp, kd, ki, kf, limit, dt, alpha, null, np.ascontiguousarray(ref.time),
           np.ascontiguousarray(ref.q), ff_time, ff_pa, lead)
    return CompiledPIDF(controller, law, np.zeros((3, n_joint)), np.zeros(1, np.int64))


@numba.njit(cache=True, error_model="numpy", inline="always")
def clip(x, lo, hi):
    """numpy.clip of one float, with its semantics: NaN passes, min(max(x, lo), hi) as
    ``x > lo ? x : lo`` then ``< hi``."""
    if not np.isnan(x) and not x > lo:
        x = lo
    if not np.isnan(x) and not x < hi:
        x = hi
    return x


@numba.njit(cache=True, error_model="numpy")
def reference_at(t, time, q, out):
    """controllers.reference.JointReference.reference(t) into ``out``, the same arithmetic."""
    last = time.size - 1
    if t <= time[0]:
        out[:] = q[0]
        return
    if t >= time[last]:
        out[:] = q[last]
        return
    i = np.searchsorted(time, t, side="right") - 1
    for j in range(out.size):
        slope = (q[i + 1, j] - q[i, j]) / (time[i + 1] - time[i])
        out[j] = slope * (t - time[i]) + q[i, j]


@numba.njit(cache=True, error_model="numpy")
def interp_columns(x, xp, fp, out):
    """``out[j] = numpy.interp(x, xp, fp[:, j])`` with numpy's own arithmetic (its C
    arr_interp: held ends, an exact sample returned as is, slope * (x - xp[j]) + fp[j])."""
    last = xp.size - 1
    if x > xp[last] or x == xp[last]:
        out[:] = fp[last]
        return
    if x < xp[0]:
        out[:] = fp[0]
        return
    i = np.searchsorted(xp, x, side="right") - 1
    if xp[i] == x:
        out[:] = fp[i]
        return
    for j in range(out.size):
        slope = (fp[i + 1, j] - fp[i, j]) / (xp[i + 1] - xp[i])
        y = slope * (x - xp[i]) + fp[i, j]
        if np.isnan(y):  # numpy's fallbacks for an infinite slope
            y = slope * (x - xp[i + 1]) + fp[i + 1, j]
            if np.isnan(y) and fp[i, j] == fp[i + 1, j]:
                y = fp[i, j]
        out[j] = y


@numba.njit(cache=True, error_model="numpy")
def pidf_command(t, q_seen, p_seen, law, state, started, ref, ff, u):
    """One call of PIDF / ModelBasedPIDF at time t: ``ref`` (n_joint,) gets the reference at t,
    ``u`` (n_ch,) the valve commands [V]; the PID state advances as in PIDF.effort."""
    kind, kp, kd, ki, kf, limit, dt, alpha, null, ref_time, ref_q, ff_time, ff_pa, lead = law
    reference_at(t, ref_time, ref_q, ref)
    integral, deriv, last_err = state[0], state[1], state[2]
    if started[0] == 0:
        started[0] = 1
        for j in range(ref.size):
            integral[j] = 0.0
            deriv[j] = 0.0
            last_err[j] = ref[j] - q_seen[j]
    if kind == MODEL_BASED_LAW:
        interp_columns(t + lead, ff_time, ff_pa, ff)
    for j in range(ref.size):
        err = ref[j] - q_seen[j]
        raw = (err - last_err[j]) / dt
        deriv[j] += alpha * (raw - deriv[j])
        last_err[j] = err
        integral[j] += err * dt
        integral[j] = clip(integral[j], -limit[j], limit[j])
        e = kp[j] * err + kd[j] * deriv[j] + ki[j] * integral[j]
        d = p_seen[2 * j] - p_seen[2 * j + 1]
        if kind == MODEL_BASED_LAW:  # eq. 17: u = null +- (e + k_F (d^ - d))
            v = e + kf[j] * ((ff[j] - d) / BAR)
        else:  # eq. 15: u = null +- (e - k_F d)
            v = e - kf[j] * (d / BAR)
        u[2 * j] = clip(null[2 * j] + v, COMMAND_MIN_V, COMMAND_MAX_V)
        u[2 * j + 1] = clip(null[2 * j + 1] - v, COMMAND_MIN_V, COMMAND_MAX_V)


@numba.njit(cache=True, error_model="numpy")
def run_rows(k0, k1, n_rows, n_sub, t0, rate_hz, average, noisy, noise, angle_sd, pressure_sd, sensors,
             step_args, command_args, law, state, started, rec_t, rec_q, rec_qd, rec_p, rec_u, rec_force,
             rec_ref):
    """Rows k0..k1-1 of pneumatics.runner.run, each: sensors, law, command, record, and (but the
    last row of the run) the period's physics steps.

    ``noisy``: add ``noise`` (k1 - k0, n_joint + n_ch), standard normals of these rows (the
    joints' before the chambers'), times ``angle_sd`` [rad] and ``pressure_sd`` [Pa];
    ``sensors``: (qadr, dadr, q_offset, p_offset, p_drift, p_drift_tau, q_gain) of Simulation.sensor_maps;
    ``step_args``: Simulation.physics_step_args; ``command_args``: Simulation.command_step_args.
    Returns (rows done, status): k1 and OK or CLIPPED, or the row whose commands
    command_step refused (NOT_FINITE, UNIT_SLIP; the commands left in ``rec_u`` of that row)
    with the simulation unchanged by them.
    """
    qadr, dadr, q_off, p_off, p_drift, p_tau, q_gain = sensors
    pressure, act, glob, qpos, qvel, sums = (step_args[3], step_args[8], step_args[10], step_args[11],
                                             step_args[12], step_args[13])
    n_j, n_ch, nq = qadr.size, pressure.size, qpos.size
    q_seen, qd, p_seen = np.empty(n_j), np.empty(n_j), np.empty(n_ch)
    ref, ff, u = np.empty(n_j), np.empty(n_j), np.empty(n_ch)
    status = OK
    pending = False  # the last period's pressures wait for this period's mj_step1 (period_start)
    drifting = np.any(p_drift != 0.0)
    for k in range(k0, k1):
        if pending:
            period_start(*step_args)
        t = t0 + k / rate_hz
        if average and k > 0:  # Simulation.take_mean: the sums hold this period's n_sub steps
            for j in range(n_j):
                q_seen[j] = q_gain[j] * (sums[n_ch + qadr[j]] / n_sub) + q_off[j]
                qd[j] = q_gain[j] * (sums[n_ch + nq + dadr[j]] / n_sub)
            for i in range(n_ch):
                p_seen[i] = sums[i] / n_sub + p_off[i]
            sums[:] = 0.0
        else:  # Simulation.observe
            for j in range(n_j):
                q_seen[j] = q_gain[j] * qpos[qadr[j]] + q_off[j]
                qd[j] = q_gain[j] * qvel[dadr[j]]
            for i in range(n_ch):
                p_seen[i] = pressure[i] + p_off[i]
        if drifting:  # a warming-up pressure sensor (effects.pressure_sensor_offset.offset_at)
            for i in range(n_ch):
                if p_tau[i] > 0.0:
                    p_seen[i] = p_seen[i] + p_drift[i] * -np.expm1(-t / p_tau[i])
        if noisy:  # runner.add_noise: rng.normal(0, sd) is 0 + sd * z
            for j in range(n_j):
                q_seen[j] = q_seen[j] + (0.0 + angle_sd * noise[k - k0, j])
            for i in range(n_ch):
                p_seen[i] = p_seen[i] + (0.0 + pressure_sd * noise[k - k0, n_j + i])
        pidf_command(t, q_seen, p_seen, law, state, started, ref, ff, u)
        s = command_step(u, *command_args)
        if s != OK and s != CLIPPED:
            rec_u[k] = u  # for the caller's error message
            return k, s
        if s == CLIPPED:
            status = CLIPPED
        rec_t[k] = t
        rec_q[k] = q_seen
        rec_qd[k] = qd
        rec_p[k] = p_seen
        rec_u[k] = command_args[3]
        room = glob[9]
        for j in range(act.shape[0]):  # chamber.actuator_force of the true pressures
            aa, ab = act[j, 0], act[j, 1]
            rec_force[k, j] = aa * pressure[2 * j] - ab * pressure[2 * j + 1] - (aa - ab) * room
        rec_ref[k] = ref
        if k < n_rows - 1:
            # synchronous at the end of the run and of these rows (the caller's view), else the
            # next row's mj_step1 finishes the period
            catch_up = k + 1 == n_rows - 1 or k + 1 == k1
            period_steps(n_sub, pending, catch_up, *step_args)
            pending = not catch_up
    return k1, status
