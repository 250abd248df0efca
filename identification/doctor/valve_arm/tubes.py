"""The doctor's lumped lines (line_dynamics, lumped_rc): where a replay window starts its tube,
the tube's step in the numpy reference, and the valve's flow into the tube.

A lumped line's tube has a pressure of its own that no sensor reads; only the chamber's is
measured.  A replay window that started its tube at the chamber's pressure would begin with
the resistance's drop missing (0.3-1 kPa RMS over a 0.3 s replay of the round trip, a valve
wide open into a 10 ms tube), so each tube is started from its own history: settled
TUBE_LEAD_TIME_CONSTANTS of its time constant before the window, then stepped against the
measured chamber pressure (:func:`start_tubes`; pneumatics.tube_kernel.warm_tubes_compiled).
"""
from __future__ import annotations

import numpy as np

from pneumatics.effects.line_dynamics import rc_line_step, tube_conductance, tube_quasi_steady, valve_into_tube
from pneumatics.tube_kernel import warm_tubes_compiled
from pneumatics.valve import valve_areas

from .data import FINE_DT, fine_pressures

#: a replay window's tube starts settled this many of its time constants earlier, then follows
#: the valve against the chamber's measured pressure, at most TUBE_LEAD_MAX_STEPS fine steps
TUBE_LEAD_TIME_CONSTANTS, TUBE_LEAD_MAX_STEPS = 5.0, 500


def has_tubes(mods) -> bool:
    return mods.tube_volume_m3 is not None and bool(np.any(mods.tube_volume_m3 > 0))


def tube_valve(tab, mods, u: np.ndarray, c: int):
    """(supply area, exhaust area, supply-land conductance, exhaust-land conductance), each
    (F,), of chamber c's valve at its commands ``u`` (F,) [V] under the chamber model ``mods``:
    the valve's flow into a lumped line's tube (pneumatic.model_areas for the one valve;
    effects.valve_leak.clearance_conductances)."""
    u = np.asarray(u, float)
    a_s, a_e = valve_areas(u[:, None], tab.valve[c:c + 1])
    leak_s, leak_e = mods.valve_leak_areas(u[:, None], tab.valve[c:c + 1, 0], slice(c, c + 1))
    a_s, a_e = (a_s * mods.supply_scale[c] + leak_s)[:, 0], (a_e * mods.exhaust_scale[c] + leak_e)[:, 0]
    g_s, g_e = mods.valve_clearance_conductances(u, tab.valve[c, 0], c)
    return tuple(np.ascontiguousarray(np.broadcast_to(x, u.shape), float) for x in (a_s, a_e, g_s, g_e))


def start_tubes(model, exp, u_fine: np.ndarray, first: np.ndarray) -> None:
    """``model.p_tube`` (a pneumatic.ChamberModel's) where its windows start (fine steps
    ``first`` (W,)), ``u_fine`` (F, C) every chamber's effective commands: each tube warmed up
    (module docstring) at the nominal supply."""
    mods, tab = model.mods, model.tab
    if not has_tubes(mods):
        return
    own = np.arange(tab.n_chambers) if model.chambers is None else np.asarray(model.chambers)
    glob = model.kernel_glob()
    first = np.ascontiguousarray(first, np.int64)
    for k, c in enumerate(own):
        if not mods.tube_volume_m3[c] > 0:
            continue
        tau = float(mods.tube_time_constant_s[c])
        lead = int(min(TUBE_LEAD_MAX_STEPS, np.ceil(TUBE_LEAD_TIME_CONSTANTS * tau / FINE_DT)))
        a_s, a_e, g_s, g_e = tube_valve(tab, mods, u_fine[:, c], c)
        p_meas = np.ascontiguousarray(fine_pressures(exp, mods, [c])[:, 0])
        out = np.empty(first.size)
        warm_tubes_compiled(p_meas, a_s, a_e, g_s, g_e, first, lead, float(mods.tube_volume_m3[c]), tau,
                            float(tab.supply_pa), glob, out)
        model.p_tube[: first.size, k] = out


def tube_step_reference(model, p, p_new, u, a_s, a_e, vol, vdot, ps):
    """The numpy reference (ChamberModel.step_reference) of the lumped lines' chambers, a window
    and a chamber at a time, by effects.line_dynamics.rc_line_step from the step's start, their
    leaks held there; ``p_new`` (W, C) with those chambers replaced.  A tube not started yet
    (NaN) starts settled (effects.line_dynamics.tube_quasi_steady)."""
    mods, tab, gas = model.mods, model.tab, model.gas
    room = tab.room_pa
    ps = np.broadcast_to(ps, p.shape)
    other = mods.chamber_leak_flow(p, room, gas)
    g_s, g_e = (np.broadcast_to(g, p.shape) for g in mods.valve_clearance_conductances(u, tab.valve[:, 0]))
    p_new = p_new.copy()
    for c in np.nonzero(mods.tube_volume_m3 > 0)[0]:
        g = float(tube_conductance(mods.tube_volume_m3[c], mods.tube_time_constant_s[c], model.n, model.rt))
        for w in range(p.shape[0]):
            valve_flow = valve_into_tube(a_s[w, c], a_e[w, c], g_s[w, c], g_e[w, c], ps[w, c], room, gas)
            start = model.p_tube[w, c]
            if not np.isfinite(start):
                start = tube_quasi_steady(float(p[w, c]), g, valve_flow, room, float(ps[w, c]))
            model.p_tube[w, c], p_new[w, c] = rc_line_step(
                float(start), float(p[w, c]), float(vol[w, c]), float(vdot[w, c]), float(mods.tube_volume_m3[c]),
                float(mods.tube_time_constant_s[c]), valve_flow, float(other[w, c]), model.n, model.rt, FINE_DT)
    return p_new
