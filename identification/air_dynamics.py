"""Measured against model-predicted chamber pressure rates on data the calibration never saw
(paper 002 §IV-B.3 and Fig. 4A: "The resulting model was able to fit the experimental data
quite well").

The model is the paper's air dynamics, eq. 9 with the mass flows of eqs. 6-8::

    dp/dt = n / V (R T (a_c(u) f(P_c, p) - a_r(u) f(p, P_r)) - p dV/dt)

with the orifice areas a_c(u), a_r(u) of the static-volume calibration (eqs. 10-12,
:mod:`identification.orifice`), linearly interpolated between its commands, and the chamber
volume V and its rate from the measured joint motion (chamber geometry of the model file).

The held-out record is the robot moving under feedback control.  Its pressures are sampled at
1 kHz (raw samples, each with the sensor noise of one sample: sigma_100Hz * sqrt(10), as the
calibration records) while the controller updates the valves at 100 Hz.  The commands hold
over each control period, so dp/dt is smooth inside a period and jumps at its edges: the
measured rate is the slope of a quadratic least-squares fit to each period's samples, at the
period's middle, where the prediction is evaluated too.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from pneumatics.chamber import chamber_geometry, pressure_rate
from pneumatics.errors import PneumasimError
from pneumatics.sim import CommandClippedWarning, Simulation

from .orifice import OrificeCalibration


@dataclass
class HeldOutRecord:
    """Raw samples: time (T,) s; pressure (T, n_ch) Pa; length (T, n_act) actuator lengths
    [m or rad] from the joint encoders; command (T, n_ch) V held since the last control tick;
    ``period_samples`` samples per control period (ticks at samples 0, k, 2k, ...)."""

    time: np.ndarray
    pressure: np.ndarray
    length: np.ndarray
    command: np.ndarray
    period_samples: int


def record_held_out(sim: Simulation, controller, duration_s: float, *, control_hz: float = 100.0,
                    seed: int = 0) -> HeldOutRecord:
    """Run ``controller(time, observation) -> (n_ch,) V`` at ``control_hz`` on ``sim`` from its
    state and sample the pressures every physics step with one sample's sensor noise."""
    k = round(1.0 / (control_hz * sim.dt))
    if k < 3:
        raise PneumasimError(f"held-out record: {control_hz:g} Hz control leaves {k} samples per period; need 3")
    n = round(duration_s / sim.dt) // k * k
    # [sensors] pressure_noise_pa is the noise of a 100 Hz mean: one raw sample has sqrt(N) more
    sd = sim.robot.fluid.sensors.pressure_noise_pa * np.sqrt(1.0 / (sim.dt * 100.0))
    rng = np.random.default_rng(seed)
    ids = sim.robot.actuator_ids
    t, p, length, u = (np.empty((n,) + s) for s in ((), sim.pressure.shape, ids.shape, sim.pressure.shape))
    controller.reset()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CommandClippedWarning)
        for i in range(n):
            if i % k == 0:
                obs = sim.observe()
                sim.set_command(controller(obs.time, obs))
            t[i], p[i], length[i], u[i] = sim.time, sim.pressure, sim.data.actuator_length[ids], sim.command
            sim.step(1)
    return HeldOutRecord(t, p + rng.normal(0.0, sd, p.shape), length, u, k)


@dataclass
class PeriodRates:
    """Per control period, at its middle: time (N,), pressure (N, n_ch), measured dp/dt
    (N, n_ch), length (N, n_act), length rate (N, n_act), command (N, n_ch)."""

    time: np.ndarray
    pressure: np.ndarray
    measured_rate: np.ndarray
    length: np.ndarray
    length_rate: np.ndarray
    command: np.ndarray


def period_rates(rec: HeldOutRecord) -> PeriodRates:
    """Quadratic least-squares fit to each control period's samples (value and slope at its middle)."""
    k = rec.period_samples
    n = rec.time.size // k
    tt = rec.time[: n * k].reshape(n, k)
    mid = tt.mean(axis=1)
    x = tt[0] - tt[0].mean()  # the same sample times in every period
    basis = np.column_stack([np.ones(k), x, x * x])
    proj = np.linalg.pinv(basis)  # (3, k): value, slope, curvature at the middle

    def fit(a):
        coef = np.einsum("ck,nk...->nc...", proj, a[: n * k].reshape((n, k) + a.shape[1:]))
        return coef[:, 0], coef[:, 1]

    p, dp = fit(rec.pressure)
    length, dlength = fit(rec.length)
    return PeriodRates(mid, p, dp, length, dlength, rec.command[: n * k: k])


def predicted_rates(cal: OrificeCalibration, tables, rates: PeriodRates, dt: float = 1e-3) -> np.ndarray:
    """(N, n_ch) dp/dt [Pa/s] of eq. 9 with the calibrated areas at each period's command."""
    a_c, a_r = cal.areas()
    a_s = np.column_stack([np.interp(rates.command[:, i], cal.commands_v, a_c[i]) for i in range(a_c.shape[0])])
    a_e = np.column_stack([np.interp(rates.command[:, i], cal.commands_v, a_r[i]) for i in range(a_r.shape[0])])
    out = np.empty_like(rates.measured_rate)
    for j in range(out.shape[0]):
        half = 0.5 * rates.length_rate[j] * dt
        volume, volume_rate = chamber_geometry(tables, rates.length[j] - half, rates.length[j] + half, dt)
        out[j] = pressure_rate(rates.pressure[j], volume, volume_rate, a_s[j], a_e[j], tables.gas,
                               tables.supply_pa, tables.room_pa)[0]
    return out


def r_squared(measured: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """(n_ch,) 1 - SS_res / SS_tot per column."""
    res = np.sum((measured - predicted) ** 2, axis=0)
    tot = np.sum((measured - measured.mean(axis=0)) ** 2, axis=0)
    return 1.0 - res / tot
