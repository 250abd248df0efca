"""The per-millisecond physics of the variant simulator (numba): valves, lines, chambers,
cylinders, transmission and joint friction, with every variant effect switched by its
parameter row (0 = off).

Written from the arm2 reference numbers (``reference/arm2.md`` beside DESIGN.md) and paper 002
only (no pneumasim import).
Chambers are columns 0..3 = shoulder.a, shoulder.b, elbow.a, elbow.b; joints / actuators
columns 0..1 = shoulder, elbow.  ``P[row, col]`` holds parameters, ``S[row, col]`` states.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

# -- air (arm2.md "Air") -------------------------------------------------------------------
KAPPA = 1.4
R_GAS = 287.0
T0 = 293.15
P_ATM = 1.0e5
P_SUPPLY = 7.0e5
#: laminarised below this pressure ratio distance (arm2.md: p_down/p_up > 0.995)
LAMINAR_RATIO = 0.995
CRIT_RATIO = (2.0 / (KAPPA + 1.0)) ** (KAPPA / (KAPPA - 1.0))
#: paper 002 eq. 8 (choked) and eq. 7 (subsonic) coefficients, per unit area and upstream pressure
BETA = math.sqrt(KAPPA / (R_GAS * T0) * (2.0 / (KAPPA + 1.0)) ** ((KAPPA + 1.0) / (KAPPA - 1.0)))
ALPHA = math.sqrt(2.0 * KAPPA / (R_GAS * T0 * (KAPPA - 1.0)))
#: reference mass flow of the flow-dependent heat transfer coefficient [kg/s]
MDOT_REF = 2e-4

# -- parameter rows ---------------------------------------------------------------------------
AS, AE, VD, ACYL, SIGN = 0, 1, 2, 3, 4              # chamber: valve areas, dead volume, piston area, +1 a / -1 b
R_ARM, STROKE = 5, 6                               # joint: moment arm [m], stroke [m]
BW_H = 7                                           # chamber: Bouc-Wen half width [V] (used in Python)
SP_W, SP_Z = 8, 9                                  # chamber: spool natural frequency [rad/s], damping ratio
UL_G, UL_B = 10, 11                                # chamber: underlap conductance [kg/(s Pa)], band [-]
EX_G = 12                                          # chamber: laminar external leak [kg/(s Pa^2)]
LN_V, LN_TAU = 13, 14                              # chamber: tube volume [m^3], tube time constant [s]
HT_NAT, HT_F, HT_SCALE = 15, 16, 17                # chamber: hA natural [W/K], hA forced at MDOT_REF [W/K], scale
PL_G = 18                                          # actuator: laminar piston leak a->b [kg/(s Pa^2)]
LG_FC, LG_FS, LG_VS, LG_S0, LG_S1, LG_S2 = 19, 20, 21, 22, 23, 24   # joint: LuGre
KP_FS, KP_FC, KP_DV = 25, 26, 27                   # joint: Karnopp stick-slip
VS_B0, VS_B1 = 28, 29                              # joint: viscous + pressure-dependent seal viscous
BL_GAP, BL_K, BL_C, BL_J = 30, 31, 32, 33          # joint: compliant dead zone, piston inertia
SU_A, SU_V = 34, 35                                # col 0: regulator orifice area [m^2], reservoir volume [m^3]
DAMP, INERTIA = 36, 37                             # joint: MJCF damping, rough diagonal inertia (Karnopp)
NP = 38
# -- state rows -------------------------------------------------------------------------------
SP, ST, SPT, SY, SYD = 0, 1, 2, 3, 4               # chamber: pressure, gas temperature, tube pressure, spool, spool rate
SLZ, STH, STHD = 5, 6, 7                           # joint: LuGre bristle, piston angle, piston rate
SPS = 8                                            # col 0: supply pressure
NS = 9

VALVE_LEAK_F = 0.02
VALVE_LEAK_W = 0.6 / 5.0
VALVE_DEAD = 0.15 / 5.0
VALVE_GAMMA = 1.3


@njit(cache=True)
def orifice(p_up, p_down):
    """Isentropic mass flow per unit effective area from p_up to p_down [kg/(s m^2)], signed
    (paper 002 eqs. 6-8), linear in the pressure difference for ratios above 0.995."""
    sgn = 1.0
    if p_down > p_up:
        p_up, p_down = p_down, p_up
        sgn = -1.0
    if p_up <= 0.0:
        return 0.0
    r = p_down / p_up
    if r <= CRIT_RATIO:
        return sgn * BETA * p_up
    if r > LAMINAR_RATIO:
        rl = LAMINAR_RATIO
        fl = ALPHA * p_up * math.sqrt(rl ** (2.0 / KAPPA) - rl ** ((KAPPA + 1.0) / KAPPA))
        return sgn * fl * (1.0 - r) / (1.0 - rl)
    return sgn * ALPHA * p_up * math.sqrt(r ** (2.0 / KAPPA) - r ** ((KAPPA + 1.0) / KAPPA))


@njit(cache=True)
def valve_areas(u, a_s, a_e):
    """arm2.md valve map: effective supply and exhaust areas [m^2] at spool command u [V]."""
    s = min(1.0, max(-1.0, (u - 5.0) / 5.0))
    leak = VALVE_LEAK_F * math.exp(-(s / VALVE_LEAK_W) ** 2)
    up = max(0.0, (s - VALVE_DEAD) / (1.0 - VALVE_DEAD)) ** VALVE_GAMMA
    dn = max(0.0, (-s - VALVE_DEAD) / (1.0 - VALVE_DEAD)) ** VALVE_GAMMA
    return a_s * (leak + (1.0 - VALVE_LEAK_F) * up), a_e * (leak + (1.0 - VALVE_LEAK_F) * dn), s


@njit(cache=True)
def step_ms(u, q, qd, bias, P, S, dt, nsub, tau):
    """Advance the fluid, the pistons and the friction states by ``dt`` [s] in ``nsub``
    explicit sub-steps; write the generalised force on the two links into ``tau`` (2,) [N m].

    u (4,): command after valve hysteresis [V]; q, qd (2,): link angle [rad] and rate [rad/s]
    (held over dt); bias (2,): MuJoCo's qfrc_bias (gravity + Coriolis) for the stick test.

    One compiled loop over the explicit sub-steps, its blocks in the order of the equations
    (valve areas, flows, pressures, piston forces, friction states): a transcription kept whole
    so it can be read against the independent simulator's written model, not against
    pneumasim's code."""
    h = dt / nsub
    tau_cyl = np.zeros(2)
    for _ in range(nsub):
        th = np.empty(2)
        thd = np.empty(2)
        for j in range(2):
            if P[BL_GAP, j] > 0.0:
                th[j] = S[STH, j]
                thd[j] = S[STHD, j]
            else:
                th[j] = q[j]
                thd[j] = qd[j]
        ps = S[SPS, 0] if P[SU_A, 0] > 0.0 else P_SUPPLY
        m_supply = 0.0
        m_in = np.zeros(4)
        for c in range(4):
            # spool: second-order (omega_n, zeta) or follows the command
            if P[SP_W, c] > 0.0:
                w = P[SP_W, c]
                acc = w * w * (u[c] - S[SY, c]) - 2.0 * P[SP_Z, c] * w * S[SYD, c]
                S[SYD, c] += h * acc
                S[SY, c] += h * S[SYD, c]
                y = S[SY, c]
            else:
                y = u[c]
            a_s, a_e, s = valve_areas(y, P[AS, c], P[AE, c])
            pn = S[SPT, c] if P[LN_V, c] > 0.0 else S[SP, c]
            m_s = a_s * orifice(ps, pn)
            m_v = m_s - a_e * orifice(pn, P_ATM)
            if P[UL_G, c] > 0.0:  # laminar underlap flow across the spool lands near null
                tri = max(0.0, 1.0 - abs(s) / P[UL_B, c])
                g = P[UL_G, c] * tri
                m_s += g * (ps - pn)
                m_v += g * (ps - pn) - g * (pn - P_ATM)
            m_supply += m_s
            if P[LN_V, c] > 0.0:  # two-volume line: tube volume + laminar resistance
                p = S[SP, c]
                vt = P[LN_V, c]
                g = vt / (R_GAS * T0 * P[LN_TAU, c]) * (pn + p) / (2.0 * 4.0e5)
                j = c // 2
                x = 0.5 * P[STROKE, j] + P[R_ARM, j] * th[j]
                vol = P[VD, c] + P[ACYL, c] * (x if P[SIGN, c] > 0 else P[STROKE, j] - x)
                lam = KAPPA * R_GAS * T0 * g * (1.0 / vt + 1.0 / vol)
                frac = (1.0 - math.exp(-lam * h)) / (lam * h) if lam * h > 1e-12 else 1.0
                m_x = g * (pn - p) * frac
                S[SPT, c] += h * KAPPA * R_GAS * T0 / vt * (m_v - m_x)
                m_in[c] = m_x
            else:
                m_in[c] = m_v
            if P[EX_G, c] > 0.0:  # laminar (capillary) leak to the room
                m_in[c] -= P[EX_G, c] * (S[SP, c] ** 2 - P_ATM ** 2)
        for j in range(2):
            if P[PL_G, j] > 0.0:  # laminar leak past the piston seal, a -> b
                ml = P[PL_G, j] * (S[SP, 2 * j] ** 2 - S[SP, 2 * j + 1] ** 2)
                m_in[2 * j] -= ml
                m_in[2 * j + 1] += ml
        for c in range(4):
            j = c // 2
            x = 0.5 * P[STROKE, j] + P[R_ARM, j] * th[j]
            xc = x if P[SIGN, c] > 0 else P[STROKE, j] - x
            vol = P[VD, c] + P[ACYL, c] * xc
            vdot = P[SIGN, c] * P[ACYL, c] * P[R_ARM, j] * thd[j]
            p = S[SP, c]
            pdot = KAPPA / vol * (R_GAS * T0 * m_in[c] - p * vdot)  # paper 002 eq. 9
            if P[HT_SCALE, c] > 0.0:
                # gas temperature as a state: energy balance with outflow at the gas
                # temperature and wall convection hA(|mdot|) (Dittus-Boelter-like ^0.8)
                T = S[ST, c]
                ha = P[HT_NAT, c] + P[HT_F, c] * (abs(m_in[c]) / MDOT_REF) ** 0.8
                m_out = max(-m_in[c], 0.0)
                dev = -KAPPA * R_GAS / vol * m_out * (T - T0) - (KAPPA - 1.0) * ha * (T - T0) / vol
                pdot += P[HT_SCALE, c] * dev
                S[ST, c] += h * T * (pdot / p + vdot / vol - m_in[c] * R_GAS * T / (p * vol))
            S[SP, c] = p + h * pdot
        for j in range(2):
            a, b = 2 * j, 2 * j + 1
            tc = P[R_ARM, j] * (P[ACYL, a] * S[SP, a] - P[ACYL, b] * S[SP, b] - (P[ACYL, a] - P[ACYL, b]) * P_ATM)
            if P[BL_GAP, j] > 0.0:  # compliant dead zone between piston and link
                d = S[STH, j] - q[j]
                half = 0.5 * P[BL_GAP, j]
                pen = d - min(half, max(-half, d))
                tt = P[BL_K, j] * pen
                if pen != 0.0:
                    tt += P[BL_C, j] * (S[STHD, j] - qd[j])
                S[STHD, j] += h * (tc - tt) / P[BL_J, j]
                S[STH, j] += h * S[STHD, j]
                tau_cyl[j] += tt / nsub
            else:
                tau_cyl[j] += tc / nsub
        if P[SU_A, 0] > 0.0:  # reservoir behind a regulator orifice, exact for a frozen conductance
            dp = max(P_SUPPLY - ps, 10.0)
            g = P[SU_A, 0] * orifice(P_SUPPLY, P_SUPPLY - dp) / dp
            pss = P_SUPPLY - m_supply / g
            S[SPS, 0] = pss + (ps - pss) * math.exp(-R_GAS * T0 * g / P[SU_V, 0] * h)
    for j in range(2):
        v = qd[j]
        f = 0.0
        if P[LG_S0, j] > 0.0:  # LuGre (Canudas de Wit et al. 1995), z exact for frozen v
            g = P[LG_FC, j] + (P[LG_FS, j] - P[LG_FC, j]) * math.exp(-(v / P[LG_VS, j]) ** 2)
            a = P[LG_S0, j] * abs(v) / g
            z = S[SLZ, j]
            zn = z if a <= 0.0 else v / a + (z - v / a) * math.exp(-a * dt)
            S[SLZ, j] = zn
            f += P[LG_S0, j] * zn + P[LG_S1, j] * (zn - z) / dt + P[LG_S2, j] * v
        if P[KP_FS, j] > 0.0:  # Karnopp (1985): stick band |v| < dv holds up to Fs
            if abs(v) < P[KP_DV, j]:
                need = tau_cyl[j] - bias[j] - P[DAMP, j] * v + P[INERTIA, j] * v / dt
                f += min(P[KP_FS, j], max(-P[KP_FS, j], need))
            else:
                f += P[KP_FC, j] * (1.0 if v > 0 else -1.0)
        if P[VS_B0, j] > 0.0 or P[VS_B1, j] > 0.0:  # viscous + seal term growing with pressure
            pm = 0.5 * (S[SP, 2 * j] + S[SP, 2 * j + 1])
            f += (P[VS_B0, j] + P[VS_B1, j] * (pm - P_ATM)) * v
        tau[j] = tau_cyl[j] - f
