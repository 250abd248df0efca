"""Paper 002 §V, Fig. 6A-B: PID, PIDF, model-based PIDF and its MPC variant tracking the
arm2 references at normal and 2x ("fast") speed.

For each controller and speed, the mean absolute joint error (averaged over the two joints
and the references) between the reference q*(t) and the trajectory q(t + lag) for lags
0-200 ms (Fig. 6B): the controllers often reproduce the reference with a delay.  The
inverse-dynamics model of the model-based controllers is fitted (paper 002 eqs. 1-5,
:mod:`identification.inverse_dynamics`) on this scenario's own PIDF runs, as the paper fitted
it on data recorded under feedback control on its three references.

Metrics: ``mae_deg_<controller>_<speed>`` (zero lag), ``best_lag_ms_<controller>_<speed>``,
``mae_best_deg_<controller>_<speed>`` (at the best lag), for controllers pid, pidf,
model_based, mpc and speeds normal, fast; ``pid_limit_hits_<speed>``: control periods in
which plain PID drove a joint into its limit at speed.  Writes ``tracking_lag.png``
(Fig. 6B), ``tracking_fast_segment.png`` (Fig. 6A) and ``inverse_dynamics.json``.
"""
from __future__ import annotations

import numpy as np
from matplotlib.ticker import FormatStrFormatter

from controllers.ilqg import ILQGCfg, build_mpc_model_based
from controllers.model_based import ModelBasedCfg
from controllers.tuning import LIMIT_MARGIN_RAD, LIMIT_SPEED_RAD_S
from identification import inverse_dynamics as idyn

from ._arm2_control import SPEEDS, gains, mae_vs_lag, references, run_controller
from .common import main, plt

SUMMARY = "Fig. 6B: arm2 tracking error vs lag for PID, PIDF, model-based PIDF and MPC at two speeds"
FITTED_MODEL = "arm2"  # takes --fitted: a doctor's model.toml of arm2 (scenarios.common)
CONTROLLERS = ("pid", "pidf", "model_based", "mpc")
LAGS_S = np.arange(0.0, 0.2001, 0.01)


def factories(robot, ref, model, mpc_cfg: ILQGCfg | None = None):
    """{controller name: factory(sim) -> controller} for one reference."""
    g = gains()
    null = robot.tables.valve[:, 0]
    return {"pid": lambda sim: g["pid"].build(ref, null),
            "pidf": lambda sim: g["pidf"].build(ref, null),
            "model_based": lambda sim: ModelBasedCfg(pidf=g["pidf"]).build(ref, null, model),
            "mpc": lambda sim: build_mpc_model_based(robot, ref, model, g["pidf"], mpc_cfg)}


def fit_model(robot, recs) -> idyn.InverseDynamics:
    """Inverse dynamics fitted on recordings made under feedback control."""
    return idyn.fit([idyn.samples(r, robot.joint_range()) for r in recs], idyn.torque_gain(robot))


def track(robot, controllers=CONTROLLERS, speeds=tuple(SPEEDS), n_refs: int = 3, duration_s: float = 60.0,
          seed: int = 0, model=None, mpc_cfg: ILQGCfg | None = None, refs: dict | None = None,
          only: dict | None = None):
    """Run the controllers; returns (recordings {(controller, speed): [Recording per ref]}, model).

    ``refs`` {speed: [reference, ...]} overrides the standard references; ``only``
    {controller: (speeds)} restricts a controller to some speeds.  PIDF runs first; unless
    ``model`` is given, the inverse dynamics is fitted on its runs."""
    refs = refs or {s: references(robot, s, duration_s, n_refs) for s in speeds}
    speeds = tuple(refs)
    recs = {}
    order = ["pidf"] + [c for c in controllers if c != "pidf"]
    for c in order:
        if c in ("model_based", "mpc") and model is None:
            model = fit_model(robot, [r for s in speeds for r in recs[("pidf", s)]])
        for s in speeds:
            if only and c in only and s not in only[c]:
                continue
            recs[(c, s)] = [run_controller(robot, factories(robot, ref, model, mpc_cfg)[c], ref, duration_s,
                                           seed=seed + 7 * i) for i, ref in enumerate(refs[s])]
    return {k: v for k, v in recs.items() if k[0] in controllers}, model


def limit_hits(rec, joint_range) -> int:
    q = rec.matrix("q", [c[2:] for c in rec.columns if c.startswith("q.")])
    qd = np.gradient(q, rec.time, axis=0)
    near = (q < joint_range[:, 0] + LIMIT_MARGIN_RAD) | (q > joint_range[:, 1] - LIMIT_MARGIN_RAD)
    return int(np.sum(np.any(near & (np.abs(qd) > LIMIT_SPEED_RAD_S), axis=1)))


