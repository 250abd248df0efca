"""Paper 000 Sec. IV, Figs. 14-18: force control of the jet-pipe actuator, proportional and
feedforward + proportional (eq. 14), tracking a 45 +- 5 N sine with the piston on the stopper.

* Fig. 18: a 5 Hz sine, proportional alone (offset) vs feedforward (k_p = 20, 1 kHz servo).
* Fig. 15: servo-rate study at 7 Hz, k_p = 20: maximum tracking error at 70 Hz and 500 Hz
  (paper: 10.93 N and 2.37 N).
* Fig. 14: closed-loop -3 dB bandwidth (below the lowest-frequency gain, 0.5 Hz) vs gain
  (feedforward, 1 kHz), and the highest tracking
  frequency before the actuator saturates.  "Saturation" is the jet pipe running into its
  stops: the commanded current leaves the jet's range (|i| above the current that puts the
  static jet position at 90 % of x_sat, ~0.1 A) -- the definition under which the paper's
  three statements (onset near k_p = 7.5 at the bandwidth; 7 Hz at k_p = 20; 5 Hz at k_p = 50)
  are consistent with one another.
* Figs. 16-17: closed-loop frequency responses vs gain (5 N amplitude) and vs amplitude (k_p = 30).
"""
from __future__ import annotations

import math

import numpy as np

from controllers.force import ForceCfg
from pneumatics.jetpipe.freqresp import bandwidth_hz, sine_gain
from pneumatics.jetpipe.sim import JetpipeSim
from pneumatics.jetpipe.statics import static_curve

from .common import main, plt

SUMMARY = "Figs. 14-18: feedforward + proportional force control; servo rate, bandwidth vs gain, saturation"

MEAN_N = 45.0


def gain_name(kp: float) -> str:
    return f"{kp:g}".replace(".", "p")


def jet_saturation_current_a(cfg, fraction: float = 0.9) -> float:
    """|i| [A] at which the static jet position reaches ``fraction`` of x_sat (eqs. 1-2)."""
    return cfg.jet.saturation_force_n * math.atanh(fraction) / cfg.driver.force_constant_n_per_a


def sine_ref(amp_n: float, freq_hz: float):
    return lambda t: MEAN_N + amp_n * math.sin(2 * math.pi * freq_hz * t)


def tracking(sim, curve, kp, freq, amp, rate_hz=None, feedforward=True, duration=None, delay=None):
    """Run one tracking experiment (servo rate: the model's [control] rate_hz unless given);
    returns (recording, controller, max |error| after the first period)."""
    rate_hz = rate_hz or sim.cfg.control.rate_hz
    extra = {} if delay is None else {"delay_samples": delay}
    ctl = ForceCfg(kp=kp, rate_hz=rate_hz, feedforward=feedforward, static_gain_n_per_a=curve.slope_n_per_a(MEAN_N),
                   **extra).build(sine_ref(amp, freq), curve.inverse)
    sim.reset(MEAN_N)
    duration = duration or max(3.0 / freq, 0.6)
    rec = sim.run(ctl, duration, record_hz=2000.0)
    keep = rec.time >= max(1.0 / freq, 0.2)
    err = rec["force.piston"][keep] - rec["force_ref.piston"][keep]
    return rec, ctl, float(np.max(np.abs(err)))


def closed_loop_response(sim, curve, kp, amp, freqs, i_sat, periods):
    """(gains (F,), max |i_cmd| (F,)) of the feedforward loop at the model's servo rate (1 kHz)."""
    gains, imax = [], []
    for f in freqs:
        ctl = ForceCfg(kp=kp, rate_hz=sim.cfg.control.rate_hz, static_gain_n_per_a=curve.slope_n_per_a(MEAN_N)).build(
            sine_ref(amp, f), curve.inverse)
        g, rec = sine_gain(sim, ctl, f, "force_ref.piston", MEAN_N, *periods)
        keep = rec.time >= rec.time[-1] - periods[1] / f
        gains.append(g)
        imax.append(float(np.max(np.abs(rec["i_cmd.piston"][keep]))))
    return np.array(gains), np.array(imax)


