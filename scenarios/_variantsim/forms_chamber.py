"""Chamber- and actuator-side forms of the variant simulator: valve_leak, valve_hysteresis,
valve_lag, line_dynamics, heat_transfer, external_leak, piston_leak, pressure_sensor_offset
and the chamber effects outside the vocabulary.  Magnitudes are for arm2's valves (supply
areas 6-8e-7 m^2, a built-in 2 % null leak) and chambers (3-4 cm^3 dead volume, up to
~25 cm^3 at full stroke): a leak draws ~1-4e-5 kg/s at a few bar, comparable with the valve's
own null leak.
"""
from __future__ import annotations

import math

from . import flows as F
from . import kernel as K
from . import rows as R
from .forms import OUTSIDE, Form


def _u(r, lo, hi):
    return float(r.uniform(lo, hi))


def _sym(r, lo, hi):
    return float(r.choice([-1.0, 1.0]) * r.uniform(lo, hi))


def _set(hidden, col, pairs):
    for row, v in pairs:
        hidden.P_rows[row, col] = v


MERRITT = "Merritt 1967, Hydraulic Control Systems (Wiley), ch. 5"
ISO6358 = "ISO 6358-1:2013 (sonic conductance C, critical pressure ratio b)"
HAGEN = "Hagen–Poiseuille capillary, isothermal gas: ṁ = G (p_up² − p_down²)"
ORIFICE = "paper 002 eqs. 6–8 (isentropic orifice)"


# -- valve_leak ---------------------------------------------------------------------------------------
def _valve_leak(mode, name, source, summary, draw):
    def apply(col, e, h):
        _set(h, col, [(R.VL_MODE, float(mode)), (R.VL_A, e["magnitude"]), (R.VL_W, e["band"]),
                      (R.VL_B, e.get("critical_ratio", 0.0))])
    return Form("valve_leak", name, "chamber", source, summary, draw, apply, scaled=("magnitude",),
                slots=("valve_leak",))


VALVE_LEAK = [
    _valve_leak(F.VL_LAMINAR_UNDERLAP, "laminar_underlap", MERRITT + " (underlapped spool, laminar leakage)",
                "conductance g (1 − |s|/band)+ across both lands, g 0.8–2e-10 kg/(s Pa), band 0.1–0.2",
                lambda r, c: {"magnitude": _u(r, 0.8e-10, 2e-10), "band": _u(r, 0.1, 0.2)}),
    _valve_leak(F.VL_UNDERLAP_ORIFICE, "underlap_orifice", MERRITT + " (underlapped spool); " + ORIFICE,
                "two underlap orifices of area A (1 ± s/band) clipped to 0..A, A 1.5–4e-8 m², band 0.05–0.15",
                lambda r, c: {"magnitude": _u(r, 1.5e-8, 4e-8), "band": _u(r, 0.05, 0.15)}),
    _valve_leak(F.VL_OVERLAP_CLEARANCE, "overlap_clearance", MERRITT + " (radial clearance flow of an overlapped spool)",
                "laminar annulus G (p_up² − p_down²) / covered length, G 0.5–1.5e-16 kg/(s Pa²), overlap 0.05–0.15",
                lambda r, c: {"magnitude": _u(r, 0.5e-16, 1.5e-16), "band": _u(r, 0.05, 0.15)}),
    _valve_leak(F.VL_ISO6358, "iso6358_null_leak", ISO6358,
                "each land an ISO 6358 path, C (1 − |s|/band)+, C 0.6–1.5e-10 m³/(s Pa), band 0.1–0.2, b 0.2–0.5",
                lambda r, c: {"magnitude": _u(r, 0.6e-10, 1.5e-10), "band": _u(r, 0.1, 0.2),
                              "critical_ratio": _u(r, 0.2, 0.5)}),
]


# -- external_leak and piston_leak: three leak paths ----------------------------------------------------
def _leak_forms(family, kind, rows, slot):
    mode_row, a_row, b_row = rows

    def apply(mode):
        return lambda col, e, h: _set(h, col, [(mode_row, float(mode)), (a_row, e["magnitude"]),
                                               (b_row, e.get("critical_ratio", 0.0))])
    return [
        Form(family, f"laminar_{family}", kind, HAGEN, "ṁ = G (p_up² − p_down²), G 0.5–1.5e-16 kg/(s Pa²)",
             lambda r, c: {"magnitude": _u(r, 0.5e-16, 1.5e-16)}, apply(F.LEAK_LAMINAR),
             scaled=("magnitude",), slots=(slot,)),
        Form(family, f"orifice_{family}", kind, ORIFICE, "an orifice of effective area 1–3e-8 m²",
             lambda r, c: {"magnitude": _u(r, 1e-8, 3e-8)}, apply(F.LEAK_ORIFICE),
             scaled=("magnitude",), slots=(slot,)),
        Form(family, f"iso6358_{family}", kind, ISO6358, "C 2–6e-11 m³/(s Pa), b 0.2–0.5",
             lambda r, c: {"magnitude": _u(r, 2e-11, 6e-11), "critical_ratio": _u(r, 0.2, 0.5)},
             apply(F.LEAK_ISO6358), scaled=("magnitude",), slots=(slot,)),
    ]


