"""Open-loop runs of a hydraulic joint that log a :class:`~pneumatics.recording.Recording`.

The current command is updated at ``control_rate_hz`` (zero-order hold) and the sensors are
sampled at ``rate_hz`` (paper 001 §4: 10 ms), optionally with white noise of the sizes in
``[sensors]`` of fluid.toml.  Columns (DESIGN.md names; extras are kept by readers)::

    i.elbow                 current command [A]
    q.elbow, q.shaft        vane (motor-side encoder) angle and shaft twist [rad]
    qd.elbow                vane velocity [rad/s] (true, not noised)
    p_a.elbow, p_b.elbow    chamber pressures [Pa abs]
    tau.elbow               joint torque sensor, k_s (theta_v - theta_l) [N m]
    load_angle, load_velocity   theta_l [rad], [rad/s]
    p_supply, p_return      pressures at the valve [Pa abs]
    i_hys, x_v              virtual current after hysteresis [A], valve tip position [m]
    tap_volume_a, tap_volume_b  oil delivered into manifold taps [m^3]
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..recording import Recording
from .sim import HydraulicJointSim

NOISY = {"q.elbow": "angle", "q.shaft": "angle", "load_angle": "angle", "p_a.elbow": "pressure",
         "p_b.elbow": "pressure", "p_supply": "pressure", "p_return": "pressure", "tau.elbow": "torque"}


def _sample(sim: HydraulicJointSim) -> list[float]:
    p = sim.circuit.y
    return [sim.current_a, sim.vane_angle, float(sim.data.qpos[sim._shaft_q]),
            float(sim.data.qvel[sim._vane]), float(p[4]), float(p[5]), sim.joint_torque_nm,
            sim.load_angle, sim.load_velocity, float(p[0]), float(p[2]), sim.i_hys_a, sim.tip.x,
            float(sim.circuit.tap_volume_m3[0]), float(sim.circuit.tap_volume_m3[1])]


COLUMNS = ["i.elbow", "q.elbow", "q.shaft", "qd.elbow", "p_a.elbow", "p_b.elbow", "tau.elbow",
           "load_angle", "load_velocity", "p_supply", "p_return", "i_hys", "x_v",
           "tap_volume_a", "tap_volume_b"]


def run_current(sim: HydraulicJointSim, current: Callable[[float], float], duration_s: float, *,
                rate_hz: float | None = None, noise: bool = False,
                rng: np.random.Generator | None = None, name: str = "run") -> Recording:
    """Drive the valve with ``current(t)`` [A] for ``duration_s`` from the sim's present state.

    Returns a Recording with one row per ``1/rate_hz`` (the first row is the initial state);
    ``noise`` adds the white sensor noise of ``cfg.sensors`` (needs ``rng`` or uses seed 0).
    """
    s = sim.cfg.sensors
    rate_hz = rate_hz or s.rate_hz
    per_control = max(1, round(1.0 / (s.control_rate_hz * sim.dt)))
    per_sample = max(1, round(1.0 / (rate_hz * sim.dt * per_control)))
    n_samples = round(duration_s * rate_hz)
    t0 = sim.time
    rows, times = [_sample(sim)], [t0]
    for _ in range(n_samples):
        for _ in range(per_sample):
            sim.set_current(current(sim.time))
            sim.step(per_control)
        rows.append(_sample(sim))
        times.append(sim.time)
    data = np.array(rows)
    columns = {c: data[:, j] for j, c in enumerate(COLUMNS)}
    if noise:
        rng = rng or np.random.default_rng(0)
        sd = {"angle": s.angle_noise_rad, "pressure": s.pressure_noise_pa, "torque": s.torque_noise_nm}
        for col, kind in NOISY.items():
            columns[col] = columns[col] + rng.normal(0.0, sd[kind], len(times))
    meta = {"model": "sarcos_elbow", "rate_hz": rate_hz, "timestep_s": sim.dt, "noise": bool(noise),
            "name": name}
    return Recording(np.array(times), columns, meta, source=name)


#: what a real elbow's sensors give (DESIGN.md names), the columns of :func:`run_measured`
MEASURED = ["i.elbow", "q.elbow", "p_a.elbow", "p_b.elbow", "tau.elbow"]


def run_measured(sim: HydraulicJointSim, current: Callable[[float], float], duration_s: float, *,
                 rate_hz: float = 1000.0, noise: bool = True, rng: np.random.Generator | None = None,
                 name: str = "run") -> Recording:
    """A recording as the real elbow's sensors give it (what ``pneumasim doctor --model
    sarcos_elbow`` reads): the columns :data:`MEASURED` only, the valve current ``i.elbow`` of
    each row being the command applied *from* that row's time until the next row (zero-order
    hold, as a controller logs it), sampled at ``rate_hz`` (a multiple of the control rate's
    period), with the white sensor noise of ``[sensors]`` when ``noise``.

    ``current(t)`` may read ``sim`` (a closed-loop controller): it is called once per
    control period with the state at ``t``."""
    s = sim.cfg.sensors
    per_control = max(1, round(1.0 / (s.control_rate_hz * sim.dt)))
    per_sample = max(1, round(1.0 / (rate_hz * sim.dt * per_control)))
    n = round(duration_s * rate_hz)
    times, cmd, q, pa, pb, tau = [], [], [], [], [], []
    for _ in range(n + 1):
        times.append(sim.time)
        q.append(sim.vane_angle)
        pa.append(float(sim.circuit.y[4]))
        pb.append(float(sim.circuit.y[5]))
        tau.append(sim.joint_torque_nm)
        for k in range(per_sample):
            sim.set_current(current(sim.time))
            if k == 0:
                cmd.append(sim.current_a)
            sim.step(per_control)
    columns = {"i.elbow": np.array(cmd), "q.elbow": np.array(q), "p_a.elbow": np.array(pa),
               "p_b.elbow": np.array(pb), "tau.elbow": np.array(tau)}
    if noise:
        rng = rng or np.random.default_rng(0)
        for col, kind in NOISY.items():
            if col in columns:
                sd = {"angle": s.angle_noise_rad, "pressure": s.pressure_noise_pa, "torque": s.torque_noise_nm}[kind]
                columns[col] = columns[col] + rng.normal(0.0, sd, len(times))
    meta = {"model": "sarcos_elbow", "rate_hz": rate_hz, "noise": bool(noise), "name": name,
            "daq_averaging": False,  # sensors sampled at each row's time, not averaged over the period
            "braced": sim.braced}
    return Recording(np.array(times), columns, meta, source=name)