def summarise(robot, recs) -> tuple[dict, dict]:
    """(metrics, {(controller, speed): MAE-vs-lag curve (len(LAGS_S),)})."""
    metrics, curves = {}, {}
    for (c, s), rs in recs.items():
        curve = np.mean([mae_vs_lag(r, robot.joint_names, LAGS_S) for r in rs], axis=0)
        curves[(c, s)] = curve
        k = int(np.argmin(curve))
        metrics[f"mae_deg_{c}_{s}"] = float(curve[0])
        metrics[f"best_lag_ms_{c}_{s}"] = float(round(1000 * LAGS_S[k]))
        metrics[f"mae_best_deg_{c}_{s}"] = float(curve[k])
        if c == "pid":
            metrics[f"pid_limit_hits_{s}"] = sum(limit_hits(r, robot.joint_range()) for r in rs)
    return metrics, curves


def run(ctx):
    robot = ctx.load_robot("arm2")
    n_refs, duration = (1, 6.0) if ctx.fast else (3, 60.0)
    recs, model = track(robot, n_refs=n_refs, duration_s=duration)
    model.save(ctx.out / "inverse_dynamics.json")
    ctx.written.append(ctx.out / "inverse_dynamics.json")
    metrics, curves = summarise(robot, recs)
    fast = metrics.get("mae_deg_pid_fast", np.nan), metrics.get("mae_deg_pidf_fast", np.nan), \
        metrics.get("mae_deg_model_based_fast", np.nan)
    metrics["ordering_holds_fast"] = int(fast[0] > fast[1] > fast[2])
    metrics.update({"n_references": n_refs, "reference_seconds": duration})
    _plot_lag(ctx, curves)
    _plot_segment(ctx, robot, recs)
    return metrics


STYLE = {"pid": ("C3", "PID (eq. 14)"), "pidf": ("C1", "PIDF (eq. 15)"),
         "model_based": ("C0", "model-based PIDF (eqs. 16-17)"), "mpc": ("C2", "model-based + iLQG MPC")}


def _plot_lag(ctx, curves):
    speeds = sorted({s for _, s in curves}, key=list(SPEEDS).index)
    fig, axes = plt.subplots(1, len(speeds), figsize=(5.5 * len(speeds), 4.2), squeeze=False)
    for ax, s in zip(axes[0], speeds):
        for c in CONTROLLERS:
            if (c, s) in curves:
                col, label = STYLE[c]
                ax.plot(1000 * LAGS_S, curves[(c, s)], color=col, marker="o", ms=3, label=label)
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
        ax.yaxis.set_minor_formatter(FormatStrFormatter("%g"))
        ax.tick_params(axis="y", which="minor", labelsize=7)
        ax.set_xlabel("time lag [ms]")
        ax.set_ylabel("mean absolute error [deg]")
        ax.set_title(f"{s} speed")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("arm2 tracking: error between reference and trajectory lagged (paper 002 Fig. 6B)")
    fig.tight_layout()
    ctx.savefig(fig, "tracking_lag.png")


def _plot_segment(ctx, robot, recs):
    if ("pid", "fast") not in recs:
        return
    rec0 = recs[("pidf", "fast")][0]
    t = rec0.time
    # the 3 s window with the fastest reference motion
    ref = rec0.matrix("ref", robot.joint_names)
    speed = np.abs(np.gradient(ref, t, axis=0)).max(axis=1)
    win_n = int(3.0 / np.median(np.diff(t)))
    k0 = int(np.argmax(np.convolve(speed, np.ones(win_n), "valid"))) if t.size > win_n else 0
    sl = slice(k0, k0 + win_n)
    fig, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    for j, joint in enumerate(robot.joint_names):
        ax = axes[j]
        ax.plot(t[sl], np.degrees(ref[sl, j]), "k", lw=2, label="reference")
        for c in CONTROLLERS:
            if (c, "fast") in recs:
                col, label = STYLE[c]
                ax.plot(t[sl], np.degrees(recs[(c, "fast")][0][f"q.{joint}"][sl]), color=col, lw=1, label=label)
        ax.set_ylabel(f"{joint} [deg]")
    axes[0].legend(fontsize=8, ncol=3)
    axes[1].set_xlabel("time [s]")
    fig.suptitle("arm2 on a fast reference (paper 002 Fig. 6A)")
    fig.tight_layout()
    ctx.savefig(fig, "tracking_fast_segment.png")


if __name__ == "__main__":
    main(__name__)
