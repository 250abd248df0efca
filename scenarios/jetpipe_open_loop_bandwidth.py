"""Paper 000 Sec. III-B, Figs. 10-11: open-loop force/current frequency response of the jet-pipe
actuator, piston on the stopper at x_s = 54 mm, for several mean currents (amplitude 0.01 A) and
several amplitudes (mean at 45 N).  Stepped sine, as a swept-sine analyser; the -3 dB bandwidth
is taken relative to each curve's lowest-frequency gain.  Paper: 0.8-2.8 Hz, rising slightly
with mean current and amplitude.
"""
from __future__ import annotations

import numpy as np

from pneumatics.jetpipe.freqresp import bandwidth_hz, sine_gain
from pneumatics.jetpipe.sim import JetpipeSim, OpenLoopCurrent
from pneumatics.jetpipe.statics import static_curve

from .common import main, plt

SUMMARY = "Figs. 10-11: open-loop force/current response vs mean current and amplitude (-3 dB bandwidth)"


def response(sim, curve, mean_a, amp_a, freqs, settle_periods, periods):
    force0 = float(np.interp(mean_a, curve.current_a, curve.force_n))
    gains = []
    for f in freqs:
        ctl = OpenLoopCurrent(lambda t, f=f: mean_a + amp_a * np.sin(2 * np.pi * f * t))
        g, _ = sine_gain(sim, ctl, f, "i_cmd.piston", force0, settle_periods, periods)
        gains.append(g)
    return np.array(gains)


def run(ctx):
    sim = JetpipeSim()
    curve = static_curve(sim.cfg)
    if ctx.fast:
        freqs = np.array([0.4, 1.5, 4.0])
        cases = [(45.0, 0.02)]
        periods = (0.5, 1.0)
    else:
        freqs = np.array([0.2, 0.4, 0.7, 1.0, 1.5, 2.0, 3.0, 5.0, 8.0])
        cases = [(30.0, 0.01), (45.0, 0.01), (52.0, 0.01), (45.0, 0.015), (45.0, 0.02)]
        periods = (1.5, 2.0)
    results = {}
    for force, amp in cases:
        mean = curve.inverse(force)
        g = response(sim, curve, mean, amp, freqs, *periods)
        results[(force, amp)] = (mean, g, bandwidth_hz(freqs, g))

    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    for col, (title, select) in enumerate([("mean current (amplitude 0.01 A)", lambda f, a: a == 0.01),
                                           ("amplitude (mean at 45 N)", lambda f, a: f == 45.0)]):
        for (force, amp), (mean, g, bw) in results.items():
            if not select(force, amp):
                continue
            label = f"mean {mean * 1e3:.1f} mA ({force:.0f} N), amp {amp * 1e3:.0f} mA: bw {bw:.2f} Hz"
            axes[0, col].semilogx(freqs, 20 * np.log10(np.abs(g)), "o-", label=label)
            axes[1, col].semilogx(freqs, np.degrees(np.unwrap(np.angle(g))), "o-")
        axes[0, col].set_title(f"open loop vs {title}")
        axes[0, col].set_ylabel("|F / i| [dB re 1 N/A]")
        if axes[0, col].get_legend_handles_labels()[0]:
            axes[0, col].legend(fontsize=7)
        axes[1, col].set_ylabel("phase [deg]")
        axes[1, col].set_xlabel("frequency [Hz]")
        for ax in axes[:, col]:
            ax.grid(True, which="both", alpha=0.3)
    ctx.savefig(fig, "open_loop_response.png")

    bws = np.array([r[2] for r in results.values()])
    metrics = {"bw_hz_min": float(np.nanmin(bws)), "bw_hz_max": float(np.nanmax(bws))}
    for (force, amp), (mean, g, bw) in results.items():
        metrics[f"bw_hz_{force:.0f}n_{amp * 1e3:.0f}ma"] = bw
        metrics[f"dc_gain_n_per_a_{force:.0f}n_{amp * 1e3:.0f}ma"] = float(abs(g[0]))
    return metrics


if __name__ == "__main__":
    main(__name__)
