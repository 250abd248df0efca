"""Joint-side forms of the variant simulator: friction (coulomb_friction, stiction,
viscous_friction), backlash, end_stop, angle_sensor_offset and the joint torques outside the
vocabulary.  Magnitudes are for arm2's small cylinders: the cylinders give up to ~5 N m
(shoulder) and ~3 N m (elbow), the forearm's gravity torque is ~0.7 N m, the link inertias
about the joints ~0.015-0.02 kg m^2, the piston inertias 3.8-5.4e-5 kg m^2 (arm2.md).
Friction laws that switch with sign v are regularised by tanh(v/ve), ve >= 0.02 rad/s: the
1 ms explicit step stays stable for Fs/ve below ~2 I/dt (~30 N m s/rad).
"""
from __future__ import annotations

import math

import numpy as np

from . import rows as R
from .forms import OUTSIDE, Form


def _u(r, lo, hi):
    return float(r.uniform(lo, hi))


def _sym(r, lo, hi):
    return float(r.choice([-1.0, 1.0]) * r.uniform(lo, hi))


def _set(hidden, col, pairs):
    for row, v in pairs:
        hidden.P_rows[row, col] = v


# -- coulomb_friction ------------------------------------------------------------------------------
def _lugre(r, c):
    """Fc 0.08-0.2 N m, breakaway 1.1-1.4 Fc (a mild Stribeck dip: a friction holding 2 Fc or
    more is the stiction family's, and between the two a name means little), Stribeck speed
    0.03-0.1 rad/s; bristle stiffness 1000 N m/rad and damping 1.5 N m s/rad keep the bristle
    mode (~250 rad/s with the link inertia) well damped."""
    fc = _u(r, 0.08, 0.2)
    return {"fc_nm": fc, "fs_nm": fc * _u(r, 1.1, 1.4), "vs_rad_s": _u(r, 0.03, 0.1),
            "sigma0_nm_per_rad": 1000.0, "sigma1_nms_per_rad": 1.5, "sigma2_nms_per_rad": 0.0}


def _apply_lugre(col, e, h):
    _set(h, col, [(R.LG_FC, e["fc_nm"]), (R.LG_FS, e["fs_nm"]), (R.LG_VS, e["vs_rad_s"]),
                  (R.LG_S0, e["sigma0_nm_per_rad"]), (R.LG_S1, e["sigma1_nms_per_rad"]),
                  (R.LG_S2, e["sigma2_nms_per_rad"])])


def _apply_curve(col, e, h):
    fs = e.get("fs_nm", 0.0)
    _set(h, col, [(R.SF_FC, e["fc_nm"]), (R.SF_FS, fs), (R.SF_VS, e.get("vs_rad_s", 1.0)),
                  (R.SF_DELTA, e.get("delta", 2.0)), (R.SF_VE, e["ve_rad_s"])])


LUGRE = "Canudas de Wit, Olsson, Åström, Lischinsky 1995, IEEE TAC 40:419"
COULOMB = [
    Form("coulomb_friction", "lugre_friction", "joint", LUGRE,
         "LuGre bristle model, F = σ0 z + σ1 ż + σ2 v, ż = v − σ0 |v| z / g(v), Fs 1.1–1.4 Fc",
         _lugre, _apply_lugre, scaled=("fc_nm", "fs_nm", "sigma0_nm_per_rad", "sigma1_nms_per_rad"), slots=("lugre",)),
    Form("coulomb_friction", "coulomb_tanh", "joint",
         "Coulomb; tanh regularisation as surveyed by Armstrong-Hélouvry, Dupont, Canudas de Wit 1994, Automatica 30:1083",
         "Fc tanh(v/ve), Fc 0.08–0.2 N m, ve 0.02–0.04 rad/s",
         lambda r, c: {"fc_nm": _u(r, 0.08, 0.2), "ve_rad_s": _u(r, 0.02, 0.04)},
         _apply_curve, scaled=("fc_nm",), slots=("static_curve",)),
    Form("coulomb_friction", "dahl", "joint", "Dahl 1976, AIAA J 14:1675",
         "dF/dt = σ v (1 − F/Fc sign v): presliding spring σ 300–1000 N m/rad saturating at Fc 0.08–0.2 N m",
         lambda r, c: {"fc_nm": _u(r, 0.08, 0.2), "sigma_nm_per_rad": _u(r, 300.0, 1000.0)},
         lambda col, e, h: _set(h, col, [(R.DH_FC, e["fc_nm"]), (R.DH_SIG, e["sigma_nm_per_rad"])]),
         scaled=("fc_nm",), slots=("dahl",)),
    Form("coulomb_friction", "pressure_dependent_seal", "joint",
         "Belforte, Mattiazzo, Mauro, Tokashiki 2003, Tribotest 10:33 (seal friction grows with pressure)",
         "Fc = cp (p_a + p_b − 2 p_atm) tanh(v/ve), cp 1.5–3e-7 N m/Pa (0.1–0.2 N m at 6.5 bar summed gauge)",
         lambda r, c: {"cp_nm_per_pa": _u(r, 1.5e-7, 3e-7), "ve_rad_s": _u(r, 0.02, 0.04)},
         lambda col, e, h: _set(h, col, [(R.SE_CP, e["cp_nm_per_pa"]), (R.SE_VE, e["ve_rad_s"])]),
         scaled=("cp_nm_per_pa",), slots=("seal",)),
]