EXTERNAL_LEAK = _leak_forms("external_leak", "chamber", (R.EX_MODE, R.EX_A, R.EX_B), "external_leak")
PISTON_LEAK = _leak_forms("piston_leak", "actuator", (R.PL_MODE, R.PL_A, R.PL_B), "piston_leak")


# -- valve_hysteresis (Python operators on the command, :mod:`.hysteresis`) ---------------------------------
def _hyst(name, source, summary, draw, scaled):
    return Form("valve_hysteresis", name, "chamber", source, summary, draw,
                lambda col, e, h: h.hysteresis.__setitem__(col, (name, dict(e))), scaled=scaled,
                slots=("hysteresis",))


VALVE_HYSTERESIS = [
    _hyst("bouc_wen_valve", "Wen 1976, ASCE J Eng Mech Div 102:249", "Bouc–Wen, n = 1, half width H 0.2–0.45 V",
          lambda r, c: {"half_width_v": _u(r, 0.2, 0.45)}, ("half_width_v",)),
    _hyst("play_operator", "Krasnosel'skii & Pokrovskii 1989, Systems with Hysteresis (Springer)",
          "play (backlash) operator, half width r 0.15–0.35 V",
          lambda r, c: {"half_width_v": _u(r, 0.15, 0.35)}, ("half_width_v",)),
    _hyst("preisach_relays", "Mayergoyz 1991, Mathematical Models of Hysteresis (Springer)",
          "250 relays over the command range, half widths r (1 ± spread), r 0.15–0.35 V, spread 0.3–0.8",
          lambda r, c: {"half_width_v": _u(r, 0.15, 0.35), "spread": _u(r, 0.3, 0.8),
                        "seed": int(r.integers(0, 2**31))}, ("half_width_v",)),
    _hyst("jiles_atherton", "Jiles & Atherton 1986, J Magn Magn Mater 61:48",
          "Jiles–Atherton with H = u − 5 V, pinning k 0.2–0.45 V, reversible c 0.1–0.3",
          lambda r, c: {"pinning_v": _u(r, 0.2, 0.45), "reversible": _u(r, 0.1, 0.3), "shape_v": 15.0,
                        "coupling": 0.01}, ("pinning_v",)),
]

# -- valve_lag -------------------------------------------------------------------------------------------
VALVE_LAG = [
    Form("valve_lag", "second_order_spool", "chamber", MERRITT + " (servovalve as a second-order system)",
         "ÿ = ω² (u − y) − 2ζω ẏ, f_n 6–12 Hz, ζ 0.5–0.8",
         lambda r, c: {"natural_hz": _u(r, 6.0, 12.0), "zeta": _u(r, 0.5, 0.8)},
         lambda col, e, h: _set(h, col, [(R.SP_W, 2 * math.pi * e["natural_hz"]), (R.SP_Z, e["zeta"])]),
         inverse=("natural_hz",), slots=("spool",)),
    Form("valve_lag", "first_order_spool", "chamber", MERRITT + " (first-order servovalve approximation)",
         "τ ẏ = u − y, τ 10–25 ms",
         lambda r, c: {"time_constant_s": _u(r, 0.010, 0.025)},
         lambda col, e, h: _set(h, col, [(R.SP_TAU, e["time_constant_s"])]),
         scaled=("time_constant_s",), slots=("spool",)),
    Form("valve_lag", "dead_time", "chamber", "pure transport delay of the command (valve electronics, PWM)",
         "the spool sees the command 5–25 ms late (1 ms resolution)",
         lambda r, c: {"dead_time_s": _u(r, 0.005, 0.025)},
         lambda col, e, h: h.dead_time_s.__setitem__(col, e["dead_time_s"]),
         scaled=("dead_time_s",), slots=("dead_time",)),
    Form("valve_lag", "rate_limit", "chamber", "spool slew limit: the solenoid's force bounds the spool speed",
         "|ẏ| ≤ 50–150 V/s (a full 5 V step in 33–100 ms)",
         lambda r, c: {"rate_v_s": _u(r, 50.0, 150.0)},
         lambda col, e, h: _set(h, col, [(R.SP_RATE, e["rate_v_s"])]),
         inverse=("rate_v_s",), slots=("spool",)),
]


