"""Gas temperatures for the heat_transfer hypothesis: an open-loop observer driven by the data.

A pressure replay starts each window from the measured pressures, but a chamber that carries
its gas temperature also needs T at the window's start, and no sensor measures it.  Its
thermal memory (tau = m c_v / (h A), 0.1-3 s on arm2) is longer than a window, so T is
carried through the whole recording by the energy equation with the *measured* pressure in
place of the modelled one (Richer & Hurmuzlu 2000 eq. 11 with p V = m R T eliminated)::

    dT/dt = T / (p V) [ R (k T_in - T) mdot_in + (k - 1) R T mdot_out
                        - (k - 1) p dV/dt + (k - 1) h A (T_w - T) ]

(mdot_in >= 0 enters at T_in, mdot_out <= 0 leaves at T; the flows are the model's at the
measured pressures; a piston leak is left out of this observer, the replays carry it).  Its
errors decay with tau, so the estimate forgets its start.  A numba
kernel runs the 1 ms loop; :func:`track_reference` is the readable numpy twin the tests compare.
"""
from __future__ import annotations

import numpy as np

from pneumatics.medium import orifice_flow
from pneumatics.valve import valve_areas

from .data import FINE_DT, Experiment, fine_pressures

try:
    from numba import njit
except ImportError:  # pragma: no cover - numba is a dependency; the reference runs without it
    njit = None


def _inputs(exp: Experiment, mods, chambers, u_fine: np.ndarray):
    """Per thermal chamber on the 1 ms grid (F, n): measured p, V, dV/dt, inflow, outflow
    (at the reference temperature), and the conductance (n,)."""
    tab, gas = exp.robot.tables, exp.robot.tables.gas
    cs = np.asarray(chambers, int)
    F = exp.fine_t.size
    p = np.maximum(fine_pressures(exp, mods, cs), 1e3)
    act = tab.actuator_of_chamber[cs]
    x = np.clip(exp.fine_length[:, act] - tab.length_zero[act], 0.0, tab.stroke[act])
    travel = np.where(tab.is_a[cs], x, tab.stroke[act] - x)
    dead = tab.dead_volume[cs] * mods.dead_volume_scale[cs]
    if mods.extra_volume_m3 is not None:
        dead = dead + mods.extra_volume_m3[cs]
    vol = dead + tab.area[cs] * travel
    vdot = np.gradient(vol, FINE_DT, axis=0)
    rows = np.repeat(tab.valve[cs][None], F, 0).reshape(-1, 8)
    a_s, a_e = valve_areas(u_fine[:, cs].ravel(), rows)
    a_s = a_s.reshape(F, -1) * mods.supply_scale[cs]
    a_e = a_e.reshape(F, -1) * mods.exhaust_scale[cs]
    leak_s, leak_e = mods.valve_leak_areas(u_fine[:, cs], tab.valve[cs, 0], cs)
    a_s, a_e = a_s + leak_s, a_e + leak_e
    m = orifice_flow(a_s, tab.supply_pa, p, gas)[0] - orifice_flow(a_e, p, tab.room_pa, gas)[0]
    m = m - mods.external_leak_flow(p, tab.room_pa, gas, cs)[0]
    m = m + mods.valve_clearance_flow(u_fine[:, cs], tab.valve[cs, 0], p, tab.supply_pa, tab.room_pa, cs)[0]
    return p, vol, vdot, np.maximum(m, 0.0), np.minimum(m, 0.0), mods.heat_w_k[cs]


def _rate(T, p, v, vdot, m_in, m_out_ref, hA, R, k, t_ref):
    m_out = m_out_ref * np.sqrt(t_ref / T)
    return T / (p * v) * (R * (k * t_ref - T) * m_in + (k - 1) * R * T * m_out
                          - (k - 1) * p * vdot + (k - 1) * hA * (t_ref - T))


def track_reference(p, vol, vdot, m_in, m_out, hA, R, k, t_ref, dt=FINE_DT):
    """(F, n) gas temperatures [K] by Heun's method from T = t_ref; inputs (F, n), hA (n,)."""
    T = np.empty_like(p)
    T[0] = t_ref
    for i in range(p.shape[0] - 1):
        a = _rate(T[i], p[i], vol[i], vdot[i], m_in[i], m_out[i], hA, R, k, t_ref)
        guess = T[i] + dt * a
        b = _rate(guess, p[i + 1], vol[i + 1], vdot[i + 1], m_in[i + 1], m_out[i + 1], hA, R, k, t_ref)
        T[i + 1] = np.clip(T[i] + 0.5 * dt * (a + b), 0.5 * t_ref, 3.0 * t_ref)
    return T


if njit is not None:
    @njit(cache=True)
    def track_compiled(p, vol, vdot, m_in, m_out, hA, R, k, t_ref, dt):  # pragma: no cover - compiled
        """:func:`track_reference` compiled (the same Heun steps, chamber by chamber)."""
        F, n = p.shape
        T = np.empty((F, n))
        for c in range(n):
            T[0, c] = t_ref
            for i in range(F - 1):
                Ti = T[i, c]
                a = Ti / (p[i, c] * vol[i, c]) * (R * (k * t_ref - Ti) * m_in[i, c]
                                                  + (k - 1) * R * Ti * m_out[i, c] * np.sqrt(t_ref / Ti)
                                                  - (k - 1) * p[i, c] * vdot[i, c] + (k - 1) * hA[c] * (t_ref - Ti))
                g = Ti + dt * a
                j = i + 1
                b = g / (p[j, c] * vol[j, c]) * (R * (k * t_ref - g) * m_in[j, c]
                                                 + (k - 1) * R * g * m_out[j, c] * np.sqrt(t_ref / g)
                                                 - (k - 1) * p[j, c] * vdot[j, c] + (k - 1) * hA[c] * (t_ref - g))
                T[j, c] = min(max(Ti + 0.5 * dt * (a + b), 0.5 * t_ref), 3.0 * t_ref)
        return T


def gas_temperatures(exp: Experiment, mods, u_fine: np.ndarray, compiled: bool = True) -> np.ndarray:
    """(F, C) gas temperature [K] of every chamber on the 1 ms grid: tracked for the chambers
    with a heat_transfer conductance (``mods.heat_w_k`` not NaN), the reference temperature
    elsewhere.  ``u_fine`` (F, C) are the effective valve commands."""
    gas = exp.robot.tables.gas
    out = np.full((exp.fine_t.size, exp.robot.tables.n_chambers), gas.temperature_k)
    if mods.heat_w_k is None:
        return out
    cs = np.nonzero(np.isfinite(mods.heat_w_k))[0]
    if cs.size == 0:
        return out
    args = _inputs(exp, mods, cs, u_fine)
    consts = (gas.gas_constant_j_per_kg_k, gas.heat_capacity_ratio, gas.temperature_k)
    if compiled and njit is not None:
        T = track_compiled(*[np.ascontiguousarray(a, float) for a in args], *consts, FINE_DT)
    else:
        T = track_reference(*args, *consts)
    out[:, cs] = T
    return out
