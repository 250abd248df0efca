"""Paper 000 Sec. IV, Figs. 19-20: feedforward + proportional force control (eq. 14) tracking a
5 Hz sine, 45 +- 5 N, piston on the stopper at 54 mm, 1 kHz servo.

* Fig. 19: actuator saturation.  k_p = 30 tracks cleanly; k_p = 80 drives the command past the
  jet's range (the paper: "the actuator saturation shown in 19(d) causes noise at the
  corresponding points in 19(c)").  Panels (b) and (d) of the paper show the D/A input voltage;
  ours show the current command [A] (the driver's volts-to-amperes scale is not given).
  Saturation is the jet running into its stops: |i_cmd| above the current that puts the
  static jet position at 90 % of x_sat (scenarios/jetpipe_force_control.py).
* Fig. 20: the effect of gain: maximum absolute error 1.97 N at k_p = 20 and 0.89 N at
  k_p = 50, "the maximum possible gain for tracking this frequency before saturation occurs".

``gain_5hz`` is the closed-loop amplitude ratio |F / F_d| at 5 Hz with k_p = 50 (the fundamental
of force over that of the desired force, after the first period); ``gain_5hz_kp_<k>`` for every
gain; ``max_err_n_kp_<k>`` the maximum absolute tracking error; ``saturated_share_kp_<k>`` the
share of servo samples with |i_cmd| past the jet's range.
"""
from __future__ import annotations

import numpy as np

from pneumatics.jetpipe.freqresp import fundamental
from pneumatics.jetpipe.sim import JetpipeSim
from pneumatics.jetpipe.statics import static_curve

from .common import main, plt
from .jetpipe_force_control import gain_name, jet_saturation_current_a, tracking

SUMMARY = "Figs. 19-20: 5 Hz force tracking with feedforward; saturation at k_p = 80, error vs gain"

FREQ_HZ = 5.0
AMPLITUDE_N = 5.0
PAPER_MAX_ERR_N = {20.0: 1.97, 50.0: 0.89}


def run(ctx):
    sim = JetpipeSim()
    curve = static_curve(sim.cfg)
    i_sat = jet_saturation_current_a(sim.cfg)
    duration = 0.6 if ctx.fast else 1.2
    gains = (20.0, 50.0, 80.0) if ctx.fast else (20.0, 30.0, 50.0, 80.0)
    recs = {}
    metrics = {"jet_saturation_current_a": i_sat}
    for kp in gains:
        rec, _, err = tracking(sim, curve, kp, FREQ_HZ, AMPLITUDE_N, duration=duration)
        recs[kp] = rec
        keep = rec.time >= 1.0 / FREQ_HZ
        t = rec.time[keep]
        g = fundamental(t, rec["force.piston"][keep], FREQ_HZ) / fundamental(t, rec["force_ref.piston"][keep], FREQ_HZ)
        name = gain_name(kp)
        metrics[f"max_err_n_kp_{name}"] = err
        metrics[f"gain_5hz_kp_{name}"] = abs(g)
        metrics[f"phase_deg_5hz_kp_{name}"] = float(np.degrees(np.angle(g)))
        metrics[f"saturated_share_kp_{name}"] = float(np.mean(np.abs(rec["i_cmd.piston"][keep]) > i_sat))
        metrics[f"max_abs_command_a_kp_{name}"] = float(np.max(np.abs(rec["i_cmd.piston"][keep])))
    metrics["gain_5hz"] = metrics["gain_5hz_kp_50"]
    _plot_fig19(ctx, recs, i_sat, 30.0 if 30.0 in recs else 20.0)
    _plot_fig20(ctx, recs, metrics)
    return metrics


def _plot_fig19(ctx, recs, i_sat, low_kp):
    fig, axes = plt.subplots(2, 2, figsize=(11, 6), sharex=True)
    for col, kp in enumerate((low_kp, 80.0)):
        rec = recs[kp]
        axes[0, col].plot(rec.time, rec["force_ref.piston"], "k--", lw=0.9, label="desired")
        axes[0, col].plot(rec.time, rec["force.piston"], "C0", label="actual")
        axes[0, col].set_title(f"({'a' if col == 0 else 'c'}) k_p = {kp:g}: force")
        axes[0, col].set_ylabel("force [N]")
        axes[0, col].legend(fontsize=8)
        axes[1, col].plot(rec.time, rec["i_cmd.piston"], "C1")
        for s in (-1, 1):
            axes[1, col].axhline(s * i_sat, color="r", lw=0.8, ls=":")
        axes[1, col].set_title(f"({'b' if col == 0 else 'd'}) command (red: jet range, ±{i_sat * 1e3:.0f} mA)")
        axes[1, col].set_ylabel("current command [A]")
        axes[1, col].set_xlabel("time [s]")
    for a in axes.flat:
        a.grid(alpha=0.3)
    fig.suptitle("Fig. 19: effect of actuator saturation, 5 Hz, feedforward + proportional")
    fig.tight_layout()
    ctx.savefig(fig, "saturation.png")


def _plot_fig20(ctx, recs, metrics):
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), sharey=True)
    for ax, kp in zip(axes, (20.0, 50.0)):
        rec = recs[kp]
        err = metrics[f"max_err_n_kp_{gain_name(kp)}"]
        ax.plot(rec.time, rec["force_ref.piston"], "k-", lw=0.9, label="desired")
        ax.plot(rec.time, rec["force.piston"], "C0--", label="actual")
        ax.set_title(f"k_p = {kp:g}: max |error| {err:.2f} N (paper {PAPER_MAX_ERR_N[kp]:.2f} N)")
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("force [N]")
    fig.suptitle("Fig. 20: effect of gain on tracking a 5 Hz sine (feedforward)")
    fig.tight_layout()
    ctx.savefig(fig, "gain_effect.png")


if __name__ == "__main__":
    main(__name__)
