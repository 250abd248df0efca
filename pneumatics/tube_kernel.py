"""Compiled twin of :func:`pneumatics.effects.line_dynamics.rc_line_step`: one lumped line
(line_dynamics, lumped_rc form) and its chamber over one step, for the simulator's fast path
and the doctor's compiled replays (identification.doctor.valve_arm.chamber_kernel) alike.

The same arithmetic as the numpy reference, sub-step for sub-step (``tests/test_tube_kernel.py``
checks them against each other); a Python step of it costs tens of microseconds of small
numpy calls a sub-step, this one a few hundred nanoseconds.  ``glob`` is
:func:`pneumatics.kernel.pack_glob`'s array (R, T, n, room pressure).
"""
from __future__ import annotations

import math

import numba

from .effects.line_dynamics import GAMMA, MAX_SUBSTEPS, QUASI_STEADY_ITERATIONS, SUBSTEP_RATE
from .kernel import clearance_flow_compiled, orifice_flow_compiled


@numba.njit(cache=True, error_model="numpy", inline="always")
def _valve_into_tube(q, a_s, a_e, g_s, g_e, ps, glob):
    """(mdot, d mdot / d p_t) [kg/s, kg/(s Pa)] of a valve into its tube at pressure q: the
    supply and exhaust orifices and the lands' clearances (effects.valve_leak.clearance_flows)."""
    room = glob[9]
    ms, _, dms = orifice_flow_compiled(a_s, ps, q, glob)
    me, dme, _ = orifice_flow_compiled(a_e, q, room, glob)
    m, dm = ms - me, dms - dme
    if g_s > 0.0 or g_e > 0.0:
        m += clearance_flow_compiled(q, g_s, g_e, ps, room)
        dm -= (g_s + g_e) * q / room
    return m, dm


@numba.njit(cache=True, error_model="numpy", inline="always")
def _rates(q_t, q, k_t, k_c, g, rt, other_flow, volume_rate, a_s, a_e, g_s, g_e, ps, glob):
    """(dp_t/dt, dp/dt, d mdot_valve / d p_t) of the pair (effects.line_dynamics.rc_line_step)."""
    m_v, dm_v = _valve_into_tube(q_t, a_s, a_e, g_s, g_e, ps, glob)
    m_x = g * (q_t - q)
    return k_t * (m_v - m_x), k_c * (rt * (m_x + other_flow) - q * volume_rate), dm_v


@numba.njit(cache=True, error_model="numpy")
def rc_line_step_compiled(p_tube, p, volume, volume_rate, tube_volume, time_constant, a_s, a_e, g_s, g_e, ps,
                          other_flow, glob, dt):
    """(p_t, p) [Pa] after ``dt``: effects.line_dynamics.rc_line_step with the valve's flow from
    its areas ``a_s``, ``a_e`` [m^2] and land conductances ``g_s``, ``g_e`` [kg/(s Pa)] at the
    supply pressure ``ps`` [Pa]."""
    rt, n = glob[0] * glob[2], glob[3]
    g = tube_volume / (n * rt * time_constant)
    k_t, k_c = n * rt / tube_volume, n / volume
    slope = _valve_into_tube(p_tube, a_s, a_e, g_s, g_e, ps, glob)[1]
    rate = k_t * (abs(slope) + g)
    steps = int(min(MAX_SUBSTEPS, max(1, math.ceil(dt * rate / SUBSTEP_RATE))))
    h = dt / steps
    for _ in range(steps):
        f_t, f_c, dm_v = _rates(p_tube, p, k_t, k_c, g, rt, other_flow, volume_rate, a_s, a_e, g_s, g_e, ps, glob)
        a11, a12 = 1.0 - GAMMA * h * k_t * (dm_v - g), -GAMMA * h * k_t * g
        a21, a22 = -GAMMA * h * k_c * rt * g, 1.0 + GAMMA * h * k_c * (rt * g + volume_rate)
        det = a11 * a22 - a12 * a21
        k1_t, k1_c = (f_t * a22 - a12 * f_c) / det, (a11 * f_c - a21 * f_t) / det
        f_t, f_c, _ = _rates(p_tube + h * k1_t, p + h * k1_c, k_t, k_c, g, rt, other_flow, volume_rate, a_s, a_e,
                             g_s, g_e, ps, glob)
        b_t, b_c = f_t - 2.0 * k1_t, f_c - 2.0 * k1_c
        k2_t, k2_c = (b_t * a22 - a12 * b_c) / det, (a11 * b_c - a21 * b_t) / det
        p_tube = max(p_tube + h * (1.5 * k1_t + 0.5 * k2_t), 1.0)
        p = max(p + h * (1.5 * k1_c + 0.5 * k2_c), 1.0)
    return p_tube, p


