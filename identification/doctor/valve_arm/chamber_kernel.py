"""Compiled twin of :meth:`identification.doctor.valve_arm.pneumatic.ChamberModel.step_reference`: one 1 ms step
of paper 002 eq. 9 for a batch (W, C) of chamber sets, with the doctor's pneumatic hypotheses
(valve leak near null or through the lands' clearances, external and piston leaks, calibration scales, supply droop, heat transfer;
a compliant wall, which the check of a line's constant volume fits).

The doctor replays a recording hundreds of times (calibration, every hypothesis, the held-out
scores); in numpy each step costs ~4 ms of small-array calls, most of the doctor's time.  This
loop costs a few microseconds.  ``tests/test_chamber_kernel.py`` checks it against the numpy
reference to round-off, effect by effect.

Arrays (C chambers, ordered a, b per actuator; W windows):
  p, u, travel0, travel1, out (W, C) [Pa, V, m, m, Pa];  rows (C, 8) valve columns
  (pneumatics.valve.VALVE_COLUMNS);  supply_scale, exhaust_scale, valve_leak_m2, underlap_m2,
  underlap_width_v, clearance_g (valve_leak's clearance form: each land's conductance at null
  [kg/(s Pa)]), clearance_width_v, external_leak_m2,
  external_leak_g, dead_m3, area_m2 (C,);  piston_leak_m2, piston_leak_g (C // 2,) (the *_g are the
  laminar forms' conductances [kg/(s Pa)], pneumatics.effects.external_leak.laminar_flow);  m_supply (W,) total supply flow of the last
  step [kg/s], low-passed with the droop's time constant glob[14] (read for the droop, then updated);  glob as in :mod:`pneumatics.kernel`;
  wall (C,) a compliant wall's dV/dp [m^3/Pa] (0: rigid);  supply_shift (W,) each window's supply
  pressure minus the table's [Pa] (a receiver's, supply_receiver);  tube_m3, tube_tau_s (C,) a
  lumped line's tube volume [m^3] (0: none) and time constant [s], p_tube (W, C) its pressure
  [Pa] (a state; NaN until the first step starts it settled).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from pneumatics.effects.valve_leak import COVER_MIN
from pneumatics.kernel import GAMMA, QUADRATIC_DROOP, clearance_flow_compiled, orifice_flow_compiled
from pneumatics.tube_kernel import rc_line_step_compiled, tube_quasi_steady_compiled


@numba.njit(cache=True, error_model="numpy")
def _valve(u, row, scale_s, scale_e, leak_s, leak_e, leak_width, lap, lap_width):
    """pneumatics.valve.valve_areas for one command, scaled, plus the valve_leak hypothesis
    (extra supply-side and exhaust-side areas near null; an underlapped spool's shifted areas,
    pneumatics.effects.valve_leak.underlap_areas)."""
    null, half, f, width, dead, gam, a_s, a_e = row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7]
    s = min(max((u - null) / half, -1.0), 1.0)
    w = width / half
    d = dead / half
    lk = f * math.exp(-(s / w) ** 2)
    ramp_s = max(0.0, (s - d) / (1.0 - d)) ** gam
    ramp_e = max(0.0, (-s - d) / (1.0 - d)) ** gam
    out_s = a_s * (lk + (1.0 - f) * ramp_s) * scale_s
    out_e = a_e * (lk + (1.0 - f) * ramp_e) * scale_e
    if leak_s > 0.0 or leak_e > 0.0:
        g = math.exp(-((u - null) / leak_width) ** 2)
        out_s += leak_s * g
        out_e += leak_e * g
    if lap > 0.0:
        x = (u - null) / lap_width
        out_s += lap * min(1.0, max(0.0, 1.0 + x))
        out_e += lap * min(1.0, max(0.0, 1.0 - x))
    return out_s, out_e


@numba.njit(cache=True, error_model="numpy", inline="always")
def _clearance(u, null, g, width):
    """pneumatics.effects.valve_leak.clearance_conductances for one command: (supply, exhaust)."""
    x = (u - null) / width
    return g / max(COVER_MIN, 1.0 - x), g / max(COVER_MIN, 1.0 + x)


@numba.njit(cache=True, error_model="numpy")
def _rhs(q, vol, vdot, a_s, a_e, g_s, g_e, ext, piston, ext_g, piston_g, ps, glob, f, jac, m_s, wall):
    """Pressure rates f and their diagonal Jacobian jac (C,) at pressures q (C,); ``g_s``, ``g_e``
    (C,) the valves' land clearance conductances at the command (valve_leak, clearance form);
    ``wall`` (C,) a compliant wall's dV/dp [m^3/Pa] (pneumatic.capacity)."""
    rt, n, room = glob[0] * glob[2], glob[3], glob[9]
    C = q.shape[0]
    m = np.empty(C)
    dm = np.empty(C)
    for c in range(C):
        ms, _, dms = orifice_flow_compiled(a_s[c], ps, q[c], glob)
        me, dme, _ = orifice_flow_compiled(a_e[c], q[c], room, glob)
        m[c] = ms - me
        dm[c] = dms - dme
        m_s[c] = ms
        if ext[c] > 0.0:
            mx, dmx, _ = orifice_flow_compiled(ext[c], q[c], room, glob)
            m[c] -= mx
            dm[c] -= dmx
        if ext_g[c] > 0.0:  # laminar: G (p^2 - p_room^2) / (2 p_room)
            m[c] -= ext_g[c] * (q[c] - room) * (q[c] + room) / (2.0 * room)
            dm[c] -= ext_g[c] * q[c] / room
        if g_s[c] > 0.0 or g_e[c] > 0.0:  # the lands' clearances (effects.valve_leak.clearance_flows)
            m[c] += clearance_flow_compiled(q[c], g_s[c], g_e[c], ps, room)
            dm[c] -= (g_s[c] + g_e[c]) * q[c] / room
    for j in range(C // 2):
        if piston[j] > 0.0:
            mab, da, db = orifice_flow_compiled(piston[j], q[2 * j], q[2 * j + 1], glob)
            m[2 * j] -= mab
            m[2 * j + 1] += mab
            dm[2 * j] -= da
            dm[2 * j + 1] += db
        if piston_g[j] > 0.0:
            qa, qb = q[2 * j], q[2 * j + 1]
            mab = piston_g[j] * (qa - qb) * (qa + qb) / (2.0 * room)
            m[2 * j] -= mab
            m[2 * j + 1] += mab
            dm[2 * j] -= piston_g[j] * qa / room
            dm[2 * j + 1] -= piston_g[j] * qb / room
    for c in range(C):
        cap = vol[c] + wall[c] * (q[c] - room) + n * q[c] * wall[c]
        f[c] = n / cap * (rt * m[c] - q[c] * vdot[c])
        jac[c] = n / cap * (rt * dm[c] - vdot[c])


@numba.njit(cache=True, error_model="numpy")
def _flows_thermal(q, T, a_s, a_e, ps, extra, glob):
    """pneumatics.effects.heat_transfer.chamber_flows for one chamber: (mdot, sum T_j mdot_j, its d/dp)."""
    room, t_ref = glob[9], glob[2]
    ms, _, dms = orifice_flow_compiled(a_s, ps, q, glob)
    me, dme, _ = orifice_flow_compiled(a_e, q, room, glob)
    scale = math.sqrt(t_ref / T)
    mdot, h, dh = 0.0, 0.0, 0.0
    for m, dm in ((ms, dms), (-me, -dme), (extra, 0.0)):
        if m < 0.0:
            mdot += m * scale
            h += T * m * scale
            dh += T * dm * scale
        else:
            mdot += m
            h += t_ref * m
            dh += t_ref * dm
    return mdot, h, dh


@numba.njit(cache=True, error_model="numpy")
def _thermal(p, T, vol, vdot, a_s, a_e, ps, hA, extra, glob):
    """pneumatics.effects.heat_transfer.thermal_step for one chamber: (p, T) after dt."""
    R, k, t_ref, dt = glob[0], glob[1], glob[2], glob[10]
    heat = (k - 1.0) * hA * (t_ref - T)
    _, h0, dh0 = _flows_thermal(p, T, a_s, a_e, ps, extra, glob)
    f0 = (k * R * h0 - k * p * vdot + heat) / vol
    denom = 1.0 - GAMMA * dt * (k * R * dh0 - k * vdot) / vol
    k1 = f0 / denom
    _, h1, _ = _flows_thermal(p + dt * k1, T, a_s, a_e, ps, extra, glob)
    f1 = (k * R * h1 - k * (p + dt * k1) * vdot + heat) / vol
    k2 = (f1 - 2.0 * k1) / denom
    p_new = p + 1.5 * dt * k1 + 0.5 * dt * k2
    mdot, _, _ = _flows_thermal(0.5 * (p + p_new), T, a_s, a_e, ps, extra, glob)
    m0 = p * (vol - 0.5 * dt * vdot) / (R * T)
    m1 = max(m0 + dt * mdot, 1e-3 * m0)
    return p_new, p_new * (vol + 0.5 * dt * vdot) / (R * m1)


@numba.njit(cache=True, error_model="numpy")
def step_batch(p, u, travel0, travel1, rows, supply_scale, exhaust_scale, valve_leak_m2, valve_leak_exhaust_m2,
               leak_width_v, underlap_m2, underlap_width_v, clearance_g, clearance_width_v,
               external_leak_m2, piston_leak_m2, external_leak_g, piston_leak_g, dead_m3, area_m2, m_supply, glob,
               out, heat_w_k, T, wall, supply_shift, tube_m3, tube_tau_s, p_tube):
    """One linearly implicit ROS2 step (chamber.integrate's stages, fixed dt) for every window.

    Chambers with a finite ``heat_w_k`` (C,) [W/K] carry their gas temperature ``T`` (W, C) [K]
    (updated in place) and follow the energy equation instead (heat_transfer), the leaks held
    over the step at their start-of-step flows, as in ChamberModel._thermal_step (a compliant
    ``wall`` (C,) [m^3/Pa] is not carried there: the check that uses it fits no heat transfer).
    Chambers with a tube volume ``tube_m3`` (C,) > 0 [m^3] behind a resistance of time constant
    ``tube_tau_s`` (C,) [s] (line_dynamics, lumped_rc) carry the tube's pressure ``p_tube``
    (W, C) [Pa] (updated in place; NaN: it starts settled, tube_quasi_steady) and take the lumped line's
    step instead (pneumatics.tube_kernel), their leaks held likewise; neither heat transfer nor
    a compliant wall is carried there."""
    W, C = p.shape
    dt, droop, droop2 = glob[10], glob[12], glob[QUADRATIC_DROOP]
    follow = dt / (glob[14] + dt)  # the reservoir form's low-pass of the supply flow (effects.supply_droop)
    a_s, a_e, g_s, g_e = np.empty(C), np.empty(C), np.zeros(C), np.zeros(C)
    vol, vdot = np.empty(C), np.empty(C)
    f0, jac, f1, jac1 = np.empty(C), np.empty(C), np.empty(C), np.empty(C)
    m_s, m_s1 = np.empty(C), np.empty(C)
    k1, q1 = np.empty(C), np.empty(C)
    for w in range(W):
        ps = glob[8] - (droop * m_supply[w] + droop2 * m_supply[w] * m_supply[w]) + supply_shift[w]
        for c in range(C):
            a_s[c], a_e[c] = _valve(u[w, c], rows[c], supply_scale[c], exhaust_scale[c], valve_leak_m2[c],
                                   valve_leak_exhaust_m2[c], leak_width_v, underlap_m2[c], underlap_width_v[c])
            if clearance_g[c] > 0.0:
                g_s[c], g_e[c] = _clearance(u[w, c], rows[c, 0], clearance_g[c], clearance_width_v[c])
            vol[c] = dead_m3[c] + area_m2[c] * 0.5 * (travel0[w, c] + travel1[w, c])
            vdot[c] = area_m2[c] * (travel1[w, c] - travel0[w, c]) / dt
        _rhs(p[w], vol, vdot, a_s, a_e, g_s, g_e, external_leak_m2, piston_leak_m2, external_leak_g, piston_leak_g, ps, glob,
             f0, jac, m_s, wall)
        for c in range(C):
            k1[c] = f0[c] / (1.0 - GAMMA * dt * jac[c])
            q1[c] = p[w, c] + dt * k1[c]
        _rhs(q1, vol, vdot, a_s, a_e, g_s, g_e, external_leak_m2, piston_leak_m2, external_leak_g, piston_leak_g, ps, glob,
             f1, jac1, m_s1, wall)
        total = 0.0
        for c in range(C):
            denom = 1.0 - GAMMA * dt * jac[c]
            k2 = (f1[c] - 2.0 * k1[c]) / denom
            q = p[w, c] + 1.5 * dt * k1[c] + 0.5 * dt * k2
            out[w, c] = q if (math.isfinite(q) and q > 0.0) else p[w, c]
            total += max(m_s[c], 0.0)
        m_supply[w] += (total - m_supply[w]) * follow
        for c in range(C):
            tube = tube_m3[c] > 0.0
            if not (tube or math.isfinite(heat_w_k[c])):
                continue
            extra = _chamber_leaks(p[w], c, external_leak_m2, piston_leak_m2, external_leak_g, piston_leak_g, glob)
            if tube:  # the lands' clearance flows enter the tube (tube_kernel._valve_into_tube)
                if not math.isfinite(p_tube[w, c]):  # a window's start: the tube settled
                    p_tube[w, c] = tube_quasi_steady_compiled(p[w, c], tube_m3[c], tube_tau_s[c], a_s[c], a_e[c],
                                                              g_s[c], g_e[c], ps, glob)
                p_tube[w, c], out[w, c] = rc_line_step_compiled(p_tube[w, c], p[w, c], vol[c], vdot[c], tube_m3[c],
                                                                tube_tau_s[c], a_s[c], a_e[c], g_s[c], g_e[c], ps,
                                                                extra, glob, dt)
                continue
            if g_s[c] > 0.0 or g_e[c] > 0.0:
                extra += clearance_flow_compiled(p[w, c], g_s[c], g_e[c], ps, glob[9])
            out[w, c], T[w, c] = _thermal(p[w, c], T[w, c], vol[c], vdot[c], a_s[c], a_e[c], ps, heat_w_k[c], extra, glob)


@numba.njit(cache=True, error_model="numpy")
def _chamber_leaks(q, c, external_leak_m2, piston_leak_m2, external_leak_g, piston_leak_g, glob):
    """The flow [kg/s] into chamber c at pressures q (C,) through its external and piston leaks
    (orifice and laminar forms): held over a step by the thermal and the lumped line's steps."""
    room = glob[9]
    extra = 0.0
    if external_leak_m2[c] > 0.0:
        extra -= orifice_flow_compiled(external_leak_m2[c], q[c], room, glob)[0]
    if external_leak_g[c] > 0.0:
        extra -= external_leak_g[c] * (q[c] - room) * (q[c] + room) / (2.0 * room)
    j = c // 2
    pa, pb = q[2 * j], q[2 * j + 1]
    mab = 0.0
    if piston_leak_m2[j] > 0.0:
        mab += orifice_flow_compiled(piston_leak_m2[j], pa, pb, glob)[0]
    if piston_leak_g[j] > 0.0:
        mab += piston_leak_g[j] * (pa - pb) * (pa + pb) / (2.0 * room)
    return extra - mab if c == 2 * j else extra + mab


@numba.njit(cache=True, error_model="numpy")
def replay_batch(p, u_fine, travel, first, horizon, n_sub, averaged, receiver, supply_pa, rows, supply_scale,
                 exhaust_scale, valve_leak_m2, valve_leak_exhaust_m2, leak_width_v, underlap_m2, underlap_width_v,
                 clearance_g, clearance_width_v, external_leak_m2, piston_leak_m2, external_leak_g, piston_leak_g,
                 dead_m3, area_m2, m_supply, glob, heat_w_k, T, wall, supply_shift, tube_m3, tube_tau_s, p_tube, out):
    """pneumatic.replay's loop over the fine steps, compiled: every window w starts at fine step
    ``first[w]`` from pressures ``p`` (W, C) and is stepped by :func:`step_batch` ``horizon`` x
    ``n_sub`` times with its commands ``u_fine`` (F, C) and travels ``travel`` (F, C); ``out``
    (W, horizon, C) gets each sample's pressure (the mean of its ``n_sub`` steps when
    ``averaged``).  A non-empty ``receiver`` (F,) [Pa] is the supply's path, read every step
    (ChamberModel.follow_supply).  The same arithmetic as the Python loop it replaces, step by
    step (tests/test_chamber_kernel.py), without its ~20 us of numpy calls a step."""
    W, C = p.shape
    last = travel.shape[0] - 1
    u, t0, t1 = np.empty((W, C)), np.empty((W, C)), np.empty((W, C))
    nxt, acc = np.empty((W, C)), np.zeros((W, C))
    for step in range(horizon * n_sub):
        for w in range(W):
            f = first[w] + step
            g = min(f + 1, last)
            for c in range(C):
                u[w, c] = u_fine[f, c]
                t0[w, c] = travel[f, c]
                t1[w, c] = travel[g, c]
            if receiver.size:
                supply_shift[w] = receiver[min(f, receiver.size - 1)] - supply_pa
        step_batch(p, u, t0, t1, rows, supply_scale, exhaust_scale, valve_leak_m2, valve_leak_exhaust_m2,
                   leak_width_v, underlap_m2, underlap_width_v, clearance_g, clearance_width_v, external_leak_m2,
                   piston_leak_m2, external_leak_g, piston_leak_g, dead_m3, area_m2, m_supply, glob, nxt, heat_w_k, T,
                   wall, supply_shift, tube_m3, tube_tau_s, p_tube)
        p, nxt = nxt, p
        acc += p
        if (step + 1) % n_sub == 0:
            k = (step + 1) // n_sub - 1
            if averaged:
                out[:, k] = acc / n_sub
            else:
                out[:, k] = p
            acc[:] = 0.0
