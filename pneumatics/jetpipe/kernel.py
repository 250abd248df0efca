"""The jet-pipe plant step compiled with numba: the arithmetic of plant.py/chambers.py/ports.py
in scalar form (same equations, same order; tests/test_jetpipe.py checks they agree).

``pack(cfg)`` flattens the parameters into one float64 array; ``step(y, plays, radii, i_cmd,
q, qd, h, n_sub, prm)`` advances the state y (6,) and the play outputs (n,) in place by n_sub
RK4 substeps of h [s] (hysteresis advanced at the start of each substep, as in plant.py).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .params import JetpipeCfg

# indices into the packed parameter array
(W_D, I_MAX, K_M, W1, W2, ZETA, X_SAT, F_SAT, X_OFF, R_JET, R_FLANGE, C_PORT, CD, LEAK_SLOPE,
 LEAK_OFFSET, A_P, STROKE, VD1, VD2, P_S, P_R, RT, N_POLY, GAMMA, R_C, R_L, C_CHOKE, C_SUB) = range(28)


def pack(cfg: JetpipeCfg) -> np.ndarray:
    """(28,) float64 parameters for the compiled step."""
    g, d, j, p, lk, c, s = cfg.gas, cfg.driver, cfg.jet, cfg.ports, cfg.leak, cfg.cylinder, cfg.supply
    return np.array([
        2.0 * math.pi * d.corner_hz, d.current_limit_a, d.force_constant_n_per_a,
        j.omega1_rad_s, j.omega2_rad_s, j.damping_ratio, j.saturation_m, j.saturation_force_n, j.offset_m,
        p.jet_diameter_m / 2.0, p.flange_diameter_m / 2.0, p.port_centre_m, p.discharge_coefficient,
        lk.slope_m2, lk.offset_m2, c.piston_area_m2, c.stroke_m, c.dead_volume_1_m3, c.dead_volume_2_m3,
        s.supply_pa, s.room_pa, g.gas_constant_j_per_kg_k * g.temperature_k, g.polytropic_exponent,
        g.heat_capacity_ratio, g.critical_ratio, g.laminar_ratio, g.c_choke, g.c_sub], dtype=np.float64)


@njit(cache=True)
def lens(r1, r2, d):
    """Overlap area of two circles (ports.circle_overlap, scalar)."""
    d = abs(d)
    a, b = min(r1, r2), max(r1, r2)
    if d >= a + b:
        return 0.0
    if d <= b - a:
        return math.pi * a * a
    ca = min(max((d * d + a * a - b * b) / (2.0 * d * a), -1.0), 1.0)
    cb = min(max((d * d + b * b - a * a) / (2.0 * d * b), -1.0), 1.0)
    k = (-d + a + b) * (d + a - b) * (d - a + b) * (d + a + b)
    return a * a * math.acos(ca) + b * b * math.acos(cb) - 0.5 * math.sqrt(max(k, 0.0))


@njit(cache=True)
def _psi(r, k):
    return math.sqrt(max(r ** (2.0 / k) - r ** ((k + 1.0) / k), 0.0))


@njit(cache=True)
def flow(area, p_from, p_to, prm):
    """Signed mass flow [kg/s] through effective area ``area`` (medium.orifice_flow, scalar)."""
    if area <= 0.0:
        return 0.0
    sign = 1.0
    hi, lo = p_from, p_to
    if p_to > p_from:
        sign, hi, lo = -1.0, p_to, p_from
    r = lo / hi
    k = prm[GAMMA]
    if r <= prm[R_C]:
        f = prm[C_CHOKE] * hi
    elif r <= prm[R_L]:
        f = prm[C_SUB] * hi * _psi(r, k)
    else:
        f = prm[C_SUB] * _psi(prm[R_L], k) / (1.0 - prm[R_L]) * (hi - lo)
    return sign * area * f


@njit(cache=True)
def rhs(y, out, i_cmd, f_hyst, q, qd, prm):
    """dy/dt into ``out`` (6,) (plant.rhs, scalar)."""
    cmd = min(max(i_cmd, -prm[I_MAX]), prm[I_MAX])
    out[0] = prm[W_D] * (cmd - y[0])
    x_st = prm[X_SAT] * math.tanh(f_hyst / prm[F_SAT])
    w1, w2 = prm[W1], prm[W2]
    out[1] = w1 * (x_st - y[1])
    out[2] = y[3]
    out[3] = w2 * w2 * (y[1] - y[2]) - 2.0 * prm[ZETA] * w2 * y[3]
    x = y[2] + prm[X_OFF]
    r, rf, c = prm[R_JET], prm[R_FLANGE], prm[C_PORT]
    port = math.pi * r * r
    d1, d2 = abs(c - x), abs(c + x)
    cd = prm[CD]
    p1, p2, ps, pr = y[4], y[5], prm[P_S], prm[P_R]
    m_s1 = flow(cd * lens(r, r, d1), ps, p1, prm)
    m_r1 = flow(cd * (port - lens(rf, r, d1)), p1, pr, prm)
    m_s2 = flow(cd * lens(r, r, d2), ps, p2, prm)
    m_r2 = flow(cd * (port - lens(rf, r, d2)), p2, pr, prm)
    ratio = min(p1, p2) / max(p1, p2)
    a_leak = max(prm[LEAK_SLOPE] * ratio + prm[LEAK_OFFSET], 0.0)
    m_l = flow(a_leak, p1, p2, prm)
    ap = prm[A_P]
    v1 = prm[VD1] + ap * q
    v2 = prm[VD2] + ap * (prm[STROKE] - q)
    n, rt = prm[N_POLY], prm[RT]
    out[4] = n / v1 * (rt * (m_s1 - m_r1 - m_l) - p1 * ap * qd)
    out[5] = n / v2 * (rt * (m_s2 - m_r2 + m_l) + p2 * ap * qd)


@njit(cache=True)
def step(y, plays, radii, i_cmd, q, qd, h, n_sub, prm):
    """Advance y (6,) and plays (n,) in place by n_sub RK4 substeps of h [s]."""
    k1 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    k4 = np.empty(6)
    tmp = np.empty(6)
    n = plays.size
    for _ in range(n_sub):
        f_tip = prm[K_M] * y[0]
        total = 0.0
        for k in range(n):
            plays[k] = min(max(plays[k], f_tip - radii[k]), f_tip + radii[k])
            total += plays[k]
        f_h = total / n
        rhs(y, k1, i_cmd, f_h, q, qd, prm)
        for j in range(6):
            tmp[j] = y[j] + 0.5 * h * k1[j]
        rhs(tmp, k2, i_cmd, f_h, q, qd, prm)
        for j in range(6):
            tmp[j] = y[j] + 0.5 * h * k2[j]
        rhs(tmp, k3, i_cmd, f_h, q, qd, prm)
        for j in range(6):
            tmp[j] = y[j] + h * k3[j]
        rhs(tmp, k4, i_cmd, f_h, q, qd, prm)
        for j in range(6):
            y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