def max_frequency_before_saturation(freqs, imax, i_sat) -> float:
    """Highest frequency [Hz] at which the peak command stays below ``i_sat`` (log-interpolated)."""
    over = np.nonzero(imax > i_sat)[0]
    if over.size == 0:
        return float(freqs[-1])
    k = over[0]
    if k == 0:
        return float(freqs[0])
    return float(np.exp(np.interp(i_sat, [imax[k - 1], imax[k]], np.log([freqs[k - 1], freqs[k]]))))


def saturation_onset_kp(gains, bws, fsat):
    """The gain at which the bandwidth first exceeds the highest frequency trackable without
    saturating (Fig. 14's crossing), linearly interpolated; None if it never does."""
    d = np.asarray(fsat) - np.nan_to_num(np.asarray(bws), nan=0.0)
    for k in range(1, len(gains)):
        if d[k - 1] > 0 >= d[k]:
            return float(np.interp(0.0, [d[k], d[k - 1]], [gains[k], gains[k - 1]]))
    return None


def run(ctx):
    sim = JetpipeSim()
    curve = static_curve(sim.cfg)
    i_sat = jet_saturation_current_a(sim.cfg)
    metrics = {"static_gain_n_per_a": curve.slope_n_per_a(MEAN_N), "jet_saturation_current_a": i_sat}
    _tracking(ctx, sim, curve, metrics)
    _frequency_responses(ctx, sim, curve, i_sat, metrics)
    return metrics


