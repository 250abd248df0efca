"""Paper 001 §4.1, Figs. 5-6: the SARCOS elbow braced, sinusoidal valve currents.

The steel brace locks the load (the equality ``brace``), so the valve works against the
blocked vane and its compliant shaft: what the valve does shows directly in the pressures.
Currents of 0.2 A and 0.3 A at 1 rad/s, after the decaying sinusoid that puts the valve at its
null (paper §4).  Plots the supply and the two chamber pressures as the paper's Figs. 5 and 6
and reports the load-pressure amplitude of the last full cycle (the paper: the DC gain from
current to load pressure falls as the amplitude grows), the supply pressure at the valve and
its dip while the valve draws flow.
"""
from __future__ import annotations

import math

from pneumatics.hydraulics import load_hydraulic, run_current

from .common import main, plt

SUMMARY = "Figs. 5-6: braced elbow, 0.2 A and 0.3 A at 1 rad/s: supply and chamber pressures"
PSI = 6894.757
OMEGA = 1.0  # rad/s


def one_amplitude(sim, amp_a: float, duration_s: float):
    sim.reset(braced=True)
    return run_current(sim, lambda t: amp_a * math.sin(OMEGA * t), duration_s, name=f"locked_{amp_a:g}a")


def last_cycle(rec, fast: bool):
    """The samples of the last full current period (fast: the whole run)."""
    period = 2 * math.pi / OMEGA
    t0 = rec.time[-1] - period if not fast else 0.0
    return rec.time >= t0


def run(ctx):
    sim = load_hydraulic("sarcos_elbow")
    # fast: past the first positive peak; full: two periods, the second one measured
    duration = 2.0 if ctx.fast else 2 * 2 * math.pi / OMEGA
    recs = {amp: one_amplitude(sim, amp, duration) for amp in (0.2, 0.3)}
    logger = ctx.rerun_logger(sim.rerun_robot(), "sarcos_locked")
    if logger is not None:
        for amp, rec in recs.items():
            logger.log_recording(rec, prefix=f"locked_{round(amp * 10):02d}a", bodies=False)
        logger.close()
    metrics = {}
    fig, axes = plt.subplots(2, 2, figsize=(12, 7), gridspec_kw={"width_ratios": [2.2, 1]})
    gauge = sim.cfg.power.tank_pa
    for row, (amp, rec) in enumerate(recs.items()):
        ax, loop = axes[row]
        sel = last_cycle(rec, ctx.fast)
        p_l = rec["p_a.elbow"] - rec["p_b.elbow"]
        tag = f"{round(amp * 10):02d}a"
        amp_pa = p_l[sel].max() if ctx.fast else (p_l[sel].max() - p_l[sel].min()) / 2
        metrics[f"load_pressure_amp_mpa_{tag}"] = float(amp_pa / 1e6)
        metrics[f"supply_pressure_mean_mpa_{tag}"] = float(rec["p_supply"][sel].mean() / 1e6)
        metrics[f"supply_pressure_dip_mpa_{tag}"] = float(
            (sim.cfg.power.pump_pa - rec["p_supply"][sel].min()) / 1e6)
        metrics[f"chamber_pressure_mean_mpa_{tag}"] = float(
            0.5 * (rec["p_a.elbow"] + rec["p_b.elbow"])[sel].mean() / 1e6)
        tau = rec["tau.elbow"][sel]
        metrics[f"torque_amp_nm_{tag}"] = float(tau.max() if ctx.fast else (tau.max() - tau.min()) / 2)
        for col, label in (("p_supply", "supply (at the valve)"), ("p_a.elbow", "chamber a (port 1)"),
                           ("p_b.elbow", "chamber b (port 2)")):
            ax.plot(rec.time, (rec[col] - gauge) / PSI, label=label)
        ax.set_ylabel("pressure [psi gauge]")
        sec = ax.secondary_yaxis("right", functions=(lambda p: p * PSI / 1e6, lambda m: m * 1e6 / PSI))
        sec.set_ylabel("[MPa gauge]")
        ax.set_title(f"braced elbow, i = {amp:g} sin({OMEGA:g} t) A (paper Fig. {5 if amp == 0.2 else 6});"
                     f" load-pressure amplitude {metrics[f'load_pressure_amp_mpa_{tag}']:.2f} MPa", fontsize=10)
        ax.legend(loc="lower left", fontsize=8)
        ax.grid(alpha=0.3)
        ax.set_xlabel("time [s]")
        loop.plot(rec["i.elbow"], p_l / 1e6, lw=1)
        loop.set_xlabel("current [A]")
        loop.set_ylabel("load pressure P_a - P_b [MPa]")
        loop.set_title("valve hysteresis seen in the load pressure", fontsize=10)
        loop.grid(alpha=0.3)
        ctx.save_recording(rec, f"locked_{tag}.csv")
    fig.tight_layout()
    ctx.savefig(fig, "locked_pressures.png")
    metrics["pressure_gain_ratio_03a_over_02a"] = (
        (metrics["load_pressure_amp_mpa_03a"] / 0.3) / (metrics["load_pressure_amp_mpa_02a"] / 0.2))
    metrics["mujoco_warnings"] = int(sum(sim.warnings))
    return metrics


if __name__ == "__main__":
    main(__name__)
