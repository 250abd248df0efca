"""Paper 001 §4.2, Figs. 7-9: the SARCOS elbow free, i = 0.1 sin(0.25 t).

No brace: the valve's flow swings the forearm up against gravity and back.  The position is
the integral of the valve flow over D_v, so it turns where the flow changes sign.  At each
turning point the vane's Coulomb friction changes sign: the load pressure has to fall (or
rise) by 2 tau_c / D_v before the vane slides again, and meanwhile the load stands still —
the stick-slip the paper points out "as the arm approaches the highest parts of its
trajectory".  Plots the supply and chamber pressures (Fig. 7), the load pressure (Fig. 8)
and the load position with the stuck intervals shaded (Fig. 9); reports how long the load
sticks at the turning points.

``--fast`` drives the same amplitude four times faster, i = 0.1 sin(1.0 t), for 4 s, so the
first turning point comes at t = pi instead of 4 pi (the stick is then about 4x shorter:
the pressure crosses the same friction band at four times the rate).
"""
from __future__ import annotations

import math

import numpy as np

from pneumatics.hydraulics import load_hydraulic, run_current

from .common import main, plt

SUMMARY = "Figs. 7-9: free elbow, i = 0.1 sin(0.25 t): pressures, load position, stick-slip"
PSI = 6894.757
AMP_A, OMEGA = 0.1, 0.25
STUCK_RAD_S = 1e-3  # |load velocity| below this counts as stuck


def stuck_intervals(time, velocity, threshold=STUCK_RAD_S):
    """[(t0, t1)] where |velocity| < threshold, joining runs of consecutive samples."""
    stuck = np.abs(velocity) < threshold
    out, start = [], None
    for t, s in zip(time, stuck):
        if s and start is None:
            start = t
        elif not s and start is not None:
            out.append((start, t))
            start = None
    if start is not None:
        out.append((start, time[-1]))
    return out


def turning_point_sticks(time, velocity, angle):
    """Stuck intervals that contain a reversal of the load's motion (the angle's extrema),
    ignoring the rest at t = 0 and the end of the run."""
    result = []
    for t0, t1 in stuck_intervals(time, velocity):
        if t0 <= time[0] or t1 >= time[-1]:
            continue
        i0 = np.searchsorted(time, t0) - 1
        i1 = min(np.searchsorted(time, t1) + 1, len(time) - 1)
        before, after = velocity[max(i0 - 5, 0)], velocity[min(i1 + 5, len(time) - 1)]
        if before * after < 0:  # the load moves the other way afterwards: a turning point
            result.append((t0, t1, float(angle[i0])))
    return result


def run(ctx):
    sim = load_hydraulic("sarcos_elbow")
    sim.reset(braced=False)
    # full: two periods of the current (50 s); fast: 4x faster, through the first turning point
    omega = 1.0 if ctx.fast else OMEGA
    duration = 4.0 if ctx.fast else 2 * 2 * math.pi / OMEGA
    rec = run_current(sim, lambda t: AMP_A * math.sin(omega * t), duration, name="free")
    ctx.save_recording(rec, "free.csv")
    logger = ctx.rerun_logger(sim.rerun_robot(), "sarcos_free")
    if logger is not None:
        logger.log_recording(rec, prefix="", bodies=True)
        logger.close()
    t = rec.time
    sticks = turning_point_sticks(t, rec["load_velocity"], rec["load_angle"])
    p_l = rec["p_a.elbow"] - rec["p_b.elbow"]

    fig, axes = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
    gauge = sim.cfg.power.tank_pa
    for col, label in (("p_supply", "supply (at the valve)"), ("p_a.elbow", "chamber a (port 1)"),
                       ("p_b.elbow", "chamber b (port 2)")):
        axes[0].plot(t, (rec[col] - gauge) / PSI, label=label)
    axes[0].set_ylabel("pressure [psi gauge]")
    axes[0].set_title(f"i = {AMP_A:g} sin({omega:g} t) A: supply and chamber pressures, no brace "
                      "(paper Fig. 7)", fontsize=10)
    axes[0].legend(fontsize=8)
    axes[1].plot(t, p_l / 1e6, label="load pressure P_a - P_b")
    axes[1].plot(t, rec["tau.elbow"] / sim.d_v / 1e6, "--", lw=1, label="joint torque / D_v")
    axes[1].set_ylabel("[MPa]")
    axes[1].set_title("load pressure (paper Fig. 8); the gap to torque/D_v is the vane's friction",
                      fontsize=10)
    axes[1].legend(fontsize=8)
    axes[2].plot(t, np.degrees(rec["load_angle"]), label="load position")
    for k, (t0, t1, _) in enumerate(sticks):
        for ax in axes:
            ax.axvspan(t0, t1, color="tab:red", alpha=0.15, label="stuck" if (k == 0 and ax is axes[2]) else None)
    axes[2].set_ylabel("load angle [deg] (0 = hanging)")
    cur = axes[2].twinx()
    cur.plot(t, rec["i.elbow"], "k:", lw=0.8)
    cur.set_ylabel("current [A]")
    axes[2].set_title("load position (paper Fig. 9) and current; stick-slip at the turning points",
                      fontsize=10)
    axes[2].legend(fontsize=8, loc="lower left")
    axes[2].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    ctx.savefig(fig, "free_response.png")

    durations = [t1 - t0 for t0, t1, _ in sticks]
    # the friction band the pressure has to cross at a reversal, for comparison
    band_mpa = 2 * sim.coulomb_friction_nm / sim.d_v / 1e6
    return {
        "stick_time_s": float(np.mean(durations)) if durations else 0.0,
        "stick_count": len(durations),
        "stick_time_max_s": float(max(durations)) if durations else 0.0,
        "friction_band_mpa": float(band_mpa),
        "load_angle_max_deg": float(np.degrees(rec["load_angle"].max())),
        "load_angle_min_deg": float(np.degrees(rec["load_angle"].min())),
        "load_pressure_max_mpa": float(np.abs(p_l).max() / 1e6),
        "chamber_pressure_min_mpa": float(min(rec["p_a.elbow"].min(), rec["p_b.elbow"].min()) / 1e6),
        "chamber_pressure_max_mpa": float(max(rec["p_a.elbow"].max(), rec["p_b.elbow"].max()) / 1e6),
        "mujoco_warnings": int(sum(sim.warnings)),
    }


if __name__ == "__main__":
    main(__name__)
