"""Compiled flow laws of the variant simulator (numba): the isentropic orifice, the ISO 6358
(C, b) path, laminar capillaries, the valve's null-leak forms and the line forms' helpers.
Every function returns a signed mass flow [kg/s] from the first pressure to the second
(pressures absolute, Pa) unless it says otherwise.

Written from paper 002 and the sources each function names (no pneumasim import).
"""
from __future__ import annotations

import math

from numba import njit

KAPPA = 1.4
R_GAS = 287.0
T0 = 293.15
P_ATM = 1.0e5
P_SUPPLY = 7.0e5
#: laminarised above this downstream/upstream ratio (arm2.md: p_down/p_up > 0.995)
LAMINAR_RATIO = 0.995
CRIT_RATIO = (2.0 / (KAPPA + 1.0)) ** (KAPPA / (KAPPA - 1.0))
#: paper 002 eq. 8 (choked) and eq. 7 (subsonic) coefficients, per unit area and upstream pressure
BETA = math.sqrt(KAPPA / (R_GAS * T0) * (2.0 / (KAPPA + 1.0)) ** ((KAPPA + 1.0) / (KAPPA - 1.0)))
ALPHA = math.sqrt(2.0 * KAPPA / (R_GAS * T0 * (KAPPA - 1.0)))
#: ISO 6358-1:2013 reference density of air at the ANR state (20 degC, 1 bar, 65 % RH) [kg/m^3]
RHO_ANR = 1.185
#: dynamic viscosity of air at 20 degC [Pa s] (laminar line friction)
MU_AIR = 1.81e-5
#: speed of sound at T0 [m/s]
SOUND_M_S = math.sqrt(KAPPA * R_GAS * T0)

# valve-leak forms (the VL_MODE row)
VL_LAMINAR_UNDERLAP, VL_UNDERLAP_ORIFICE, VL_OVERLAP_CLEARANCE, VL_ISO6358 = 1, 2, 3, 4
# leak-path forms (EX_MODE, PL_MODE rows)
LEAK_LAMINAR, LEAK_ORIFICE, LEAK_ISO6358 = 1, 2, 3


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
def iso6358(c_m3_s_pa, b, p_up, p_down):
    """ISO 6358-1:2013 flow through a component of sonic conductance C [m^3/(s Pa)] and
    critical pressure ratio b: choked rho0 C p_up below b, rho0 C p_up sqrt(1 - ((r - b) /
    (1 - b))^2) above it (T = T0); linear in (1 - r) above 0.995 so that an explicit step
    stays stable where the ellipse's slope diverges.  Signed."""
    sgn = 1.0
    if p_down > p_up:
        p_up, p_down = p_down, p_up
        sgn = -1.0
    if p_up <= 0.0 or c_m3_s_pa <= 0.0:
        return 0.0
    r = p_down / p_up
    full = RHO_ANR * c_m3_s_pa * p_up
    if r <= b:
        return sgn * full
    rr = min(r, LAMINAR_RATIO)
    x = (rr - b) / (1.0 - b)
    f = full * math.sqrt(max(0.0, 1.0 - x * x))
    if r > LAMINAR_RATIO:
        f *= (1.0 - r) / (1.0 - LAMINAR_RATIO)
    return sgn * f


@njit(cache=True)
def leak_flow(mode, a, b, p_up, p_down):
    """One leak path in the form ``mode``: LEAK_LAMINAR, an isothermal capillary
    (Hagen-Poiseuille for a gas, mdot = G (p_up^2 - p_down^2), a = G [kg/(s Pa^2)]);
    LEAK_ORIFICE, an orifice of effective area a [m^2] (paper 002 eqs. 6-8); LEAK_ISO6358,
    ISO 6358 with C = a [m^3/(s Pa)] and critical ratio b."""
    if mode == LEAK_LAMINAR:
        return a * (p_up * p_up - p_down * p_down)
    if mode == LEAK_ORIFICE:
        return a * orifice(p_up, p_down)
    if mode == LEAK_ISO6358:
        return iso6358(a, b, p_up, p_down)
    return 0.0


@njit(cache=True)
def valve_null_leak(mode, a, w, b, s, ps, pn):
    """A valve leak that depends on the spool position s (-1..1) near null: (supply -> node,
    node -> exhaust) mass flows [kg/s].  Forms:
    VL_LAMINAR_UNDERLAP: laminar flow across the lands of an underlapped spool, conductance
      a [kg/(s Pa)] falling linearly to 0 at |s| = w (Merritt 1967, Hydraulic Control
      Systems, ch. 5: leakage of an underlapped valve);
    VL_UNDERLAP_ORIFICE: the underlap as two orifices (paper 002 eqs. 6-8) of area
      a [m^2] x (1 -/+ s/w), clipped to 0..1, each land closing as the spool moves toward it;
    VL_OVERLAP_CLEARANCE: an overlapped spool's radial clearance, isothermal laminar
      annulus flow a (p_up^2 - p_down^2) / (covered length / nominal overlap) (Merritt 1967
      ch. 5 clearance flow, pi d c^3 / (12 mu L) per unit dp for a liquid), a [kg/(s Pa^2)],
      w the nominal overlap in units of s;
    VL_ISO6358: each land an ISO 6358 path of conductance a (1 - |s|/w)+ [m^3/(s Pa)] and
      critical ratio b."""
    if mode == VL_LAMINAR_UNDERLAP:
        g = a * max(0.0, 1.0 - abs(s) / w)
        return g * (ps - pn), g * (pn - P_ATM)
    if mode == VL_UNDERLAP_ORIFICE:
        a_s = a * min(1.0, max(0.0, 1.0 + s / w))
        a_e = a * min(1.0, max(0.0, 1.0 - s / w))
        return a_s * orifice(ps, pn), a_e * orifice(pn, P_ATM)
    if mode == VL_OVERLAP_CLEARANCE:
        cover_s = max(0.1, 1.0 - s / w)        # s > 0 uncovers the supply land
        cover_e = max(0.1, 1.0 + s / w)
        return a / cover_s * (ps * ps - pn * pn), a / cover_e * (pn * pn - P_ATM * P_ATM)
    if mode == VL_ISO6358:
        c = a * max(0.0, 1.0 - abs(s) / w)
        return iso6358(c, b, ps, pn), iso6358(c, b, pn, P_ATM)
    return 0.0, 0.0


@njit(cache=True)
def series_area(a_valve, a_restriction):
    """Effective area of two orifices in series, 1/A^2 = 1/A1^2 + 1/A2^2 (the usual
    incompressible combination, e.g. Beater 2007, Pneumatic Drives, ch. 4)."""
    if a_valve <= 0.0:
        return 0.0
    return a_valve * a_restriction / math.sqrt(a_valve * a_valve + a_restriction * a_restriction)


@njit(cache=True)
def line_friction_rate(p, diameter_m):
    """Laminar (Hagen-Poiseuille) friction of a tube as a decay rate of its mass flow,
    32 mu / (rho d^2) [1/s], rho = p / (R T0)."""
    rho = max(p, 1e4) / (R_GAS * T0)
    return 32.0 * MU_AIR / (rho * diameter_m * diameter_m)
