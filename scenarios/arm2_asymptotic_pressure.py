"""Paper 002 Fig. 2A: asymptotic chamber pressure vs valve command, at static volume.

Each command 0-10 V is held on one chamber (elbow chamber a, piston held at mid-stroke, as
in the orifice calibration of 002 eq. 10) from atmospheric and from supply pressure.  The
pressure after 5 s (the paper's "asymptotic pressure") and the time to cover 90 % of the way
to the asymptote are plotted against the command.  The asymptote itself is where the valve's
supply and exhaust flows balance; it does not depend on the starting pressure, is monotone in
the command and intermediate near 5 V, where it is reached slowest.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from pneumatics.kernel import pack, static_transient_fast
from pneumatics.medium import orifice_flow
from pneumatics.robot import load_robot
from pneumatics.valve import valve_areas

from .common import main, plt

SUMMARY = "Fig. 2A: asymptotic pressure and 90 % time vs valve command at static volume (arm2 elbow a)"


def equilibrium_pressure(a_s, a_e, gas, supply_pa, room_pa):
    """Pressure [Pa] where supply inflow equals exhaust outflow (the true asymptote)."""
    def net(p):
        return orifice_flow(a_s, supply_pa, p, gas)[0] - orifice_flow(a_e, p, room_pa, gas)[0]
    if a_s <= 0:
        return room_pa
    if a_e <= 0:
        return supply_pa
    return brentq(lambda p: float(net(p)), room_pa, supply_pa, xtol=1e-6)


def t90(time, p, p0, p_inf):
    """First time the pressure has covered 90 % of the way from p0 to p_inf (0 if no way)."""
    span = p_inf - p0
    if abs(span) < 100.0:  # already there (within 1 mbar)
        return 0.0
    frac = (p - p0) / span
    hit = np.nonzero(frac >= 0.9)[0]
    return float(time[hit[0]]) if hit.size else float("nan")


def run(ctx):
    robot = load_robot("arm2")
    tab = robot.tables
    chamber = 2  # elbow a
    row = tab.valve[chamber][None]
    volume = tab.dead_volume[chamber] + tab.area[chamber] * tab.stroke[1] / 2
    step_v = 0.5 if ctx.fast else 0.1
    commands = np.round(np.arange(0.0, 10.0 + 1e-9, step_v), 6)
    duration = 12.0 if ctx.fast else 20.0
    dt = robot.model.opt.timestep
    _, _, glob = pack(tab, np.arange(len(robot.actuator_names)), dt)
    a_s, a_e = valve_areas(commands, row)
    n = commands.size
    starts = {"room": tab.room_pa, "supply": tab.supply_pa}
    traces = {}
    for label, p0 in starts.items():
        out = np.empty((int(round(duration / dt)) + 1, n))
        static_transient_fast(np.full(n, p0), np.full(n, volume), a_s, a_e, glob, dt, out)
        traces[label] = out
    time = np.arange(traces["room"].shape[0]) * dt
    k5 = int(round(5.0 / dt))
    p_eq = np.array([equilibrium_pressure(s, e, tab.gas, tab.supply_pa, tab.room_pa) for s, e in zip(a_s, a_e)])
    p5 = {k: v[k5] for k, v in traces.items()}
    t90s = np.array([max(t90(time, traces[k][:, i], starts[k], p_eq[i]) for k in starts) for i in range(n)])
    end_spread = np.abs(traces["room"][-1] - traces["supply"][-1])

    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.plot(commands, p_eq / 1e5, "k-", lw=1, label="asymptote (flow balance)")
    ax.plot(commands, p5["room"] / 1e5, "b.", label="after 5 s, from 1 bar")
    ax.plot(commands, p5["supply"] / 1e5, "bx", ms=4, label="after 5 s, from 7 bar")
    ax.set_xlabel("valve command [V]")
    ax.set_ylabel("pressure [bar abs]", color="b")
    ax.set_ylim(0.8, 7.2)
    ax2 = ax.twinx()
    ax2.plot(commands, t90s, "r-o", ms=3, label="time to 90 %")
    ax2.set_ylabel("time to 90 % of the asymptote [s]", color="r")
    ax.set_title("arm2 elbow chamber a, static volume (paper 002 Fig. 2A)")
    ax.legend(loc="upper left", fontsize=8)
    ctx.savefig(fig, "asymptotic_pressure.png")

    near = np.abs(commands - 5.0) < 1e-9
    full = (commands == 0.0) | (commands == 10.0)

    def at(v):
        return float(np.interp(v, commands, p_eq))

    return {
        "asymptote_spread_pa": float(end_spread.max()),
        "asymptote_spread_at_5s_pa": float(np.abs(p5["room"] - p5["supply"]).max()),
        "asymptote_monotone": bool(np.all(np.diff(p_eq) >= -1e-6)),
        "asymptote_4_5v_pa": at(4.5),
        "asymptote_5v_pa": at(5.0),
        "asymptote_5_5v_pa": at(5.5),
        "t90_near_null_s": float(t90s[near][0]),
        "t90_full_open_s": float(t90s[full].max()),
        "t90_argmax_v": float(commands[np.nanargmax(t90s)]),
        "duration_s": duration,
    }


if __name__ == "__main__":
    main(__name__)
