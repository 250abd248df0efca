"""Run a controller against a simulation at the control rate and record what the DAQ saw.

Timing follows the DAQ of paper 002 §II: at each control instant t_k the sensors report their
mean over the period ending at t_k (plus white noise); the controller's commands are held
until t_{k+1}.  A controller is any object with ``reset()`` and
``__call__(time_s, observation) -> (n_ch,) valve commands [V]`` (DESIGN.md); one that also
has ``reference(time_s) -> (n_joint,)`` gets ``ref.<joint>`` columns recorded.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .errors import PneumasimError
from .recording import Recording
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
        progress=None) -> Recording:
    """Run ``controller`` on ``sim`` from its current state for ``duration_s``.

    Args:
      rate_hz: control and recording rate (default: the model's [control] rate_hz).
      noise: add the model's [sensors] white noise to what the controller sees and records.
      average: DAQ averaging over each control period (default: the model's [sensors] average).
      record_velocity / record_force: add ``qd.<joint>`` / ``force.<actuator>`` columns.
      logger: optional :class:`workflow.rerun_log.RerunLogger`, one frame per control step.
      progress: optional callable(fraction) for progress display.
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
    for k in range(n_rows):
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
    cols: dict[str, np.ndarray] = {}
    for i, j in enumerate(joints):
        cols[f"q.{j}"] = q[:, i]
    if record_velocity:
        for i, j in enumerate(joints):
            cols[f"qd.{j}"] = qd[:, i]
    for i, a in enumerate(acts):
        cols[f"p_a.{a}"], cols[f"p_b.{a}"] = p[:, 2 * i], p[:, 2 * i + 1]
    for i, a in enumerate(acts):
        cols[f"u_a.{a}"], cols[f"u_b.{a}"] = u[:, 2 * i], u[:, 2 * i + 1]
    if record_force:
        for i, a in enumerate(acts):
            cols[f"force.{a}"] = force[:, i]
    if has_ref:
        for i, j in enumerate(joints):
            cols[f"ref.{j}"] = ref[:, i]
    meta = {"model": robot.name, "rate_hz": rate_hz, "physics_dt_s": sim.dt, "noise": noise,
            "daq_averaging": average, "seed": seed, "generator": "pneumasim",
            "timing": "row k sensors = mean over the control period ending at time[k] (+ noise); "
                      "row k commands held over [time[k], time[k+1])"}
    return Recording(t, cols, meta, f"<{robot.name} run>")