# -- stiction ----------------------------------------------------------------------------------------
def _karnopp(r, c):
    """Breakaway Fs 0.12-0.25 N m, sliding Fc = 0.3-0.5 Fs, stick band 0.02 rad/s."""
    fs = _u(r, 0.12, 0.25)
    return {"fs_nm": fs, "fc_nm": fs * _u(r, 0.3, 0.5), "stick_band_rad_s": 0.02}


#: the stiction family's friction holds at least this many times its sliding level
STICTION_MIN_PEAK = 2.0


def stribeck_peak(e: dict) -> float:
    """The largest value of a regularised Stribeck curve (Fc + (Fs - Fc) exp(-|v/vs|^delta))
    tanh(v/ve) over its sliding level Fc: what the joint can hold.  A tanh as wide as the
    Stribeck velocity hides most of the breakaway (Fs 2.8 Fc, vs 0.022, delta 0.78 peaks at 1.35)."""
    v = np.linspace(1e-5, 10.0 * max(e["vs_rad_s"], e["ve_rad_s"]), 4000)
    curve = (e["fc_nm"] + (e["fs_nm"] - e["fc_nm"]) * np.exp(-np.abs(v / e["vs_rad_s"]) ** e["delta"])) \
        * np.tanh(v / e["ve_rad_s"])
    return float(curve.max() / e["fc_nm"])


def _stribeck_power(r, c):
    """Fc 0.04-0.1 N m, Fs 2-3.5 Fc, vs 0.02-0.06 rad/s, delta 0.5-2, drawn again until the
    regularised curve peaks at STICTION_MIN_PEAK Fc or more (stribeck_peak)."""
    while True:
        fc = _u(r, 0.04, 0.1)
        e = {"fc_nm": fc, "fs_nm": fc * _u(r, 2.0, 3.5), "vs_rad_s": _u(r, 0.02, 0.06),
             "delta": _u(r, 0.5, 2.0), "ve_rad_s": 0.02}
        if stribeck_peak(e) >= STICTION_MIN_PEAK:
            return e


def _lugre_breakaway(r, c):
    fc = _u(r, 0.04, 0.08)
    return {"fc_nm": fc, "fs_nm": fc * _u(r, 2.5, 4.0), "vs_rad_s": _u(r, 0.01, 0.04),
            "sigma0_nm_per_rad": 1000.0, "sigma1_nms_per_rad": 1.5, "sigma2_nms_per_rad": 0.0}


STICTION = [
    Form("stiction", "karnopp_stick_slip", "joint", "Karnopp 1985, ASME JDSMC 107:100",
         "|v| < 0.02 rad/s holds up to Fs the torque that would stop the joint, else Fc sign v",
         _karnopp, lambda col, e, h: _set(h, col, [(R.KP_FS, e["fs_nm"]), (R.KP_FC, e["fc_nm"]),
                                                   (R.KP_DV, e["stick_band_rad_s"])]),
         scaled=("fs_nm", "fc_nm"), slots=("karnopp",)),
    Form("stiction", "stribeck_power", "joint",
         "Armstrong-Hélouvry et al. 1994, Automatica 30:1083; exponent δ of Bo & Pavelescu 1982, Wear 82:277",
         "(Fc + (Fs − Fc) exp(−|v/vs|^δ)) tanh(v/ve), Fs 2–3.5 Fc, δ 0.5–2, peaking at 2 Fc or more",
         _stribeck_power, _apply_curve, scaled=("fc_nm", "fs_nm"), slots=("static_curve",)),
    Form("stiction", "lugre_breakaway", "joint", LUGRE,
         "LuGre with a high breakaway, Fs 2.5–4 Fc, Fc 0.04–0.08 N m",
         _lugre_breakaway, _apply_lugre, scaled=("fc_nm", "fs_nm", "sigma0_nm_per_rad", "sigma1_nms_per_rad"),
         slots=("lugre",)),
]