# -- line_dynamics ----------------------------------------------------------------------------------------
def _richer(col, e, h):
    """Richer & Hurmuzlu 2000 eq. 19: delay L/c, attenuation exp(-R_t R T L / (2 p c)),
    R_t = 32 mu / d^2 (laminar), at a nominal 4 bar; the tube's volume pi d^2 L / 4 joins the
    chamber's (the air the tube holds rises and falls with the chamber's pressure: a delayed
    flow alone would keep the tube's mass constant)."""
    L, d = e["length_m"], e["diameter_m"]
    rt = 32.0 * F.MU_AIR / d ** 2
    att = math.exp(-rt * F.R_GAS * F.T0 * L / (2.0 * 4.0e5 * F.SOUND_M_S))
    _set(h, col, [(R.LN_MODE, float(K.LN_DELAYED)), (R.LN_DELAY, L / F.SOUND_M_S), (R.LN_ATT, att),
                  (R.LN_V, math.pi * d ** 2 / 4.0 * L)])


RICHER = "Richer & Hurmuzlu 2000, ASME JDSMC 122:405"
LINE = [
    Form("line_dynamics", "two_volume_line", "chamber", RICHER + " (lumped line: one R, one C)",
         "tube volume 1–3 cm³ joined to the chamber by a laminar resistance, time constant 5–15 ms",
         lambda r, c: {"tube_volume_m3": _u(r, 1e-6, 3e-6), "tube_time_constant_s": _u(r, 0.005, 0.015)},
         lambda col, e, h: _set(h, col, [(R.LN_MODE, float(K.LN_TWO_VOLUME)), (R.LN_V, e["tube_volume_m3"]),
                                         (R.LN_TAU, e["tube_time_constant_s"])]),
         scaled=("tube_volume_m3", "tube_time_constant_s"), slots=("line",)),
    Form("line_dynamics", "delay_plus_volume", "chamber", "transport delay + lumped volume (the classic simplification)",
         "the valve's flow reaches the chamber 3–10 ms late; tube volume 1–3 cm³ added to the chamber",
         lambda r, c: {"delay_s": _u(r, 0.003, 0.010), "tube_volume_m3": _u(r, 1e-6, 3e-6)},
         lambda col, e, h: _set(h, col, [(R.LN_MODE, float(K.LN_DELAYED)), (R.LN_DELAY, e["delay_s"]),
                                         (R.LN_ATT, 1.0), (R.LN_V, e["tube_volume_m3"])]),
         scaled=("delay_s", "tube_volume_m3"), slots=("line",)),
    Form("line_dynamics", "rlc_segments", "chamber", "lumped transmission line with inertance (Krichel & Sawodny)",
         "3 segments of volume, inertance L/A and laminar friction 32μ/(ρd²); tube 0.5–2 m, 2–4 mm bore",
         lambda r, c: {"length_m": _u(r, 0.5, 2.0), "diameter_m": _u(r, 0.002, 0.004)},
         lambda col, e, h: _set(h, col, [(R.LN_MODE, float(K.LN_RLC)), (R.LN_LEN, e["length_m"]),
                                         (R.LN_V, math.pi * e["diameter_m"] ** 2 / 4 * e["length_m"])]),
         scaled=("length_m",), slots=("line",)),
    Form("line_dynamics", "richer_hurmuzlu_line", "chamber", RICHER + " eq. 19",
         "distributed line: flow delayed by L/c and attenuated by exp(−R_t R T L/(2 p c)), the tube's volume π d² L/4 "
         "added to the chamber; tube 0.5–2 m, 2–4 mm bore",
         lambda r, c: {"length_m": _u(r, 0.5, 2.0), "diameter_m": _u(r, 0.002, 0.004)},
         _richer, scaled=("length_m",), slots=("line",)),
]

