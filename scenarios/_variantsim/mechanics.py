"""Compiled joint-side effects of the variant simulator (numba): friction elements, end
stops, and the joint torques outside the vocabulary.  Each function takes the parameter
matrix P, the state matrix S and the joint column j, and returns a torque [N m] that OPPOSES
the link (friction: subtract it) or acts on it (stops, springs: add it), as its docstring says.

Written from the sources each function names (no pneumasim import).
"""
from __future__ import annotations

import math

from numba import njit

from .rows import (
    DH_FC, DH_SIG, ES_C, ES_HI, ES_K, ES_K3, ES_LO, ES_MODE, ES_N, KP_DV, KP_FC, KP_FS, LG_FC, LG_FS,
    LG_S0, LG_S1, LG_S2, LG_VS, OJ_COG, OJ_K, OJ_PH, OJ_PITCH, OJ_Q0, SDZ, SE_CP, SE_VE, SF_DELTA, SF_FC,
    SF_FS, SF_VE, SF_VS, SLZ, SP, VS_B0, VS_B1, VS_N,
)
from .flows import P_ATM

ES_LINEAR, ES_HUNT_CROSSLEY, ES_PROGRESSIVE = 1, 2, 3
#: below this speed a velocity-power law with n < 1 turns linear [rad/s] (its slope would
#: diverge at v = 0 and an explicit step would chatter)
POWER_LINEAR_BELOW = 0.05


@njit(cache=True)
def friction(P, S, j, v, dt, stick_need):
    """Sum of the friction elements switched on at joint j [N m], opposing v [rad/s] (held
    over dt); ``stick_need`` is the torque that would stop the joint in one step (Karnopp).
      LuGre (Canudas de Wit, Olsson, Astrom, Lischinsky 1995, IEEE TAC 40:419, eqs. 2-4),
        bristle z integrated exactly for the step's v;
      Karnopp (1985, ASME JDSMC 107:100): |v| < dv holds up to Fs, else Fc sign v;
      static curve (Armstrong-Helouvry, Dupont, Canudas de Wit 1994, Automatica 30:1083; the
        Stribeck exponent delta of Bo & Pavelescu 1982, Wear 82:277):
        (Fc + (Fs - Fc) exp(-|v/vs|^delta)) tanh(v/ve);
      Dahl (1976, AIAA J 14:1675): dF/dt = sigma v (1 - F/Fc sign v), exact for frozen v;
      pressure-dependent seal: Fc = cp (p_a + p_b - 2 p_atm), tanh(v/ve) (seal friction
        growing with chamber pressure: Belforte, Mattiazzo, Mauro, Tokashiki 2003, Tribotest
        10:33);
      viscous (b0 + b1 (p_mean - p_atm)) |v|^n sign v (n = 1 linear; the velocity-power
        law of Andersson, Soderberg, Bjorklund 2007, Tribology Int 40:580; linear below
        POWER_LINEAR_BELOW when n < 1)."""
    f = 0.0
    if P[LG_S0, j] > 0.0:
        g = P[LG_FC, j] + (P[LG_FS, j] - P[LG_FC, j]) * math.exp(-(v / P[LG_VS, j]) ** 2)
        a = P[LG_S0, j] * abs(v) / g
        z = S[SLZ, j]
        zn = z if a <= 0.0 else v / a + (z - v / a) * math.exp(-a * dt)
        S[SLZ, j] = zn
        f += P[LG_S0, j] * zn + P[LG_S1, j] * (zn - z) / dt + P[LG_S2, j] * v
    if P[KP_FS, j] > 0.0:
        if abs(v) < P[KP_DV, j]:
            f += min(P[KP_FS, j], max(-P[KP_FS, j], stick_need))
        else:
            f += P[KP_FC, j] * (1.0 if v > 0 else -1.0)
    if P[SF_FC, j] > 0.0 or P[SF_FS, j] > 0.0:
        g = P[SF_FC, j]
        if P[SF_FS, j] > 0.0:
            g += (P[SF_FS, j] - P[SF_FC, j]) * math.exp(-abs(v / P[SF_VS, j]) ** P[SF_DELTA, j])
        f += g * math.tanh(v / P[SF_VE, j])
    if P[DH_FC, j] > 0.0:
        fc = P[DH_FC, j]
        if v != 0.0:
            sg = 1.0 if v > 0 else -1.0
            S[SDZ, j] = sg * fc + (S[SDZ, j] - sg * fc) * math.exp(-P[DH_SIG, j] * abs(v) * dt / fc)
        f += S[SDZ, j]
    if P[SE_CP, j] > 0.0:
        load = max(0.0, S[SP, 2 * j] + S[SP, 2 * j + 1] - 2.0 * P_ATM)
        f += P[SE_CP, j] * load * math.tanh(v / P[SE_VE, j])
    if P[VS_B0, j] > 0.0 or P[VS_B1, j] > 0.0:
        pm = 0.5 * (S[SP, 2 * j] + S[SP, 2 * j + 1])
        n = P[VS_N, j] if P[VS_N, j] > 0.0 else 1.0
        b = P[VS_B0, j] + P[VS_B1, j] * (pm - P_ATM)
        if n < 1.0 and abs(v) < POWER_LINEAR_BELOW:
            f += b * POWER_LINEAR_BELOW ** (n - 1.0) * v
        else:
            f += b * abs(v) ** n * (1.0 if v > 0 else -1.0 if v < 0 else 0.0)
    return f