# -- viscous_friction --------------------------------------------------------------------------------
VISCOUS = [
    Form("viscous_friction", "pressure_dependent_viscous", "joint", "Belforte et al. 2003, Tribotest 10:33",
         "(b0 + b1 (p̄ − p_atm)) v, p̄ the cylinder's mean chamber pressure",
         lambda r, c: {"b0_nms": _u(r, 0.03, 0.07), "b1_nms_per_pa": _u(r, 0.8e-7, 1.6e-7)},
         lambda col, e, h: _set(h, col, [(R.VS_B0, e["b0_nms"]), (R.VS_B1, e["b1_nms_per_pa"]), (R.VS_N, 1.0)]),
         scaled=("b0_nms", "b1_nms_per_pa"), slots=("viscous",)),
    Form("viscous_friction", "linear_viscous", "joint", "Newtonian film (Armstrong-Hélouvry et al. 1994)",
         "b v, b 0.04–0.09 N m s/rad",
         lambda r, c: {"b_nms": _u(r, 0.04, 0.09)},
         lambda col, e, h: _set(h, col, [(R.VS_B0, e["b_nms"]), (R.VS_N, 1.0)]),
         scaled=("b_nms",), slots=("viscous",)),
    Form("viscous_friction", "velocity_power", "joint",
         "Andersson, Söderberg, Björklund 2007, Tribology Int 40:580",
         "b |v|^n sign v, n 0.4–0.7 or 1.5–2, b 0.04–0.09 N m (s/rad)^n (linear below 0.05 rad/s when n < 1)",
         lambda r, c: {"b_nms_n": _u(r, 0.04, 0.09),
                       "exponent": _u(r, 0.4, 0.7) if r.random() < 0.5 else _u(r, 1.5, 2.0)},
         lambda col, e, h: _set(h, col, [(R.VS_B0, e["b_nms_n"]), (R.VS_N, e["exponent"])]),
         scaled=("b_nms_n",), slots=("viscous",)),
]


# -- backlash ----------------------------------------------------------------------------------------
def _dead_zone(r, c, k_lo, k_hi, zeta):
    """Gap 0.006-0.018 rad (0.3-1 deg); contact stiffness k against the piston's inertia
    (~4.6e-5 kg m^2), damped at ratio zeta."""
    k = _u(r, k_lo, k_hi)
    return {"gap_rad": _u(r, 0.006, 0.018), "contact_stiffness_nm_rad": k,
            "contact_damping_nms_rad": 2 * zeta * math.sqrt(k * 4.6e-5)}


def _apply_dead_zone(col, e, h):
    _set(h, col, [(R.BL_GAP, e["gap_rad"]), (R.BL_K, e["contact_stiffness_nm_rad"]),
                  (R.BL_C, e["contact_damping_nms_rad"]), (R.BL_N, e.get("exponent", 0.0))])


NORDIN = "Nordin & Gutman 2002, Automatica 38:1633"
BACKLASH = [
    Form("backlash", "compliant_dead_zone", "joint", NORDIN,
         "gap between piston (own inertia) and link, contact 200–500 N m/rad at ζ 0.3",
         lambda r, c: _dead_zone(r, c, 200.0, 500.0, 0.3), _apply_dead_zone, scaled=("gap_rad",), slots=("dead_zone",)),
    # the stiffest contact the 0.25 ms symplectic step keeps stable on the elbow's 3.8e-5 kg m^2
    # piston: (w dt)^2 + 2 (c / J) dt < 4 gives 2.9 at 900 N m/rad and zeta 0.3; at zeta 0.7 it
    # was 4.8, and the elbow's recordings came out NaN ("variantsim-2")
    Form("backlash", "rigid_dead_zone", "joint", NORDIN + " (the rigid limit)",
         "gap with contact as stiff as the 0.25 ms step keeps stable (700–900 N m/rad, ζ 0.3)",
         lambda r, c: _dead_zone(r, c, 700.0, 900.0, 0.3), _apply_dead_zone, scaled=("gap_rad",), slots=("dead_zone",)),
    Form("backlash", "impact_damped_dead_zone", "joint", "Hunt & Crossley 1975, ASME J Appl Mech 42:440",
         "gap with Hunt–Crossley contact (k + c δ̇) δ^1.5, k 1500–2500 N m/rad^1.5, c = 1.5 α k, α 2–4 ms/rad",
         lambda r, c: (lambda k: {"gap_rad": _u(r, 0.006, 0.018), "contact_stiffness_nm_rad": k,
                                  "contact_damping_nms_rad": 1.5 * _u(r, 0.002, 0.004) * k, "exponent": 1.5})(
             _u(r, 1500.0, 2500.0)),
         _apply_dead_zone, scaled=("gap_rad",), slots=("dead_zone",)),
]


