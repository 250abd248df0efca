"""Paper 002 §IV-B.3, Fig. 4A: measured and model-predicted pressure rates dp/dt of the two
chambers of cylinder 1, on data the calibration did not see.

1. Calibration (eqs. 10-12): the orifice areas of every valve from static-volume transients,
   joints braced (:func:`identification.orifice.calibrate_robot`).
2. Held-out data: arm2 tracking a hand-moved reference under PIDF control at 100 Hz, pressures
   sampled at 1 kHz with sensor noise (:func:`identification.air_dynamics.record_held_out`).
3. Measured dp/dt: slope of a quadratic fit over each control period; predicted dp/dt: eq. 9
   with the calibrated areas at the period's command and the volumes from the measured joint
   motion (:func:`identification.air_dynamics.predicted_rates`).

``r2_pdot_min`` is the worst chamber's R^2 of predicted against measured dp/dt (all four
chambers); ``r2_pdot_<actuator>_<a|b>`` each chamber's.  The measured rate carries the sensor
noise (about 1e5 Pa/s per period at 300 Pa per 100 Hz mean): ``noise_floor_r2_<...>`` is the
R^2 that noise alone would leave, for scale.
"""
from __future__ import annotations

import numpy as np

from controllers.pid import ARM2_PIDF
from identification.air_dynamics import period_rates, predicted_rates, r_squared, record_held_out
from identification.orifice import DEFAULT_COMMANDS_V, calibrate_robot
from pneumatics.sim import Simulation

from ._arm2_control import START_PRESSURE_PA, arm2, references
from ._humanoid import FAST_COMMANDS_V
from .common import main, plt

SUMMARY = "Fig. 4A: measured vs predicted dp/dt of arm2's chambers on held-out tracking data"


def run(ctx):
    robot = arm2()
    cal = calibrate_robot(robot, FAST_COMMANDS_V if ctx.fast else DEFAULT_COMMANDS_V, seed=1,
                          duration_scale=0.4 if ctx.fast else 1.0)
    duration = 8.0 if ctx.fast else 30.0
    ref = references(robot, "normal", duration, 1)[0]
    sim = Simulation(robot)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=START_PRESSURE_PA)
    rec = record_held_out(sim, ARM2_PIDF.build(ref, robot.tables.valve[:, 0]), duration, seed=11)
    rates = period_rates(rec)
    pred = predicted_rates(cal, robot.tables, rates, sim.dt)
    r2 = r_squared(rates.measured_rate, pred)
    # noise floor: the slope's standard error of a quadratic fit to k samples of sd sigma
    k = rec.period_samples
    x = (np.arange(k) - (k - 1) / 2) * sim.dt
    sigma = robot.fluid.sensors.pressure_noise_pa * np.sqrt(1.0 / (sim.dt * 100.0))
    slope_se = sigma / np.sqrt(np.sum(x * x))
    metrics = {"r2_pdot_min": float(r2.min()), "held_out_seconds": duration,
               "slope_noise_pa_s": float(slope_se), "n_periods": int(rates.time.size)}
    for i, (act, ch) in enumerate(robot.chamber_names):
        metrics[f"r2_pdot_{act}_{ch}"] = float(r2[i])
        metrics[f"noise_floor_r2_{act}_{ch}"] = float(1 - slope_se ** 2 / rates.measured_rate[:, i].var())
        metrics[f"rms_pdot_{act}_{ch}_pa_s"] = float(np.sqrt(np.mean(rates.measured_rate[:, i] ** 2)))
    _plot(ctx, robot, rates, pred, r2)
    return metrics


def _plot(ctx, robot, rates, pred, r2):
    fig, axes = plt.subplots(2, 2, figsize=(12, 6.5), gridspec_kw={"width_ratios": [2.4, 1]})
    window = (rates.time >= rates.time[0] + 2.0) & (rates.time <= rates.time[0] + 5.0)
    act = robot.actuator_names[0]
    for row in range(2):
        ax = axes[row, 0]
        ax.plot(rates.time[window], rates.measured_rate[window, row] / 1e5, "C0-", lw=1.0, label="measured")
        ax.plot(rates.time[window], pred[window, row] / 1e5, "C3-", lw=1.0, label="predicted (eq. 9)")
        ax.set_ylabel(f"{act} chamber {'ab'[row]}: dp/dt [bar/s]")
        ax.set_title(f"cylinder 1 ({act}), chamber {'ab'[row]}: R² = {r2[row]:.3f}", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    axes[1, 0].set_xlabel("time [s]")
    for i, (a, ch) in enumerate(robot.chamber_names):
        ax = axes[i // 2, 1]
        ax.plot(rates.measured_rate[:, i] / 1e5, pred[:, i] / 1e5, ".", ms=2, alpha=0.5,
                label=f"{a} {ch}: R² {r2[i]:.3f}")
    for ax in axes[:, 1]:
        lim = ax.get_xlim()
        ax.plot(lim, lim, "k-", lw=0.6)
        ax.set_xlabel("measured dp/dt [bar/s]")
        ax.set_ylabel("predicted dp/dt [bar/s]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, markerscale=4)
    fig.suptitle("Fig. 4A: measured and predicted pressure rates on held-out tracking data (arm2)")
    fig.tight_layout()
    ctx.savefig(fig, "pdot_fit.png")


if __name__ == "__main__":
    main(__name__)