@numba.njit(cache=True, error_model="numpy")
def tube_quasi_steady_compiled(p, tube_volume, time_constant, a_s, a_e, g_s, g_e, ps, glob):
    """effects.line_dynamics.tube_quasi_steady for the valve of areas ``a_s``, ``a_e`` and land
    conductances ``g_s``, ``g_e`` at the supply pressure ``ps``, between the room and the supply."""
    g = tube_volume / (glob[3] * glob[0] * glob[2] * time_constant)
    lo, hi = min(glob[9], p), max(ps, p)
    x = p
    for _ in range(QUASI_STEADY_ITERATIONS):
        m_v, dm_v = _valve_into_tube(x, a_s, a_e, g_s, g_e, ps, glob)
        f, df = m_v - g * (x - p), dm_v - g
        if f > 0.0:
            lo = x
        else:
            hi = x
        step = x - f / df if df < 0.0 else 0.5 * (lo + hi)
        x = step if lo < step < hi else 0.5 * (lo + hi)
    return x


#: a chamber volume [m^3] that holds its pressure over a step: the tube warmed up against the
#: measured chamber pressure (:func:`warm_tubes_compiled`)
PINNED_VOLUME_M3 = 1e30


@numba.njit(cache=True, error_model="numpy")
def warm_tubes_compiled(p_chamber, a_s, a_e, g_s, g_e, first, lead, tube_volume, time_constant, ps, glob, out):
    """``out`` (W,) the tube pressure [Pa] where each replay window starts (fine steps
    ``first`` (W,)): settled (:func:`tube_quasi_steady_compiled`) ``lead`` fine steps earlier,
    then stepped to the start against the chamber's measured pressure ``p_chamber`` (F,), held
    by PINNED_VOLUME_M3 over each step, with the valve's areas ``a_s``, ``a_e`` [m^2] and land
    conductances ``g_s``, ``g_e`` (F,) on the fine grid.  The tube's state then carries the
    valve's recent history, which a replay starting from the chamber's pressure alone lacks."""
    dt = glob[10]
    for w in range(first.size):
        f0 = max(first[w] - lead, 0)
        pt = tube_quasi_steady_compiled(p_chamber[f0], tube_volume, time_constant, a_s[f0], a_e[f0], g_s[f0],
                                        g_e[f0], ps, glob)
        for f in range(f0, first[w]):
            pt = rc_line_step_compiled(pt, p_chamber[f], PINNED_VOLUME_M3, 0.0, tube_volume, time_constant,
                                       a_s[f], a_e[f], g_s[f], g_e[f], ps, 0.0, glob, dt)[0]
        out[w] = pt


@numba.njit(cache=True, error_model="numpy")
def tube_path_compiled(p_chamber, a_s, a_e, g_s, g_e, tube_volume, time_constant, ps, glob, out):
    """``out`` (F,) the tube pressure [Pa] at every fine step along a recording: settled at the
    first, then stepped against the chamber's measured pressure ``p_chamber`` (F,) as in
    :func:`warm_tubes_compiled` (the doctor's mass-flow equation error of a lumped line's
    chamber: the flow the tube passes it, G (p_t - p))."""
    dt = glob[10]
    out[0] = tube_quasi_steady_compiled(p_chamber[0], tube_volume, time_constant, a_s[0], a_e[0], g_s[0], g_e[0],
                                        ps, glob)
    for f in range(p_chamber.size - 1):
        out[f + 1] = rc_line_step_compiled(out[f], p_chamber[f], PINNED_VOLUME_M3, 0.0, tube_volume, time_constant,
                                           a_s[f], a_e[f], g_s[f], g_e[f], ps, 0.0, glob, dt)[0]
