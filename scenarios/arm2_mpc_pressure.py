"""Paper 002 §IV-B.4, Fig. 4B: reference pressure differences d(t + Delta) (blue) and those the
air-dynamics model predicts (red) for the valve commands iLQG computes, both actuators.

The paper: "The two are indistinguishable, meaning that at least according to the model we can
achieve the desired pressure differences perfectly, by taking into account a few time steps into
the future (currently n = 2)."

The reference comes from the model-based PIDF (eqs. 16-17) tracking a hand-moved reference; its
inverse dynamics is fitted on a PIDF run of the same reference (as scenarios/arm2_tracking.py).
The MPC (:mod:`controllers.ilqg`, horizon n = 2, Delta = 10 ms) runs on the simulated arm;
every control step logs d*(t + Delta) and the model's predicted d(t + Delta) for the first
command (``pressure_diff_rmse_pa``, their RMS difference over both actuators).  What the
simulated arm then did is a different question, answered by ``realized_pressure_diff_rmse_pa``:
the measured d (DAQ mean over the next period, with sensor noise) against d*.
"""
from __future__ import annotations

import numpy as np

from controllers.ilqg import ILQGCfg, build_mpc_model_based

from ._arm2_control import arm2, gains, references, run_controller
from .arm2_tracking import fit_model
from .common import main, plt

SUMMARY = "Fig. 4B: iLQG MPC (n = 2): reference vs model-predicted pressure differences, both actuators"

HORIZON = 2


class PredictionLog:
    """Wraps a :class:`controllers.ilqg.PressureMPC`: records, at each solve, d*(t + Delta) and
    the model's d(t + Delta) under the commands it returns."""

    def __init__(self, mpc):
        self.mpc, self.cfg = mpc, mpc.cfg
        self.reference_pa, self.predicted_pa = [], []

    def reset(self):
        self.mpc.reset()
        self.reference_pa, self.predicted_pa = [], []

    def solve(self, p0, q_pred, d_ref):
        u = self.mpc.solve(p0, q_pred, d_ref)
        p1 = self.mpc.last_prediction[1]
        self.reference_pa.append(np.array(d_ref[0], float))
        self.predicted_pa.append(p1[0::2] - p1[1::2])
        return u


def run(ctx):
    robot = arm2()
    duration = 2.5 if ctx.fast else 30.0
    ref = references(robot, "normal", duration, 1)[0]
    g = gains()
    pidf_rec = run_controller(robot, lambda sim: g["pidf"].build(ref, robot.tables.valve[:, 0]), ref, duration)
    model = fit_model(robot, [pidf_rec])
    cfg = ILQGCfg(horizon=HORIZON)
    logs = []

    def wrap(ctrl, sim):
        ctrl.mpc = PredictionLog(ctrl.mpc)
        logs.append(ctrl.mpc)
        return ctrl

    rec = run_controller(robot, lambda sim: build_mpc_model_based(robot, ref, model, g["pidf"], cfg), ref,
                         duration, wrap=wrap)
    log = logs[0]
    d_ref, d_pred = np.array(log.reference_pa), np.array(log.predicted_pa)
    acts = robot.actuator_names
    d_meas = np.column_stack([rec[f"p_a.{a}"] - rec[f"p_b.{a}"] for a in acts])
    n = min(d_ref.shape[0], d_meas.shape[0] - 1)
    realized = d_meas[1:n + 1] - d_ref[:n]  # row k+1 is the mean over the period after command k
    metrics = {"pressure_diff_rmse_pa": float(np.sqrt(np.mean((d_pred - d_ref) ** 2))),
               "realized_pressure_diff_rmse_pa": float(np.sqrt(np.mean(realized ** 2))),
               "reference_diff_rms_pa": float(np.sqrt(np.mean(d_ref ** 2))), "horizon": HORIZON,
               "control_steps": int(d_ref.shape[0])}
    for i, a in enumerate(acts):
        metrics[f"pressure_diff_rmse_pa_{a}"] = float(np.sqrt(np.mean((d_pred[:, i] - d_ref[:, i]) ** 2)))
        metrics[f"realized_pressure_diff_rmse_pa_{a}"] = float(np.sqrt(np.mean(realized[:, i] ** 2)))
    _plot(ctx, acts, rec.time[:d_ref.shape[0]] + cfg.step_s, d_ref, d_pred, d_meas, rec.time, metrics)
    return metrics


def _plot(ctx, acts, t_next, d_ref, d_pred, d_meas, t_meas, metrics):
    fig, axes = plt.subplots(len(acts), 1, figsize=(10, 2.8 * len(acts)), sharex=True)
    for i, (ax, a) in enumerate(zip(np.atleast_1d(axes), acts)):
        ax.plot(t_next, d_ref[:, i] / 1e5, "C0-", lw=2.2, label="reference d*(t + Δ)")
        ax.plot(t_next, d_pred[:, i] / 1e5, "C3-", lw=1.0, label="model-predicted d(t + Δ) under iLQG's commands")
        ax.plot(t_meas, d_meas[:, i] / 1e5, "k:", lw=0.8, label="realized on the simulated arm (DAQ mean)")
        ax.set_ylabel(f"{a}: p_a - p_b [bar]")
        ax.set_title(f"{a}: predicted vs reference RMS {metrics[f'pressure_diff_rmse_pa_{a}']:.0f} Pa; "
                     f"realized {metrics[f'realized_pressure_diff_rmse_pa_{a}']:.0f} Pa", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    np.atleast_1d(axes)[-1].set_xlabel("time [s]")
    fig.suptitle(f"Fig. 4B: iLQG MPC on the air dynamics, horizon n = {HORIZON}")
    fig.tight_layout()
    ctx.savefig(fig, "pressure_mpc.png")


if __name__ == "__main__":
    main(__name__)