def _tracking(ctx, sim, curve, metrics):
    """Fig. 18 (proportional vs feedforward at 5 Hz) and Fig. 15 (servo rate at 7 Hz, k_p = 20)."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    for ff, label in [(False, "proportional"), (True, "feedforward + proportional")]:
        rec, _, err = tracking(sim, curve, 20.0, 5.0, 5.0, feedforward=ff, duration=0.6 if ctx.fast else 1.0)
        metrics[f"max_err_n_5hz_{'ff' if ff else 'p'}"] = err
        axes[0].plot(rec.time, rec["force.piston"], label=f"{label} (max err {err:.2f} N)")
    axes[0].plot(rec.time, rec["force_ref.piston"], "k--", lw=0.8, label="desired")
    axes[0].set_title("Fig. 18: 5 Hz, k_p = 20, 1 kHz")
    logger = ctx.rerun_logger(sim.rerun_robot(), "jetpipe force control, 7 Hz")
    for rate in (70.0, 500.0):
        rec, ctl, err = tracking(sim, curve, 20.0, 7.0, 5.0, rate_hz=rate, duration=0.6 if ctx.fast else 1.5)
        metrics[f"max_err_n_{rate:.0f}hz"] = err
        ctx.save_recording(rec, f"tracking_7hz_servo_{rate:.0f}hz.csv")
        if logger is not None:  # one Rerun recording, one prefix per servo rate
            logger.log_recording(rec, prefix=f"servo_{rate:.0f}hz", bodies=True)
        metrics[f"saturated_share_{rate:.0f}hz"] = ctl.saturation_fraction
        axes[1].plot(rec.time, rec["force.piston"] - rec["force_ref.piston"], label=f"servo {rate:.0f} Hz: max {err:.2f} N")
        if not ctx.fast:  # the same without the one-sample computation delay
            _, _, err0 = tracking(sim, curve, 20.0, 7.0, 5.0, rate_hz=rate, duration=1.5, delay=0)
            metrics[f"max_err_n_{rate:.0f}hz_no_delay"] = err0
    if logger is not None:
        logger.close()
    axes[1].set_title("Fig. 15: tracking error at 7 Hz, k_p = 20")
    for a in axes:
        a.set_xlabel("time [s]")
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    axes[0].set_ylabel("force [N]")
    axes[1].set_ylabel("force error [N]")
    ctx.savefig(fig, "tracking.png")


def _frequency_responses(ctx, sim, curve, i_sat, metrics):
    """Fig. 14 (bandwidth against k_p, saturation onset), Figs. 16-17 (gain and amplitude)."""
    if ctx.fast:
        gains, freqs, periods = [20.0], np.array([1.0, 5.0, 15.0, 30.0]), (1.0, 1.0)
        extra_gains, amps = [], []
    else:
        gains = [2.0, 5.0, 7.5, 10.0, 20.0, 30.0, 50.0]
        freqs = np.array([0.5, 1.0, 2.0, 4.0, 7.0, 10.0, 15.0, 20.0, 30.0, 50.0, 80.0])
        periods = (2.0, 2.0)
        extra_gains, amps = [120.0], [1.0, 2.0, 10.0]
    responses = {}
    for kp in gains + extra_gains:
        responses[(kp, 5.0)] = closed_loop_response(sim, curve, kp, 5.0, freqs, i_sat, periods)
    for a in amps:
        responses[(30.0, a)] = closed_loop_response(sim, curve, 30.0, a, freqs, i_sat, periods)
    bws, fsat = [], []
    for kp in gains:
        g, imax = responses[(kp, 5.0)]
        bw = bandwidth_hz(freqs, g)  # -3 dB below the lowest-frequency gain
        bws.append(bw)
        metrics[f"low_freq_gain_db_kp_{gain_name(kp)}"] = float(20 * np.log10(abs(g[0])))
        fsat.append(max_frequency_before_saturation(freqs, imax, i_sat))
        metrics[f"bw_hz_kp_{gain_name(kp)}"] = bw if np.isfinite(bw) else float(freqs[-1])
        metrics[f"max_freq_before_saturation_hz_kp_{gain_name(kp)}"] = fsat[-1]
    onset = saturation_onset_kp(gains, bws, fsat)
    if onset is not None:
        metrics["saturation_onset_kp"] = onset
    _plot_bandwidth(ctx, gains, bws, fsat, onset)
    _plot_responses(ctx, freqs, responses)
    for key, (g, _) in responses.items():
        if key[0] == 30.0:
            bw = bandwidth_hz(freqs, g)
            metrics[f"bw_hz_kp_30_amp_{key[1]:g}n"] = bw if np.isfinite(bw) else float(freqs[-1])


def _plot_bandwidth(ctx, gains, bws, fsat, onset):
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(gains, bws, "o-", label="-3 dB bandwidth")
    if onset is not None:
        ax.axvline(onset, color="k", lw=0.8, ls=":", label=f"saturation onset k_p = {onset:.1f}")
    ax.plot(gains, fsat, "s--", label="max tracking frequency before saturation")
    ax.set_xlabel("k_p")
    ax.set_ylabel("frequency [Hz]")
    ax.set_title("Fig. 14: 45 +- 5 N, feedforward, 1 kHz")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ctx.savefig(fig, "bandwidth_vs_gain.png")


def _plot_responses(ctx, freqs, responses):
    fig, axes = plt.subplots(2, 2, figsize=(12, 7), sharex=True)
    for col, (title, keys) in enumerate([
            ("Fig. 16: effect of gain (5 N amplitude)", [(k, 5.0) for k in (2.0, 5.0, 20.0, 120.0) if (k, 5.0) in responses]),
            ("Fig. 17: effect of amplitude (k_p = 30)", [(30.0, a) for a in (1.0, 2.0, 5.0, 10.0) if (30.0, a) in responses])]):
        for key in keys:
            g, _ = responses[key]
            label = f"k_p = {key[0]:g}, {key[1]:g} N"
            axes[0, col].semilogx(freqs, 20 * np.log10(np.abs(g)), "o-", label=label)
            axes[1, col].semilogx(freqs, np.degrees(np.unwrap(np.angle(g))), "o-")
        axes[0, col].set_title(title)
        axes[0, col].set_ylabel("|F / F_d| [dB]")
        axes[1, col].set_ylabel("phase [deg]")
        axes[1, col].set_xlabel("frequency [Hz]")
        if keys:
            axes[0, col].legend(fontsize=8)
        for a in axes[:, col]:
            a.grid(True, which="both", alpha=0.3)
    ctx.savefig(fig, "frequency_response.png")


if __name__ == "__main__":
    main(__name__)
