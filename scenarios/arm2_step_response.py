"""Paper 002 Fig. 2C: response of the elbow to a step on one valve, link 2 horizontal.

The elbow rests against its negative limit with chamber a (agonist) exhausted at 0 V.  At
t = 0 the agonist command steps 0 -> 10 V.  Top row: the antagonist (chamber b) at 0 V, open
to the room: a very fast movement (paper: 1450 deg/s peak) during which the antagonist
pressure rises near the end, because its volume shrinks faster than air leaves through the
fully open exhaust.  Bottom row: the antagonist at 5 V (its null, pressurised to its null
asymptote beforehand): the arm starts fast, nearly stops against the compressed antagonist,
then creeps on as the null leak lets air out.
"""
from __future__ import annotations

import numpy as np

from pneumatics.runner import OpenLoop, run as run_loop

from ._arm2 import deg, horizontal_elbow_sim
from .common import main, plt
from .arm2_asymptotic_pressure import equilibrium_pressure

SUMMARY = "Fig. 2C: elbow step response, antagonist at 0 V and at 5 V (peak velocity)"
FITTED_MODEL = "arm2"  # takes --fitted: a doctor's model.toml of arm2 (scenarios.common)
START_DEG = -65.0


def one_case(antagonist_v: float, duration_s: float, ctx, label: str):
    sim = horizontal_elbow_sim(ctx.load_robot("arm2"))
    tab = sim.tables
    # antagonist chamber pre-charged to its asymptote at its command; agonist exhausted
    from pneumatics.valve import valve_areas
    a_s, a_e = valve_areas(np.array([antagonist_v]), tab.valve[3][None])
    p_b = equilibrium_pressure(a_s[0], a_e[0], tab.gas, tab.supply_pa, tab.room_pa)
    p_shoulder = 4.0e5
    sim.reset(qpos=[0.0, np.radians(START_DEG)], pressure_pa=[p_shoulder, p_shoulder, tab.room_pa, p_b])
    null = tab.valve[:, 0]

    def commands(t):
        return np.array([null[0], null[1], 10.0 if t >= 0.0 else 0.0, antagonist_v])

    logger = ctx.rerun_logger(sim.robot, f"step_response_{label}")
    rec = run_loop(sim, _Physics(commands), duration_s, rate_hz=1000.0, noise=False, average=False,
                   record_velocity=True, logger=None)
    if logger is not None:
        logger.log_recording(rec, prefix=label)
        logger.close()
    return rec


class _Physics(OpenLoop):
    """Open-loop step at 1 kHz so the 1 ms step edge and peak velocity are resolved."""


def run(ctx):
    duration = 0.6 if ctx.fast else 1.5
    recs = {"antagonist 0 V": one_case(0.0, duration, ctx, "antagonist_0v"),
            "antagonist 5 V": one_case(5.0, duration if not ctx.fast else 1.0, ctx, "antagonist_5v")}
    fig, axes = plt.subplots(2, 3, figsize=(12, 6), sharex="row")
    peaks = {}
    for row, (label, rec) in enumerate(recs.items()):
        t = rec.time
        v = deg(rec["qd.elbow"])
        peaks[label] = float(v.max())
        axes[row, 0].plot(t, deg(rec["q.elbow"]))
        axes[row, 0].set_ylabel(f"{label}\nelbow angle [deg]")
        axes[row, 1].plot(t, v)
        axes[row, 1].set_ylabel("velocity [deg/s]")
        axes[row, 2].plot(t, rec["p_a.elbow"] / 1e5, label="agonist (a)")
        axes[row, 2].plot(t, rec["p_b.elbow"] / 1e5, label="antagonist (b)")
        axes[row, 2].set_ylabel("pressure [bar abs]")
        axes[row, 2].legend(fontsize=8)
        for ax in axes[row]:
            ax.set_xlabel("time [s]")
    fig.suptitle("arm2 elbow step response, link 2 horizontal (paper 002 Fig. 2C)")
    fig.tight_layout()
    ctx.savefig(fig, "step_response.png")
    ctx.save_recording(recs["antagonist 0 V"], "step_antagonist_0v.csv")
    ctx.save_recording(recs["antagonist 5 V"], "step_antagonist_5v.csv")

    r0 = recs["antagonist 0 V"]
    v0 = r0["qd.elbow"]
    k_peak = int(np.argmax(v0))
    pb = r0["p_b.elbow"]
    # antagonist rise at the end of the movement: its peak pressure after the velocity peak
    r5 = recs["antagonist 5 V"]
    v5 = deg(r5["qd.elbow"])
    k5 = int(np.argmax(v5))
    after = v5[k5:]
    dip = float(after[: int(0.4 * 1000)].min()) if after.size > 10 else float("nan")
    return {
        "peak_velocity_deg_s": peaks["antagonist 0 V"],
        "time_to_peak_s": float(r0.time[k_peak]),
        "antagonist_peak_pressure_pa": float(pb.max()),
        "antagonist_peak_after_velocity_peak": bool(np.argmax(pb) >= k_peak),
        "peak_velocity_5v_deg_s": peaks["antagonist 5 V"],
        "min_velocity_after_peak_5v_deg_s": dip,
        "final_angle_5v_deg": float(deg(r5["q.elbow"][-1])),
    }


if __name__ == "__main__":
    main(__name__)
