"""Paper 002 Fig. 2B: plasto-elasticity of the arm with its valves (nearly) closed.

Link 2 horizontal (as in Fig. 2C), elbow valves at null: chamber a at 5 V, chamber b trimmed
a quarter volt above so that the two null asymptotes balance the cylinder's unequal areas
at the start pose (a user trims it the same way; without it the area difference alone pushes
the joint).  First the experimenter *hits* the arm (a 60 ms torque pulse): the trapped air
springs it back to its old position, slightly under-damped.  Then the experimenter *holds* it
25 deg away for 2 s and lets go: through the valves' null leak the chambers re-equilibrate at
the new volumes, so the arm stays near where it was held — the equilibrium has moved.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from pneumatics.valve import valve_areas

from ._arm2 import deg, horizontal_elbow_sim
from .arm2_asymptotic_pressure import equilibrium_pressure
from .common import main, plt

SUMMARY = "Fig. 2B: plasto-elasticity at null valves: a push returns, a held displacement stays"
FITTED_MODEL = "arm2"  # takes --fitted: a doctor's model.toml of arm2 (scenarios.common)


def trimmed_null(tab, act=1):
    """(u_a, u_b, p_a, p_b): a at its null; b's command that balances the forces at asymptote."""
    ia, ib = 2 * act, 2 * act + 1

    def asym(u, ch):
        a_s, a_e = valve_areas(np.array([u]), tab.valve[ch][None])
        return equilibrium_pressure(a_s[0], a_e[0], tab.gas, tab.supply_pa, tab.room_pa)

    u_a = tab.valve[ia, 0]
    p_a = asym(u_a, ia)
    target_b = tab.room_pa + tab.area_a[act] / tab.area_b[act] * (p_a - tab.room_pa)
    null_b = tab.valve[ib, 0]
    u_b = brentq(lambda u: asym(u, ib) - target_b, null_b - 0.5, null_b + 0.5, xtol=1e-6)
    return u_a, u_b, p_a, target_b


def run(ctx):
    sim = horizontal_elbow_sim(ctx.load_robot("arm2"))
    tab = sim.tables
    u_a, u_b, p_a, p_b = trimmed_null(tab)
    sim.reset(qpos=[0.0, 0.0], pressure_pa=[4e5, 4e5, p_a, p_b])
    null = tab.valve[:, 0]
    sim.set_command([null[0], null[1], u_a, u_b])
    dof = sim.model.joint("elbow").dofadr[0]
    settle = 1.0 if ctx.fast else 2.0
    t_push, push_s, push_nm = settle, 0.06, 1.2
    t_hold = t_push + 2.0
    ramp_s, hold_s, hold_deg = 0.3, 2.0, 25.0
    t_release = t_hold + ramp_s + hold_s
    t_end = t_release + (2.0 if ctx.fast else 3.0)
    n = int(round(t_end / sim.dt))
    log_every = 5
    t, q, pa, pb, tau = [], [], [], [], []
    for k in range(n):
        now = sim.time
        qe, qde = sim.data.qpos[1], sim.data.qvel[1]
        if t_push <= now < t_push + push_s:
            f = push_nm
        elif t_hold <= now < t_release:
            target = np.radians(hold_deg) * min(1.0, (now - t_hold) / ramp_s)
            f = -40.0 * (qe - target) - 1.0 * qde  # the experimenter's hand: a stiff spring
        else:
            f = 0.0
        sim.data.qfrc_applied[dof] = f
        sim.step(1)
        if k % log_every == 0:
            t.append(now)
            q.append(qe)
            pa.append(sim.pressure[2])
            pb.append(sim.pressure[3])
            tau.append(f)
    t, q, pa, pb, tau = map(np.asarray, (t, q, pa, pb, tau))

    def q_at(time_s):
        return float(np.interp(time_s, t, q))

    before = q_at(t_push - 0.01)
    after_push = q_at(t_hold - 0.01)
    after_hold = q_at(t_end - 0.01)
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    axes[0].plot(t, deg(q))
    axes[0].axhline(deg(before), color="gray", ls=":", lw=0.8)
    axes[0].set_ylabel("elbow angle [deg]")
    axes[1].plot(t, tau)
    axes[1].set_ylabel("external torque [N m]\n(push, then hold)")
    axes[2].plot(t, pa / 1e5, label="chamber a")
    axes[2].plot(t, pb / 1e5, label="chamber b")
    axes[2].set_ylabel("pressure [bar abs]")
    axes[2].set_xlabel("time [s]")
    axes[2].legend(fontsize=8)
    axes[0].set_title(f"arm2 elbow, valves at null (a {u_a:.3f} V, b {u_b:.3f} V): paper 002 Fig. 2B")
    fig.tight_layout()
    ctx.savefig(fig, "plastoelastic.png")
    return {
        "return_error_deg": abs(deg(after_push - before)),
        "push_excursion_deg": float(np.max(np.abs(deg(q[(t >= t_push) & (t < t_hold)] - before)))),
        "equilibrium_shift_deg": abs(deg(after_hold - before)),
        "held_displacement_deg": hold_deg,
        "trim_u_b_v": u_b,
    }


if __name__ == "__main__":
    main(__name__)