# -- heat_transfer ------------------------------------------------------------------------------------------
HEAT = [
    Form("heat_transfer", "flow_dependent_convection", "chamber", "Dittus–Boelter-like forced convection; " + RICHER,
         "gas temperature a state, hA = hA_nat + hA_f (|ṁ| / 2e-4 kg/s)^0.8, hA_nat 0.02–0.05, hA_f 0.4–1.2 W/K",
         lambda r, c: {"ha_natural_w_k": _u(r, 0.02, 0.05), "ha_forced_w_k": _u(r, 0.4, 1.2)},
         lambda col, e, h: _set(h, col, [(R.HT_NAT, e["ha_natural_w_k"]), (R.HT_F, e["ha_forced_w_k"]),
                                         (R.HT_SCALE, e["contribution_scale"])]),
         contribution=True, slots=("heat",)),
    Form("heat_transfer", "constant_ha", "chamber", "Newton cooling, constant h A (paper 002's polytropic alternative)",
         "gas temperature a state, hA 0.1–0.5 W/K to a wall at 293 K",
         lambda r, c: {"ha_w_k": _u(r, 0.1, 0.5)},
         lambda col, e, h: _set(h, col, [(R.HT_NAT, e["ha_w_k"]), (R.HT_SCALE, e["contribution_scale"])]),
         contribution=True, slots=("heat",)),
    Form("heat_transfer", "wall_two_node", "chamber", "two-node lumped capacitance (Incropera & DeWitt, ch. 5)",
         "gas ↔ wall hA 0.2–0.8 W/K, wall heat capacity 0.5–3 J/K, wall ↔ room 0.05–0.2 W/K",
         lambda r, c: {"ha_w_k": _u(r, 0.2, 0.8), "wall_capacity_j_k": _u(r, 0.5, 3.0),
                       "wall_room_w_k": _u(r, 0.05, 0.2)},
         lambda col, e, h: _set(h, col, [(R.HT_NAT, e["ha_w_k"]), (R.HT_CW, e["wall_capacity_j_k"]),
                                         (R.HT_WA, e["wall_room_w_k"]), (R.HT_SCALE, e["contribution_scale"])]),
         contribution=True, slots=("heat",)),
]


# -- pressure_sensor_offset ----------------------------------------------------------------------------------
def _pressure(col, e, h):
    h.pressure_offset_pa[col] = e["offset_pa"]
    h.pressure_gain_error[col] = e.get("gain_error", 0.0)
    h.pressure_drift_pa[col] = e.get("drift_pa", 0.0)
    h.pressure_drift_tau_s[col] = e.get("drift_time_constant_s", 1.0)


PRESSURE = [
    Form("pressure_sensor_offset", "offset", "chamber", "zero offset of a piezoresistive transducer",
         "p_meas = p + offset, ±8–20 kPa", lambda r, c: {"offset_pa": _sym(r, 8e3, 2e4)}, _pressure,
         scaled=("offset_pa",), slots=("pressure_sensor",)),
    Form("pressure_sensor_offset", "offset_and_gain", "chamber", "two-point calibration error (offset + span)",
         "p_atm + (1 + g)(p − p_atm) + offset, offset ±8–20 kPa, g ±1–2 %",
         lambda r, c: {"offset_pa": _sym(r, 8e3, 2e4), "gain_error": _sym(r, 0.01, 0.02)}, _pressure,
         scaled=("offset_pa", "gain_error"), slots=("pressure_sensor",)),
    Form("pressure_sensor_offset", "drifting_offset", "chamber", "thermal zero drift of a transducer warming up",
         "offset ±3–8 kPa + drift ±8–20 kPa × (1 − e^{−t/τ}), τ 10–40 s",
         lambda r, c: {"offset_pa": _sym(r, 3e3, 8e3), "drift_pa": _sym(r, 8e3, 2e4),
                       "drift_time_constant_s": _u(r, 10.0, 40.0)}, _pressure,
         scaled=("offset_pa", "drift_pa"), slots=("pressure_sensor",)),
]

# -- outside the vocabulary, at a chamber ------------------------------------------------------------------------
OUTSIDE_CHAMBER = [
    Form(OUTSIDE, "wall_compliance", "chamber", "compliant chamber wall / bellows: V = V0 + C_v (p − p_atm)",
         "C_v 1–4e-12 m³/Pa (5–15 % more volume at 6 bar gauge)",
         lambda r, c: {"compliance_m3_pa": _u(r, 1e-12, 4e-12)},
         lambda col, e, h: _set(h, col, [(R.OV_CV, e["compliance_m3_pa"])]),
         scaled=("compliance_m3_pa",), slots=("compliance",)),
    Form(OUTSIDE, "exhaust_port_restriction", "chamber",
         "a condensate or port restriction in series with that chamber's exhaust path (series orifices)",
         "a restriction of area 2–4.5e-7 m² (a third to a half of the exhaust area) throttles only the exhaust",
         lambda r, c: {"area_m2": _u(r, 2e-7, 4.5e-7)},
         lambda col, e, h: _set(h, col, [(R.OV_AR, e["area_m2"])]),
         inverse=("area_m2",), slots=("exhaust_restriction",)),
]

CHAMBER_FORMS = (VALVE_LEAK + EXTERNAL_LEAK + PISTON_LEAK + VALVE_HYSTERESIS + VALVE_LAG + LINE + HEAT
                 + PRESSURE + OUTSIDE_CHAMBER)