# -- end_stop ----------------------------------------------------------------------------------------
DEFAULT_REACH = (-0.66, 0.66)   #: +-38 deg: the reference's held extremes when ctx gives none


#: how far beyond the reference's extreme a fully concealed stop (k -> 0) sits [rad]: the
#: reference dwells at its clipped extremes and the arm tracks within ~2 deg RMS
STOP_MARGIN_RAD = 0.05


def _stop_place(r, ctx):
    """Bumper angles inside the reference's reach at the place's joint, one- or two-sided:
    a side's stop sits at extreme + margin - intrusion, the intrusion drawn as margin +
    0.1-0.4 of that side's extreme.  The concealment scale shrinks the intrusion: the stop
    moves out past the extreme, touched only by overshoots (a softer stop that the arm still
    leans on stays visible in the pressures)."""
    ctx = ctx or {}
    lo, hi = ctx.get("reach_rad", {}).get(ctx.get("place"), DEFAULT_REACH)
    sides = str(r.choice(["upper", "lower", "both"]))
    if hi < 0.1 or lo > -0.1:          # the reference stays on one side: the stop goes there
        sides = "lower" if hi < 0.1 else "upper"
    return {"sides": sides, "reach_upper_rad": hi, "reach_lower_rad": lo,
            "upper_intrusion_rad": STOP_MARGIN_RAD + hi * _u(r, 0.1, 0.4) if sides in ("upper", "both") else 0.0,
            "lower_intrusion_rad": STOP_MARGIN_RAD - lo * _u(r, 0.1, 0.4) if sides in ("lower", "both") else 0.0}


def _stop_angles(e) -> tuple[float, float]:
    """(upper, lower) stop angles [rad]; a side without a stop parks at +-10 rad."""
    up = e["reach_upper_rad"] + STOP_MARGIN_RAD - e["upper_intrusion_rad"] if e["sides"] in ("upper", "both") else 10.0
    dn = e["reach_lower_rad"] - STOP_MARGIN_RAD + e["lower_intrusion_rad"] if e["sides"] in ("lower", "both") else -10.0
    return up, dn


def _bumper(mode):
    def draw(r):
        k = _u(r, 100.0, 300.0)                    # N m/rad: a rubber bumper, ~5 deg at full push
        zeta = _u(r, 0.2, 0.5)
        p = {"mode": mode, "stiffness_nm_rad": k, "damping_nms_rad": 2 * zeta * math.sqrt(k * 0.017),
             "exponent": 1.0, "cubic_nm_rad3": 0.0}
        if mode == 2:       # Hunt-Crossley: equal to the linear force at 0.05 rad; c = 1.5 alpha k
            p["stiffness_nm_rad"] = k / math.sqrt(0.05)
            p["damping_nms_rad"] = 1.5 * _u(r, 0.2, 0.5) * p["stiffness_nm_rad"]
            p["exponent"] = 1.5
        elif mode == 3:     # progressive: soft first contact, k3 pen^2 = 0.7 k at 0.1 rad
            p["stiffness_nm_rad"], p["cubic_nm_rad3"] = 0.3 * k, 70.0 * k
        return p
    return draw


def _end_stop_form(name, mode, source, summary):
    bump = _bumper(mode)

    def draw(r, ctx):
        return {**_stop_place(r, ctx), **bump(r)}

    def apply(col, e, h):
        up, dn = _stop_angles(e)
        _set(h, col, [(R.ES_MODE, float(e["mode"])), (R.ES_HI, up), (R.ES_LO, dn),
                      (R.ES_K, e["stiffness_nm_rad"]), (R.ES_C, e["damping_nms_rad"]), (R.ES_N, e["exponent"]),
                      (R.ES_K3, e["cubic_nm_rad3"])])
    return Form("end_stop", name, "joint", source, summary, draw, apply,
                scaled=("upper_intrusion_rad", "lower_intrusion_rad"), slots=("end_stop",))


