"""Flows, chamber pressures and force of the jet-pipe cylinder (paper 000 eqs. 5-13).

    orifice flows   m = C_d A p_up f(p_down/p_up)  (eq. 5: choked / subsonic; pneumatics.medium)
    piston leak     C_d,lpp A_lpp = C_dm A (P_down/P_up) + C_dc A                      (eq. 6)
    net flows       m1 = m_s1 - m_r1 - m_lpp,   m2 = m_s2 - m_r2 + m_lpp                (eqs. 7-8)
    pressures       dP_i/dt = n/V_i (R T m_i - P_i dV_i/dt)                             (eqs. 9-12)
    force           F = A_p (P1 - P2)                                                   (eq. 13)

Eq. 12 is the paper's gamma P/V (Q - V') with Q = m/rho and rho = P/(R T) (eqs. 9-10),
written with the polytropic exponent n of [gas] (n = gamma = 1.4: adiabatic, as the paper).
Everything is numpy and broadcasts; the compiled kernel (kernel.py) must agree with it.
"""
from __future__ import annotations

import numpy as np

from ..medium import orifice_flow
from .params import JetpipeCfg
from .ports import orifice_areas


def leak_area_m2(p1_pa, p2_pa, cfg: JetpipeCfg):
    """Effective piston-leak area C_d,lpp A_lpp [m^2] (eq. 6), >= 0, from the pressure ratio
    downstream/upstream (the lower over the higher chamber pressure)."""
    p1, p2 = np.asarray(p1_pa, float), np.asarray(p2_pa, float)
    ratio = np.minimum(p1, p2) / np.maximum(p1, p2)
    return np.maximum(cfg.leak.slope_m2 * ratio + cfg.leak.offset_m2, 0.0)


def volumes(piston_m, piston_speed_m_s, cfg: JetpipeCfg):
    """Chamber volumes (V1, V2) [m^3] and their rates [m^3/s]; ``piston_m`` = chamber-1 length."""
    c = cfg.cylinder
    v1 = c.dead_volume_1_m3 + c.piston_area_m2 * piston_m
    v2 = c.dead_volume_2_m3 + c.piston_area_m2 * (c.stroke_m - piston_m)
    rate = c.piston_area_m2 * piston_speed_m_s
    return v1, v2, rate, -rate


def net_mass_flows(x_abs_m, p1_pa, p2_pa, cfg: JetpipeCfg, areas=None):
    """Net mass flows into chambers 1 and 2 [kg/s] (eqs. 5-8) at jet position ``x_abs_m`` [m].

    ``areas``: the four geometric areas of ports.orifice_areas(x_abs_m), if already known.
    Returns ``(m1, m2, leak_1_to_2)``; arrays broadcast."""
    gas, ps, pr = cfg.gas, cfg.supply.supply_pa, cfg.supply.room_pa
    cd = cfg.ports.discharge_coefficient
    a_s1, a_r1, a_s2, a_r2 = orifice_areas(x_abs_m, cfg.ports) if areas is None else areas
    m_s1 = orifice_flow(cd * a_s1, ps, p1_pa, gas)[0]
    m_r1 = orifice_flow(cd * a_r1, p1_pa, pr, gas)[0]
    m_s2 = orifice_flow(cd * a_s2, ps, p2_pa, gas)[0]
    m_r2 = orifice_flow(cd * a_r2, p2_pa, pr, gas)[0]
    m_l = orifice_flow(leak_area_m2(p1_pa, p2_pa, cfg), p1_pa, p2_pa, gas)[0]
    return m_s1 - m_r1 - m_l, m_s2 - m_r2 + m_l, m_l


def pressure_rates(x_abs_m, p1_pa, p2_pa, piston_m, piston_speed_m_s, cfg: JetpipeCfg):
    """(dP1/dt, dP2/dt) [Pa/s] of eq. 12."""
    m1, m2, _ = net_mass_flows(x_abs_m, p1_pa, p2_pa, cfg)
    v1, v2, dv1, dv2 = volumes(piston_m, piston_speed_m_s, cfg)
    n, rt = cfg.gas.polytropic_exponent, cfg.gas.gas_constant_j_per_kg_k * cfg.gas.temperature_k
    return n / v1 * (rt * m1 - p1_pa * dv1), n / v2 * (rt * m2 - p2_pa * dv2)


