"""The per-millisecond physics of the variant simulator (numba): valves, lines, chambers,
cylinders, transmission, supply and joint torques, with every variant effect switched by its
parameter row (0 = off; rows in :mod:`.rows`, flow laws in :mod:`.flows`, joint torques in
:mod:`.mechanics`).

Written from the arm2 reference numbers (``reference/arm2.md`` beside DESIGN.md), paper 002
and the sources the functions name (no pneumasim import).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .flows import (  # noqa: F401  (re-exported: the constants of the air and the orifice)
    ALPHA, BETA, CRIT_RATIO, KAPPA, LAMINAR_RATIO, P_ATM, P_SUPPLY, R_GAS, SOUND_M_S, T0,
    leak_flow, line_friction_rate, orifice, series_area, valve_null_leak,
)
from .mechanics import end_stop_torque, friction, outside_joint_torque
from .rows import *  # noqa: F403  (the row numbers are the kernel's vocabulary)
from .rows import (
    ACYL, AE, AS, BL_C, BL_GAP, BL_J, BL_K, BL_N, DAMP, EX_A, EX_B, EX_MODE, HT_CW, HT_F, HT_NAT,
    HT_SCALE, HT_WA, INERTIA, LN_ATT, LN_DELAY, LN_LEN, LN_MODE, LN_TAU, LN_V, NBUF, OS_AMP, OS_HZ,
    OS_STEP, OS_T, OV_AR, OV_CV, PL_A, PL_B, PL_MODE, R_ARM, SB0, SBI, SCLK, SCMP, SIGN, SM0, SMS, SN0,
    SP, SP_RATE, SP_TAU, SP_W, SP_Z, SPS, SPT, ST, STH, STHD, STROKE, STW, SU_A, SU_BAND, SU_LK, SU_MODE,
    SU_QC, SU_R, SU_V, SY, SYD, VD, VL_A, VL_B, VL_MODE, VL_W,
)

#: reference mass flow of the flow-dependent heat transfer coefficient [kg/s]
MDOT_REF = 2e-4
#: the regulator's upstream line pressure (supply modes 1 and 3) [Pa]
P_LINE = 8.0e5
#: supply_droop forms (SU_MODE row)
SU_RESERVOIR, SU_STATIC, SU_PROPORTIONAL, SU_COMPRESSOR = 1, 2, 3, 4
#: line forms (LN_MODE row)
LN_TWO_VOLUME, LN_DELAYED, LN_RLC = 1, 2, 3
#: the static droop's flow filter [s] (the supply line's own lag; breaks the algebraic loop)
STATIC_DROOP_TAU_S = 0.005

VALVE_LEAK_F = 0.02
VALVE_LEAK_W = 0.6 / 5.0
VALVE_DEAD = 0.15 / 5.0
VALVE_GAMMA = 1.3


@njit(cache=True)
def valve_areas(u, a_s, a_e):
    """arm2.md valve map: effective supply and exhaust areas [m^2] at spool command u [V]."""
    s = min(1.0, max(-1.0, (u - 5.0) / 5.0))
    leak = VALVE_LEAK_F * math.exp(-(s / VALVE_LEAK_W) ** 2)
    up = max(0.0, (s - VALVE_DEAD) / (1.0 - VALVE_DEAD)) ** VALVE_GAMMA
    dn = max(0.0, (-s - VALVE_DEAD) / (1.0 - VALVE_DEAD)) ** VALVE_GAMMA
    return a_s * (leak + (1.0 - VALVE_LEAK_F) * up), a_e * (leak + (1.0 - VALVE_LEAK_F) * dn), s


@njit(cache=True)
def spool(u, P, S, c, h):
    """Spool position [V] after the valve's own dynamics: second order (omega_n, zeta; the
    classic servovalve approximation, Merritt 1967 ch. 5), first order (tau), a rate limit
    [V/s] (the solenoid's force bounds the spool speed), or the command itself."""
    if P[SP_W, c] > 0.0:
        w = P[SP_W, c]
        if w * h > 0.3:      # a spool this fast (a concealed one) settles within the sub-step
            S[SY, c], S[SYD, c] = u, 0.0
            return u
        S[SYD, c] += h * (w * w * (u - S[SY, c]) - 2.0 * P[SP_Z, c] * w * S[SYD, c])
        S[SY, c] += h * S[SYD, c]
    elif P[SP_TAU, c] > 0.0:
        S[SY, c] = u + (S[SY, c] - u) * math.exp(-h / P[SP_TAU, c])
    elif P[SP_RATE, c] > 0.0:
        step = P[SP_RATE, c] * h
        S[SY, c] += min(step, max(-step, u - S[SY, c]))
    else:
        return u
    return S[SY, c]


@njit(cache=True)
def chamber_volume(P, c, th):
    """Chamber volume [m^3] at piston angle th: V_dead + A x (arm2.md), plus a delayed line's
    tube volume."""
    j = c // 2
    x = 0.5 * P[STROKE, j] + P[R_ARM, j] * th
    vol = P[VD, c] + P[ACYL, c] * (x if P[SIGN, c] > 0 else P[STROKE, j] - x)
    if P[LN_MODE, c] == LN_DELAYED:
        vol += P[LN_V, c]
    return vol


@njit(cache=True)
def valve_relax_rate(P, c, volume):
    """How fast [1/s] valve c's orifices relax the pressure of a ``volume`` [m^3] at its port:
    arm2's valve relaxes a 3 cm^3 volume at ~1600 1/s (arm.py NSUB); leak forms add less.
    The lines' sub-steps are set from it."""
    return 1600.0 * 3e-6 / volume * (P[AS, c] + P[AE, c]) / 1.7e-6 * 2.0


@njit(cache=True)
def valve_flows(y, ps, pn, P, c):
    """(supply -> node, net valve -> node) mass flows [kg/s] at spool y [V]: the arm2.md valve
    (paper 002 orifices), a chamber-port restriction in series with its exhaust path, and
    the null-leak form of the VL_MODE row."""
    a_s, a_e, s = valve_areas(y, P[AS, c], P[AE, c])
    if P[OV_AR, c] > 0.0:
        a_e = series_area(a_e, P[OV_AR, c])
    m_s = a_s * orifice(ps, pn)
    m_e = a_e * orifice(pn, P_ATM)
    if P[VL_MODE, c] > 0.0:
        ls, le = valve_null_leak(int(P[VL_MODE, c]), P[VL_A, c], P[VL_W, c], P[VL_B, c], s, ps, pn)
        m_s += ls
        m_e += le
    return m_s, m_s - m_e


@njit(cache=True)
def line(m_v, pn, P, S, c, vol, h):
    """The mass flow [kg/s] the chamber receives from the valve through its line form:
    LN_TWO_VOLUME a tube volume and a laminar resistance (one lumped R and C; exchange exact
    for a frozen conductance; one sub-step of :func:`two_volume_line`); LN_DELAYED the valve's
    flow delayed by LN_DELAY and attenuated by LN_ATT (pure delay + volume; or Richer &
    Hurmuzlu 2000, ASME JDSMC 122:405, eq. 19's delayed, attenuated flow).  LN_RLC is
    :func:`rlc_line`."""
    mode = P[LN_MODE, c]
    if mode == LN_TWO_VOLUME:
        p, vt = S[SP, c], P[LN_V, c]
        g = vt / (R_GAS * T0 * P[LN_TAU, c]) * (pn + p) / (2.0 * 4.0e5)
        lam = KAPPA * R_GAS * T0 * g * (1.0 / vt + 1.0 / vol)
        frac = (1.0 - math.exp(-lam * h)) / (lam * h) if lam * h > 1e-12 else 1.0
        m_x = g * (pn - p) * frac
        S[SPT, c] += h * KAPPA * R_GAS * T0 / vt * (m_v - m_x)
        return m_x
    if mode == LN_DELAYED:
        i = int(S[SBI, c])
        S[SB0 + i, c] = m_v
        d = min(NBUF - 1, int(round(P[LN_DELAY, c] / h)))
        out = S[SB0 + (i - d) % NBUF, c]
        S[SBI, c] = (i + 1) % NBUF
        return P[LN_ATT, c] * out
    return m_v


@njit(cache=True)
def two_volume_line(y, ps, P, S, c, vol, h):
    """LN_TWO_VOLUME with the valve's flow into the tube in sub-steps: the tube is small (1-3
    cm^3, less once concealed) and the valve's orifice relaxes it at up to ~1e4 1/s, which one
    explicit 0.25 ms step does not keep stable (a concealed tube went to non-finite pressures).
    Each sub-step is :func:`line`'s exchange; returns the mean (supply -> valve, tube ->
    chamber) mass flows [kg/s] over h."""
    m = max(1, int(math.ceil(h * valve_relax_rate(P, c, P[LN_V, c]) / 0.5)))
    hs = h / m
    sum_s, sum_x = 0.0, 0.0
    for _ in range(m):
        m_s, m_v = valve_flows(y, ps, S[SPT, c], P, c)
        sum_s += m_s
        sum_x += line(m_v, S[SPT, c], P, S, c, vol, hs)
    return sum_s / m, sum_x / m


@njit(cache=True)
def rlc_line(y, ps, P, S, c, vol, h):
    """LN_RLC: three lumped segments of volume V/3, inertance (L/3)/A and laminar friction
    32 mu/(rho d^2) between the valve and the chamber (a lumped transmission line, as in
    Krichel & Sawodny's pneumatic line models).  Short segments are stiff (wave frequency
    ~ c / (L/3), a small first volume against the valve's laminar conductance), so the line
    and the valve's flow into it take their own sub-steps; the chamber pressure evolves
    locally with the line's flow only.  Returns the mean (supply -> valve, line -> chamber)
    mass flows [kg/s] over h."""
    seg_v, seg_l = P[LN_V, c] / 3.0, P[LN_LEN, c] / 3.0
    area = P[LN_V, c] / P[LN_LEN, c]
    d = math.sqrt(4.0 * area / math.pi)
    krt = KAPPA * R_GAS * T0
    valve_rate = valve_relax_rate(P, c, seg_v)
    wave = max(2.0 * SOUND_M_S / seg_l, math.sqrt(krt * area / (seg_l * vol)))
    m = max(1, int(math.ceil(h * max(valve_rate / 0.5, wave / 0.3))))
    hs = h / m
    p_ch = S[SP, c]
    sum_s, sum_out = 0.0, 0.0
    for _ in range(m):
        m_s, m_v = valve_flows(y, ps, S[SN0, c], P, c)
        for i in range(3):   # inertance first (symplectic Euler), then the node pressures
            p_up = S[SN0 + i, c]
            p_dn = S[SN0 + i + 1, c] if i < 2 else p_ch
            rate = line_friction_rate(0.5 * (p_up + p_dn), d)
            S[SM0 + i, c] += hs * (area / seg_l * (p_up - p_dn) - rate * S[SM0 + i, c])
        S[SN0, c] += hs * krt / seg_v * (m_v - S[SM0, c])
        for i in range(1, 3):
            S[SN0 + i, c] += hs * krt / seg_v * (S[SM0 + i - 1, c] - S[SM0 + i, c])
        p_ch += hs * krt / vol * S[SM0 + 2, c]
        sum_s += m_s
        sum_out += S[SM0 + 2, c]
    return sum_s / m, sum_out / m


@njit(cache=True)
def chamber_pdot(P, S, c, m_in, vol, vdot, h):
    """dp/dt [Pa/s] of chamber c (paper 002 eq. 9), with the wall compliance dV/dp = OV_CV
    (V grows with gauge pressure: dp/dt = kappa (R T0 mdot - p Vdot) / (V + kappa p C_v)) and
    the heat-transfer deviation (gas temperature a state; wall at T0 or a wall node of heat
    capacity HT_CW exchanging with the room at HT_WA: a two-node lumped model, Incropera &
    DeWitt, lumped capacitance); the gas and wall temperatures advance by h here."""
    p = S[SP, c]
    cv = P[OV_CV, c]
    vol_eff = vol + cv * (p - P_ATM)
    pdot = KAPPA * (R_GAS * T0 * m_in - p * vdot) / (vol_eff + KAPPA * p * cv)
    if P[HT_SCALE, c] > 0.0:
        # energy balance with outflow at the gas temperature and convection hA(|mdot|)
        # (Dittus-Boelter-like ^0.8; hA_f = 0 is a constant hA)
        T = S[ST, c]
        tw = S[STW, c] if P[HT_CW, c] > 0.0 else T0
        ha = P[HT_NAT, c] + P[HT_F, c] * (abs(m_in) / MDOT_REF) ** 0.8
        m_out = max(-m_in, 0.0)
        dev = -KAPPA * R_GAS / vol_eff * m_out * (T - T0) - (KAPPA - 1.0) * ha * (T - tw) / vol_eff
        pdot += P[HT_SCALE, c] * dev
        S[ST, c] += h * T * (pdot / p + vdot / vol_eff - m_in * R_GAS * T / (p * vol_eff))
        if P[HT_CW, c] > 0.0:
            S[STW, c] += h * (ha * (T - tw) - P[HT_WA, c] * (tw - T0)) / P[HT_CW, c]
    return pdot


@njit(cache=True)
def supply_pressure(P, S):
    """Pressure at the valves' supply ports [Pa]: 7 bar, or the supply_droop form's state,
    plus the outside-vocabulary compressor ripple and supply step."""
    ps = S[SPS, 0] if P[SU_MODE, 0] > 0.0 else P_SUPPLY
    t = S[SCLK, 0]
    if P[OS_AMP, 0] != 0.0:
        ps += P[OS_AMP, 0] * math.sin(2.0 * math.pi * P[OS_HZ, 0] * t)
    if P[OS_STEP, 0] != 0.0 and t >= P[OS_T, 0]:
        ps += P[OS_STEP, 0]
    return ps


@njit(cache=True)
def supply_update(P, S, m_supply, h):
    """Advance the supply_droop form by h: SU_RESERVOIR a reservoir (isothermal, SU_V) fed
    from 7 bar through a regulator orifice SU_A, exact for a frozen conductance; SU_STATIC a static droop p_s = 7 bar - R mdot (mdot filtered over 5 ms; a
    regulator's flow characteristic, ISO 6953-1); SU_PROPORTIONAL a reservoir fed by a
    regulator whose opening is proportional to its error over the band SU_BAND (a
    proportional regulator's droop; orifice from P_LINE); SU_COMPRESSOR a reservoir filled at
    SU_QC [kg/s] by a compressor a pressure switch runs between 7 bar - SU_BAND and 7 bar,
    drained by the valves and a system leak SU_LK [kg/(s Pa)] (Beater 2007, Pneumatic
    Drives, ch. 2: compressed-air supply)."""
    mode = P[SU_MODE, 0]
    p = S[SPS, 0]
    k_res = R_GAS * T0 / P[SU_V, 0] if P[SU_V, 0] > 0.0 else 0.0
    if mode == SU_RESERVOIR:
        dp = max(P_SUPPLY - p, 10.0)
        g = P[SU_A, 0] * orifice(P_SUPPLY, P_SUPPLY - dp) / dp
        pss = P_SUPPLY - m_supply / g
        S[SPS, 0] = pss + (p - pss) * math.exp(-k_res * g * h)
    elif mode == SU_STATIC:
        S[SMS, 0] += (m_supply - S[SMS, 0]) * h / STATIC_DROOP_TAU_S
        S[SPS, 0] = P_SUPPLY - P[SU_R, 0] * max(S[SMS, 0], 0.0)
    elif mode == SU_PROPORTIONAL:
        band = P[SU_BAND, 0]
        full = P[SU_A, 0] * orifice(P_LINE, p)             # regulator flow wide open [kg/s]
        if P_SUPPLY - p >= band:
            S[SPS, 0] = p + h * k_res * (full - m_supply)
        else:   # opening linear in p inside the band: implicit Euler (a narrow band is stiff)
            g = full / band
            p_new = (p + h * k_res * (g * P_SUPPLY - m_supply)) / (1.0 + h * k_res * g)
            S[SPS, 0] = p_new if p_new <= P_SUPPLY else p - h * k_res * m_supply
    elif mode == SU_COMPRESSOR:
        if p >= P_SUPPLY:
            S[SCMP, 0] = 0.0
        elif p <= P_SUPPLY - P[SU_BAND, 0]:
            S[SCMP, 0] = 1.0
        m_c = P[SU_QC, 0] * S[SCMP, 0]
        S[SPS, 0] = p + h * k_res * (m_c - m_supply - P[SU_LK, 0] * (p - P_ATM))


@njit(cache=True)
def transmission(P, S, j, tc, q, qd, h, nsub):
    """The torque [N m / nsub] the cylinder torque tc puts on link j over one sub-step: tc
    itself, or through a dead zone between the piston (own inertia BL_J) and the link:
    contact k pen + c (rate), or Hunt-Crossley (k + c rate) pen^n when BL_N > 0 (impact
    damping; Hunt & Crossley 1975); the dead zone of Nordin & Gutman 2002 (Automatica 38:1633)."""
    if P[BL_GAP, j] <= 0.0:
        return tc / nsub
    d = S[STH, j] - q[j]
    half = 0.5 * P[BL_GAP, j]
    pen = d - min(half, max(-half, d))
    rate = S[STHD, j] - qd[j]
    if pen == 0.0:
        tt = 0.0
    elif P[BL_N, j] > 0.0:
        sg = 1.0 if pen > 0 else -1.0
        tt = sg * max(0.0, (P[BL_K, j] + P[BL_C, j] * sg * rate) * abs(pen) ** P[BL_N, j])
    else:
        tt = P[BL_K, j] * pen + P[BL_C, j] * rate
    S[STHD, j] += h * (tc - tt) / P[BL_J, j]
    S[STH, j] += h * S[STHD, j]
    return tt / nsub


@njit(cache=True)
def step_ms(u, q, qd, bias, P, S, dt, nsub, tau):
    """Advance the fluid, the pistons, the supply and the friction states by ``dt`` [s] in
    ``nsub`` explicit sub-steps; write the generalised force on the two links into ``tau``
    (2,) [N m].

    u (4,): spool command after valve hysteresis and dead time [V]; q, qd (2,): link angle
    [rad] and rate [rad/s] (held over dt); bias (2,): MuJoCo's qfrc_bias (gravity +
    Coriolis) for the stick test.  The blocks follow the equations: supply, valve, line,
    leaks, chamber pressures (002 eq. 9), cylinder torque and transmission, supply state;
    then the joint torques."""
    h = dt / nsub
    tau_cyl = np.zeros(2)
    m_in = np.zeros(4)
    th = np.empty(2)
    thd = np.empty(2)
    for _ in range(nsub):
        for j in range(2):
            compliant = P[BL_GAP, j] > 0.0
            th[j] = S[STH, j] if compliant else q[j]
            thd[j] = S[STHD, j] if compliant else qd[j]
        ps = supply_pressure(P, S)
        m_supply = 0.0
        for c in range(4):
            y = spool(u[c], P, S, c, h)
            vol = chamber_volume(P, c, th[c // 2])
            if P[LN_MODE, c] == LN_RLC:
                m_s, m_in[c] = rlc_line(y, ps, P, S, c, vol, h)
            elif P[LN_MODE, c] == LN_TWO_VOLUME:
                m_s, m_in[c] = two_volume_line(y, ps, P, S, c, vol, h)
            else:
                pn = S[SP, c]   # the valve's port sees the chamber (no tube between)
                m_s, m_v = valve_flows(y, ps, pn, P, c)
                m_in[c] = line(m_v, pn, P, S, c, vol, h)
            m_supply += m_s
            if P[EX_MODE, c] > 0.0:
                m_in[c] -= leak_flow(int(P[EX_MODE, c]), P[EX_A, c], P[EX_B, c], S[SP, c], P_ATM)
        for j in range(2):
            if P[PL_MODE, j] > 0.0:   # past the piston seal, a -> b: mass conserving
                ml = leak_flow(int(P[PL_MODE, j]), P[PL_A, j], P[PL_B, j], S[SP, 2 * j], S[SP, 2 * j + 1])
                m_in[2 * j] -= ml
                m_in[2 * j + 1] += ml
        for c in range(4):
            j = c // 2
            vdot = P[SIGN, c] * P[ACYL, c] * P[R_ARM, j] * thd[j]
            pdot = chamber_pdot(P, S, c, m_in[c], chamber_volume(P, c, th[j]), vdot, h)
            S[SP, c] += h * pdot
        for j in range(2):
            a, b = 2 * j, 2 * j + 1
            tc = P[R_ARM, j] * (P[ACYL, a] * S[SP, a] - P[ACYL, b] * S[SP, b] - (P[ACYL, a] - P[ACYL, b]) * P_ATM)
            tau_cyl[j] += transmission(P, S, j, tc, q, qd, h, nsub)
        if P[SU_MODE, 0] > 0.0:
            supply_update(P, S, m_supply, h)
        S[SCLK, 0] += h
    for j in range(2):
        v = qd[j]
        stick_need = tau_cyl[j] - bias[j] - P[DAMP, j] * v + P[INERTIA, j] * v / dt
        tau[j] = (tau_cyl[j] - friction(P, S, j, v, dt, stick_need) + end_stop_torque(P, j, q[j], v)
                  + outside_joint_torque(P, j, q[j]))