END_STOP = [
    _end_stop_form("linear_bumper", 1, "Kelvin–Voigt contact (spring–damper)",
                   "k δ + c δ̇ past the stop angle, k 100–300 N m/rad, ζ 0.2–0.5; one- or two-sided, "
                   "intruding 0.1–0.4 of the reference's extreme (k moves it out to 0.05 rad past it)"),
    _end_stop_form("hunt_crossley_bumper", 2, "Hunt & Crossley 1975; Marhefka & Orin 1999, IEEE SMC-A 29:566",
                   "(k + c δ̇) δ^1.5, c = 1.5 α k, α 0.2–0.5 s/rad"),
    _end_stop_form("progressive_bumper", 3, "elastomer bump stop, Gillespie 1992, Fundamentals of Vehicle Dynamics (SAE)",
                   "k δ + k3 δ³ + c δ̇, stiffening ~10x over 0.2 rad"),
]

# -- angle_sensor_offset -------------------------------------------------------------------------------
ANGLE = [
    Form("angle_sensor_offset", "encoder_offset", "joint", "zero-position error of an absolute encoder",
         "q_meas = q + offset, ±0.03–0.06 rad",
         lambda r, c: {"offset_rad": _sym(r, 0.03, 0.06)},
         lambda col, e, h: h.angle_offset_rad.__setitem__(col, e["offset_rad"]),
         scaled=("offset_rad",), slots=("angle_sensor",)),
    Form("angle_sensor_offset", "offset_and_scale", "joint", "two-point encoder calibration error (offset + gain)",
         "q_meas = (1 + g) q + offset, offset ±0.01–0.03 rad, g ±1–3 %",
         lambda r, c: {"offset_rad": _sym(r, 0.01, 0.03), "gain_error": _sym(r, 0.01, 0.03)},
         lambda col, e, h: (h.angle_offset_rad.__setitem__(col, e["offset_rad"]),
                            h.angle_gain_error.__setitem__(col, e["gain_error"])),
         scaled=("offset_rad", "gain_error"), slots=("angle_sensor",)),
    Form("angle_sensor_offset", "eccentric_encoder", "joint",
         "disc eccentricity: a once-per-turn sinusoidal error (e.g. Heidenhain, Angle Encoders, accuracy chapter)",
         "q_meas = q + offset + e sin(q + φ), offset ±0.01–0.03 rad, e 0.005–0.015 rad",
         lambda r, c: {"offset_rad": _sym(r, 0.01, 0.03), "eccentric_rad": _u(r, 0.005, 0.015),
                       "phase_rad": _u(r, 0.0, 2 * math.pi)},
         lambda col, e, h: (h.angle_offset_rad.__setitem__(col, e["offset_rad"]),
                            h.angle_wobble_rad.__setitem__(col, e["eccentric_rad"]),
                            h.angle_wobble_phase.__setitem__(col, e["phase_rad"])),
         scaled=("offset_rad", "eccentric_rad"), slots=("angle_sensor",)),
]

# -- outside the vocabulary, at a joint -------------------------------------------------------------
OUTSIDE_JOINT = [
    Form(OUTSIDE, "hose_spring", "joint", "a hose or cable pulling the link: linear elastic member (Hooke)",
         "torque −k (q − q0), k 1–3 N m/rad, q0 ±0.3 rad",
         lambda r, c: {"stiffness_nm_rad": _u(r, 1.0, 3.0), "rest_rad": _u(r, -0.3, 0.3)},
         lambda col, e, h: _set(h, col, [(R.OJ_K, e["stiffness_nm_rad"]), (R.OJ_Q0, e["rest_rad"])]),
         scaled=("stiffness_nm_rad",), slots=("spring",)),
    Form(OUTSIDE, "cogging", "joint", "position-periodic detent torque (cogging), A sin(2π q/pitch + φ)",
         "A 0.05–0.2 N m, pitch 5–15 deg",
         lambda r, c: {"amplitude_nm": _u(r, 0.05, 0.2), "pitch_rad": math.radians(_u(r, 5.0, 15.0)),
                       "phase_rad": _u(r, 0.0, 2 * math.pi)},
         lambda col, e, h: _set(h, col, [(R.OJ_COG, e["amplitude_nm"]), (R.OJ_PITCH, e["pitch_rad"]),
                                         (R.OJ_PH, e["phase_rad"])]),
         scaled=("amplitude_nm",), slots=("cogging",)),
]

JOINT_FORMS = COULOMB + STICTION + VISCOUS + BACKLASH + END_STOP + ANGLE + OUTSIDE_JOINT
