"""Run a controller against a simulation at the control rate and record what the DAQ saw.

Timing follows the DAQ of paper 002 §II: at each control instant t_k the sensors report their
mean over the period ending at t_k (plus white noise); the controller's commands are held
until t_{k+1}.  A controller is any object with ``reset()`` and
``__call__(time_s, observation) -> (n_ch,) valve commands [V]`` (DESIGN.md); one that also
has ``reference(time_s) -> (n_joint,)`` gets ``ref.<joint>`` columns recorded.

The loop below is the readable reference.  A built-in controller may also offer
``compiled_law(n_joint)``, returning None or an object with ``run_rows(k0, k1, run, record)``
and ``finish()`` (:class:`controllers.compiled_loop.CompiledPIDF`) that runs whole control
periods of this very loop in compiled code, bit for bit the same recording; :func:`run` takes
it whenever the simulation allows (:func:`compiled_law`) unless ``compiled=False``.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .errors import PneumasimError
from .recording import Recording
from .command_kernel import CLIPPED
from .sim import Observation, Simulation


class OpenLoop:
    """Commands as a function of time: ``fn(time_s) -> (n_ch,) volts``."""

    def __init__(self, fn: Callable[[float], np.ndarray]):
        self.fn = fn

    def reset(self):
        pass

    def __call__(self, time_s: float, observation: Observation) -> np.ndarray:
        return self.fn(time_s)


def add_noise(obs: Observation, rng: np.random.Generator, angle_sd: float, pressure_sd: float) -> Observation:
    return Observation(obs.time, obs.q + rng.normal(0.0, angle_sd, obs.q.shape), obs.qd,
                       obs.p + rng.normal(0.0, pressure_sd, obs.p.shape))


def run(sim: Simulation, controller, duration_s: float, *, rate_hz: float | None = None,
        noise: bool = True, seed: int = 0, average: bool | None = None,
        record_velocity: bool = False, record_force: bool = False, logger=None,
        progress=None, compiled: bool = True) -> Recording:
    """Run ``controller`` on ``sim`` from its current state for ``duration_s``.

    Args:
      rate_hz: control and recording rate (default: the model's [control] rate_hz).
      noise: add the model's [sensors] white noise to what the controller sees and records.
      average: DAQ averaging over each control period (default: the model's [sensors] average).
      record_velocity / record_force: add ``qd.<joint>`` / ``force.<actuator>`` columns.
      logger: optional :class:`workflow.rerun_log.RerunLogger`, one frame per control step.
      progress: optional callable(fraction) for progress display.
      compiled: take a built-in controller's compiled path when it can run (False: always the
        Python loop, e.g. to test the two against each other).
    Returns:
      The recording, one row per control step, N = round(duration_s * rate_hz) + 1 rows.
    """
    robot = sim.robot
    cfg = robot.fluid
    rate_hz = rate_hz or cfg.control.rate_hz
    average = cfg.sensors.average if average is None else average
    n_sub = int(round(1.0 / (rate_hz * sim.dt)))
    if n_sub < 1 or abs(n_sub * sim.dt * rate_hz - 1.0) > 1e-6:
        raise PneumasimError(f"control rate {rate_hz:g} Hz is not a whole fraction of the physics rate {1 / sim.dt:g} Hz")
    n_rows = int(round(duration_s * rate_hz)) + 1
    rng = np.random.default_rng(seed)
    angle_sd = cfg.sensors.angle_noise_rad if noise else 0.0
    pressure_sd = cfg.sensors.pressure_noise_pa if noise else 0.0
    joints, acts = robot.joint_names, robot.actuator_names
    n_j, n_ch = len(joints), 2 * len(acts)
    t = np.empty(n_rows)
    q = np.empty((n_rows, n_j))
    qd = np.empty((n_rows, n_j))
    p = np.empty((n_rows, n_ch))
    u = np.empty((n_rows, n_ch))
    force = np.empty((n_rows, len(acts)))
    has_ref = hasattr(controller, "reference")
    ref = np.empty((n_rows, n_j)) if has_ref else None
    controller.reset()
    sim.take_mean()  # discard sums from before the run
    t0 = sim.time
    law = compiled_law(sim, controller, len(joints), logger) if compiled else None
    if law is not None:
        _run_compiled(sim, law, n_rows, n_sub, t0, rate_hz, average, noise, rng, angle_sd, pressure_sd,
                      (t, q, qd, p, u, force, ref if has_ref else np.empty((n_rows, n_j))), progress)
    for k in range(n_rows if law is None else 0):
        obs = sim.take_mean() if (average and k > 0) else sim.observe()
        obs = Observation(t0 + k / rate_hz, obs.q, obs.qd, obs.p)
        seen = add_noise(obs, rng, angle_sd, pressure_sd) if noise else obs
        cmd = controller(seen.time, seen)
        sim.set_command(cmd)
        t[k], q[k], qd[k], p[k], u[k] = seen.time, seen.q, obs.qd, seen.p, sim.command
        force[k] = sim.forces()
        if has_ref:
            ref[k] = controller.reference(seen.time)
        if logger is not None:
            logger.log_frame(sim)
        if k < n_rows - 1:
            sim.step(n_sub)
        if progress is not None and k % 100 == 0:
            progress(k / n_rows)
    return _recording(sim, rate_hz, noise, average, seed, t, q, qd if record_velocity else None, p, u,
                      force if record_force else None, ref)


def _recording(sim, rate_hz, noise, average, seed, t, q, qd, p, u, force, ref) -> Recording:
    """The run's recording from its row arrays (qd, force, ref: None where not recorded)."""
    robot = sim.robot
    joints, acts = robot.joint_names, robot.actuator_names
    cols: dict[str, np.ndarray] = {}
    for i, j in enumerate(joints):
        cols[f"q.{j}"] = q[:, i]
    if qd is not None:
        for i, j in enumerate(joints):
            cols[f"qd.{j}"] = qd[:, i]
    for i, a in enumerate(acts):
        cols[f"p_a.{a}"], cols[f"p_b.{a}"] = p[:, 2 * i], p[:, 2 * i + 1]
    for i, a in enumerate(acts):
        cols[f"u_a.{a}"], cols[f"u_b.{a}"] = u[:, 2 * i], u[:, 2 * i + 1]
    if force is not None:
        for i, a in enumerate(acts):
            cols[f"force.{a}"] = force[:, i]
    if ref is not None:
        for i, j in enumerate(joints):
            cols[f"ref.{j}"] = ref[:, i]
    meta = {"model": robot.name, "rate_hz": rate_hz, "physics_dt_s": sim.dt, "noise": noise,
            "daq_averaging": average, "seed": seed, "generator": "pneumasim",
            "timing": "row k sensors = mean over the control period ending at time[k] (+ noise); "
                      "row k commands held over [time[k], time[k+1])"}
    return Recording(t, cols, meta, f"<{robot.name} run>")


#: rows per compiled call: progress is reported between calls; the noise of one call is drawn at once
COMPILED_ROWS = 100


def compiled_law(sim: Simulation, controller, n_joint: int, logger=None):
    """``controller.compiled_law(n_joint)`` where this simulation can run it compiled, else None.

    Not for a subclass of Simulation (its own forces, observe or step would be bypassed), a
    logger (it looks at every period), the numpy kernel, heat transfer, valve lag or line delay."""
    offer = getattr(controller, "compiled_law", None)
    if (offer is None or logger is not None or type(sim) is not Simulation or not sim.compiled_steps
            or not sim.valve_dynamics_free):
        return None
    return offer(n_joint)


def _run_compiled(sim, law, n_rows, n_sub, t0, rate_hz, average, noise, rng, angle_sd, pressure_sd,
                  record, progress):
    """The loop of :func:`run` in compiled chunks of COMPILED_ROWS rows, filling ``record``
    (t, q, qd, p, u, force, ref).  The noise is drawn per chunk from ``rng``, in the order the
    Python loop draws it (per row: the joints', then the chambers'), so the stream is the same."""
    n_j, n_ch = record[1].shape[1], record[3].shape[1]
    run_args = [n_rows, n_sub, t0, rate_hz, average, noise, None, angle_sd, pressure_sd, sim.sensor_maps(),
                sim.physics_step_args(), sim.command_step_args()]
    no_noise = np.zeros((0, n_j + n_ch))
    for k0 in range(0, n_rows, COMPILED_ROWS):
        k1 = min(k0 + COMPILED_ROWS, n_rows)
        run_args[6] = rng.standard_normal((k1 - k0, n_j + n_ch)) if noise else no_noise
        done, status = law.run_rows(k0, k1, tuple(run_args), record)
        # the steps summed since the last DAQ mean, as Simulation.step / take_mean count them
        if average:
            sim.steps_summed = n_sub if done == k1 < n_rows else 0
        else:
            sim.steps_summed = min(done, n_rows - 1) * n_sub
        if status == CLIPPED:
            sim.warn_clipped(record[4][done - 1])
        if done < k1:  # commands the valves refuse (left in the row): the numpy path names the fault
            law.finish()
            sim.set_command(record[4][done])
        if progress is not None:
            progress(k0 / n_rows)
    law.finish()