@njit(cache=True)
def bumper_force(mode, k, c, n, k3, pen, pen_rate):
    """Contact force [N m] of a bumper penetrated by pen > 0 [rad] at pen_rate [rad/s], never
    pulling: ES_LINEAR spring-damper k pen + c pen_rate; ES_HUNT_CROSSLEY k pen^n + c pen^n
    pen_rate (Hunt & Crossley 1975, ASME J Appl Mech 42:440; Marhefka & Orin 1999, IEEE SMC-A
    29:566); ES_PROGRESSIVE an elastomer bump stop stiffening with compression, k pen +
    k3 pen^3 + c pen_rate (polynomial bump-stop law, Gillespie 1992, Fundamentals of Vehicle
    Dynamics, SAE)."""
    if pen <= 0.0:
        return 0.0
    if mode == ES_HUNT_CROSSLEY:
        f = (k + c * pen_rate) * pen ** n
    elif mode == ES_PROGRESSIVE:
        f = k * pen + k3 * pen ** 3 + c * pen_rate
    else:
        f = k * pen + c * pen_rate
    return max(0.0, f)


@njit(cache=True)
def end_stop_torque(P, j, q, qd):
    """Torque [N m] on link j from its bumpers at ES_HI (upper) and ES_LO (lower) [rad]; a
    one-sided stop keeps the other side at +-10 rad (never reached)."""
    if P[ES_MODE, j] <= 0.0:
        return 0.0
    mode = int(P[ES_MODE, j])
    up = bumper_force(mode, P[ES_K, j], P[ES_C, j], P[ES_N, j], P[ES_K3, j], q - P[ES_HI, j], qd)
    dn = bumper_force(mode, P[ES_K, j], P[ES_C, j], P[ES_N, j], P[ES_K3, j], P[ES_LO, j] - q, -qd)
    return dn - up


@njit(cache=True)
def outside_joint_torque(P, j, q):
    """Torque [N m] on link j from effects outside the vocabulary: a hose or cable pulling
    the link like a linear spring toward its rest angle, -k (q - q0); a position-dependent
    cogging torque A sin(2 pi q / pitch + phase)."""
    t = 0.0
    if P[OJ_K, j] != 0.0:
        t -= P[OJ_K, j] * (q - P[OJ_Q0, j])
    if P[OJ_COG, j] != 0.0:
        t += P[OJ_COG, j] * math.sin(2.0 * math.pi * q / P[OJ_PITCH, j] + P[OJ_PH, j])
    return t
