"""Row numbers of the variant kernel's parameter matrix P (NP, 4) and state matrix S (NS, 4).

Columns: chambers 0..3 = shoulder.a, shoulder.b, elbow.a, elbow.b; joints / actuators 0..1 =
shoulder, elbow; the supply uses column 0.  A parameter row left at 0 switches its effect
off; a ``*_MODE`` row picks the effect's form (the constants beside the kernels that read it).
"""
from __future__ import annotations

# -- parameters: the arm (arm2.md) -----------------------------------------------------------
AS, AE, VD, ACYL, SIGN = 0, 1, 2, 3, 4       # chamber: valve areas [m^2], dead volume [m^3], piston area, +1 a / -1 b
R_ARM, STROKE, DAMP, INERTIA = 5, 6, 7, 8    # joint: moment arm [m], stroke [m], MJCF damping, rough inertia (Karnopp)
# -- chamber effects ---------------------------------------------------------------------------
VL_MODE, VL_A, VL_W, VL_B = 9, 10, 11, 12    # valve leak: form, magnitude, band / overlap (of s), critical ratio
EX_MODE, EX_A, EX_B = 13, 14, 15             # external leak: form, magnitude, critical ratio
SP_W, SP_Z, SP_TAU, SP_RATE = 16, 17, 18, 19  # spool: omega_n [rad/s], zeta; first-order tau [s]; rate limit [V/s]
LN_MODE, LN_V, LN_TAU, LN_DELAY, LN_ATT, LN_LEN = 20, 21, 22, 23, 24, 25   # line (flows.py / kernel.py)
HT_NAT, HT_F, HT_SCALE, HT_CW, HT_WA = 26, 27, 28, 29, 30   # heat: hA nat, hA forced [W/K], scale, wall C [J/K], wall-room [W/K]
OV_CV, OV_AR = 31, 32                        # outside: wall compliance [m^3/Pa], exhaust port restriction [m^2]
# -- actuator (piston) leak ----------------------------------------------------------------------
PL_MODE, PL_A, PL_B = 33, 34, 35
# -- joint friction elements (mechanics.friction) -------------------------------------------------
LG_FC, LG_FS, LG_VS, LG_S0, LG_S1, LG_S2 = 36, 37, 38, 39, 40, 41
KP_FS, KP_FC, KP_DV = 42, 43, 44
SF_FC, SF_FS, SF_VS, SF_DELTA, SF_VE = 45, 46, 47, 48, 49
DH_FC, DH_SIG = 50, 51
SE_CP, SE_VE = 52, 53
VS_B0, VS_B1, VS_N = 54, 55, 56
# -- joint: transmission, stops, outside torques -----------------------------------------------
BL_GAP, BL_K, BL_C, BL_J, BL_N = 57, 58, 59, 60, 61   # dead zone: gap [rad], contact k, c, piston inertia, exponent
ES_MODE, ES_HI, ES_LO, ES_K, ES_C, ES_N, ES_K3 = 62, 63, 64, 65, 66, 67, 68
OJ_K, OJ_Q0, OJ_COG, OJ_PITCH, OJ_PH = 69, 70, 71, 72, 73
# -- supply (column 0) ---------------------------------------------------------------------------
SU_MODE, SU_A, SU_V, SU_R, SU_BAND, SU_QC, SU_LK = 74, 75, 76, 77, 78, 79, 80
OS_AMP, OS_HZ, OS_STEP, OS_T = 81, 82, 83, 84   # outside: ripple [Pa], [Hz]; step [Pa] at time [s]
NP = 85

# -- states --------------------------------------------------------------------------------------
SP, ST, SPT, SY, SYD = 0, 1, 2, 3, 4         # chamber: pressure, gas temperature, tube pressure, spool, spool rate
SLZ, STH, STHD = 5, 6, 7                     # joint: LuGre bristle, piston angle, piston rate
SPS = 8                                      # col 0: supply (reservoir) pressure
STW, SDZ = 9, 10                             # chamber: wall temperature; joint: Dahl friction torque
SCMP, SMS, SCLK = 11, 12, 13                 # col 0: compressor on, filtered supply flow, clock [s]
SN0, SM0 = 14, 17                            # chamber: RLC line node pressures (3), segment mass flows (3)
SBI, SB0 = 20, 21                            # chamber: delay-line write index, ring buffer of valve flows
NBUF = 64                                    #: ring buffer length in fluid sub-steps (16 ms at 0.25 ms)
NS = SB0 + NBUF