def piston_force(p1_pa, p2_pa, cfg: JetpipeCfg):
    """Pressure force on the piston toward the stopper, A_p (P1 - P2) [N] (eq. 13)."""
    return cfg.cylinder.piston_area_m2 * (np.asarray(p1_pa, float) - np.asarray(p2_pa, float))


def _balances_and_jacobian(x, p1, p2, cfg: JetpipeCfg, areas):
    """Net mass flows (m1, m2) and their Jacobian d(m1, m2)/d(P1, P2) (2, 2, N) from the
    orifice-flow derivatives and the leak area's pressure-ratio dependence (eq. 6)."""
    gas, ps, pr = cfg.gas, cfg.supply.supply_pa, cfg.supply.room_pa
    cd = cfg.ports.discharge_coefficient
    a_s1, a_r1, a_s2, a_r2 = areas
    m_s1, _, ds1 = orifice_flow(cd * a_s1, ps, p1, gas)
    m_r1, dr1, _ = orifice_flow(cd * a_r1, p1, pr, gas)
    m_s2, _, ds2 = orifice_flow(cd * a_s2, ps, p2, gas)
    m_r2, dr2, _ = orifice_flow(cd * a_r2, p2, pr, gas)
    a_l = leak_area_m2(p1, p2, cfg)
    m_l, dl1, dl2 = orifice_flow(a_l, p1, p2, gas)
    # d(area)/dP of eq. 6: area = slope * lo/hi + offset (where positive)
    hi, lo = np.maximum(p1, p2), np.minimum(p1, p2)
    live = a_l > 0.0
    d_lo = np.where(live, cfg.leak.slope_m2 / hi, 0.0)
    d_hi = np.where(live, -cfg.leak.slope_m2 * lo / hi ** 2, 0.0)
    da1 = np.where(p1 >= p2, d_hi, d_lo)
    da2 = np.where(p1 >= p2, d_lo, d_hi)
    unit = np.where(live, m_l / np.where(live, a_l, 1.0), 0.0)
    dl1 = dl1 + da1 * unit
    dl2 = dl2 + da2 * unit
    f = np.array([m_s1 - m_r1 - m_l, m_s2 - m_r2 + m_l])
    jac = np.array([[ds1 - dr1 - dl1, -dl2], [dl1, ds2 - dr2 + dl2]])
    return f, jac


def static_pressures(x_abs_m, cfg: JetpipeCfg, iterations: int = 60, p0=None):
    """Steady chamber pressures (P1, P2) [Pa], each (N,), with the piston still at jet positions
    ``x_abs_m`` (N,): the roots of m1 = m2 = 0 (eqs. 7-8), by damped Newton on the two mass
    balances, vectorised over N.  ``p0`` (2, N): a warm start."""
    x = np.atleast_1d(np.asarray(x_abs_m, float))
    ps, pr = cfg.supply.supply_pa, cfg.supply.room_pa
    p = np.stack([np.full(x.shape, 0.5 * (ps + pr)), np.full(x.shape, 0.5 * (ps + pr))])
    if p0 is not None:
        p = np.array(p0, float).reshape(2, -1) * np.ones((1, x.size))
    areas = orifice_areas(x, cfg.ports)
    lim = 0.2 * (ps - pr)  # damping: never jump more than a fifth of the supply span
    for _ in range(iterations):
        f, (j1, j2) = _balances_and_jacobian(x, p[0], p[1], cfg, areas)
        j11, j12 = j1
        j21, j22 = j2
        det = j11 * j22 - j12 * j21
        det = np.where(np.abs(det) < 1e-300, 1e-300, det)
        dp1 = -(j22 * f[0] - j12 * f[1]) / det
        dp2 = -(-j21 * f[0] + j11 * f[1]) / det
        p[0] = np.clip(p[0] + np.clip(dp1, -lim, lim), pr, ps)
        p[1] = np.clip(p[1] + np.clip(dp2, -lim, lim), pr, ps)
        if np.all(np.abs(dp1) + np.abs(dp2) < 1e-3):
            break
    return p[0], p[1]


def static_force(x_abs_m, cfg: JetpipeCfg):
    """Steady actuator force [N] at jet positions ``x_abs_m`` with the piston on the stopper:
    A_p (P1 - P2) where positive; the actuator only pulls (eq. 13; the spring's ~1 N aside)."""
    p1, p2 = static_pressures(x_abs_m, cfg)
    return np.maximum(piston_force(p1, p2, cfg), 0.0)
