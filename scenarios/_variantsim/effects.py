"""Hidden effects in functional forms that differ from pneumasim's effect library, one per
DESIGN.md vocabulary family (end_stop and force_sensor_offset left out), each with its place,
a draw of physically sensible magnitudes for a small pneumatic arm, and how a concealment
scale k acts on it (``effective``).

| family | variant form (here) | pneumasim's form |
| --- | --- | --- |
| coulomb_friction | LuGre bristle model (Canudas de Wit et al. 1995) | Coulomb + Stribeck + viscous |
| stiction | Karnopp stick-slip (Karnopp 1985): stick band, breakaway Fs > Fc | Stribeck exponential |
| viscous_friction | b0 + b1 (p_mean - p_atm): seal drag grows with cylinder pressure | constant viscous |
| valve_leak | laminar underlap flow, conductance triangular in spool position | Gaussian extra orifice area |
| external_leak | laminar capillary, mdot = G (p^2 - p_atm^2) (Hagen-Poiseuille, isothermal) | orifice |
| piston_leak | laminar, mdot = G (p_a^2 - p_b^2), mass conserving | orifice |
| valve_hysteresis | Bouc-Wen (Wen 1976), n = 1, smooth saturation | play operator |
| valve_lag | second-order spool (omega_n, zeta) | first-order lag |
| line_dynamics | tube volume + laminar resistance (two-volume model) | transport delay + volume |
| heat_transfer | gas temperature state, hA = hA0 + hA1 (|mdot|/2e-4 kg/s)^0.8 | constant hA |
| pressure_sensor_offset | offset + gain error | offset |
| angle_sensor_offset | constant encoder offset | offset |
| supply_droop | reservoir (volume) fed through a regulator orifice | static droop with flow |
| backlash | compliant dead zone: gap, contact stiffness and damping, piston inertia | rigid dead zone |
"""
from __future__ import annotations

from . import kernel as K
from .arm import CHAMBERS, JOINTS, Hidden


def _sym(r, lo, hi):
    return float(r.choice([-1.0, 1.0]) * r.uniform(lo, hi))


def _lugre(r):
    """LuGre at a small cylinder's rod seal + bearings: Fc 0.08-0.2 N m, breakaway 1.3-1.8 Fc,
    Stribeck speed 0.03-0.1 rad/s; bristle stiffness and damping (Canudas de Wit 1995 eq. 2-4)
    chosen so the bristle mode (~200 rad/s with the link inertia) stays well damped."""
    fc = r.uniform(0.08, 0.2)
    return {"fc_nm": fc, "fs_nm": fc * r.uniform(1.3, 1.8), "vs_rad_s": r.uniform(0.03, 0.1),
            "sigma0_nm_per_rad": 1000.0, "sigma1_nms_per_rad": 1.5, "sigma2_nms_per_rad": 0.0}


def _karnopp(r):
    """Karnopp: breakaway Fs 0.12-0.25 N m, sliding Fc = 0.3-0.5 Fs, stick band 0.02 rad/s."""
    fs = r.uniform(0.12, 0.25)
    return {"fs_nm": fs, "fc_nm": fs * r.uniform(0.3, 0.5), "stick_band_rad_s": 0.02}


def _dead_zone(r):
    """A worn clevis: gap 0.006-0.018 rad (0.3-1 deg); on contact a rotary stiffness of
    200-500 N m/rad (pins and rod bending; ~30-80x the cylinder's air spring) damped at
    zeta = 0.3 against the piston's inertia (arm2.md armature 5.4e-5 / 3.8e-5 kg m^2)."""
    k = r.uniform(200.0, 500.0)
    return {"gap_rad": r.uniform(0.006, 0.018), "contact_stiffness_nm_rad": k,
            "contact_damping_nms_rad": 2 * 0.3 * (k * 4.6e-5) ** 0.5}


#: family -> (place kind, form, draw(rng) -> parameters)
FAMILIES = {
    "coulomb_friction": ("joint", "lugre_friction", lambda r: _lugre(r)),
    "stiction": ("joint", "karnopp_stick_slip", lambda r: _karnopp(r)),
    "viscous_friction": ("joint", "pressure_dependent_viscous", lambda r: {
        "b0_nms": r.uniform(0.03, 0.07), "b1_nms_per_pa": r.uniform(0.8e-7, 1.6e-7)}),
    "valve_leak": ("chamber", "laminar_underlap", lambda r: {
        "conductance_kg_s_pa": r.uniform(0.8e-10, 2e-10), "band": r.uniform(0.1, 0.2)}),
    "external_leak": ("chamber", "laminar_external_leak", lambda r: {"g_kg_s_pa2": r.uniform(5e-17, 1.5e-16)}),
    "piston_leak": ("actuator", "laminar_piston_leak", lambda r: {"g_kg_s_pa2": r.uniform(5e-17, 1.5e-16)}),
    "valve_hysteresis": ("chamber", "bouc_wen_valve", lambda r: {"half_width_v": r.uniform(0.2, 0.45)}),
    "valve_lag": ("chamber", "second_order_spool", lambda r: {
        "natural_hz": r.uniform(6.0, 12.0), "zeta": r.uniform(0.5, 0.8)}),
    "line_dynamics": ("chamber", "two_volume_line", lambda r: {
        "tube_volume_m3": r.uniform(1e-6, 3e-6), "tube_time_constant_s": r.uniform(0.005, 0.015)}),
    "heat_transfer": ("chamber", "flow_dependent_convection", lambda r: {
        "ha_natural_w_k": r.uniform(0.02, 0.05), "ha_forced_w_k": r.uniform(0.4, 1.2)}),
    "pressure_sensor_offset": ("chamber", "offset_and_gain", lambda r: {
        "offset_pa": _sym(r, 8e3, 2e4), "gain_error": _sym(r, 0.01, 0.02)}),
    "angle_sensor_offset": ("joint", "encoder_offset", lambda r: {"offset_rad": _sym(r, 0.03, 0.06)}),
    "supply_droop": ("supply", "regulator_reservoir", lambda r: {
        "regulator_area_m2": r.uniform(0.4e-6, 0.8e-6), "reservoir_volume_m3": r.uniform(2e-5, 5e-5)}),
    "backlash": ("joint", "compliant_dead_zone", lambda r: _dead_zone(r)),
}

#: parameters the concealment scale leaves alone (shapes, not magnitudes)
SHAPE = {"vs_rad_s", "stick_band_rad_s", "band", "zeta", "contact_stiffness_nm_rad", "contact_damping_nms_rad",
         "reservoir_volume_m3"}


def effective(family: str, params: dict, k: float) -> dict:
    """The parameters at concealment scale k: magnitudes times k; a spool's time scale and a
    regulator's resistance shrink with k (natural frequency / area divided by k); the heat
    model keeps its h A and scales its contribution to dp/dt (``contribution_scale``)."""
    out = {}
    for key, v in params.items():
        if key in SHAPE:
            out[key] = v
        elif key in ("natural_hz", "regulator_area_m2"):
            out[key] = v / k
        elif family == "heat_transfer":
            out[key] = v
        else:
            out[key] = v * k
    if family == "heat_transfer":
        out["contribution_scale"] = k
    return out


def place_names(kind: str) -> list[str]:
    return {"joint": list(JOINTS), "chamber": list(CHAMBERS), "actuator": list(JOINTS), "supply": ["all"]}[kind]


def where(kind: str, place: str) -> dict:
    if kind == "chamber":
        a, c = place.split(".")
        return {"actuator": a, "chamber": c}
    return {"actuator": place} if kind == "actuator" else {"supply": "all"} if kind == "supply" else {"joint": place}


def apply(family: str, place: str, e: dict, hidden: Hidden) -> None:
    """Switch one effect with effective parameters ``e`` on in ``hidden``."""
    kind = FAMILIES[family][0]
    col = CHAMBERS.index(place) if kind == "chamber" else 0 if kind == "supply" else JOINTS.index(place)
    rows = hidden.P_rows
    if family == "coulomb_friction":
        for row, key in ((K.LG_FC, "fc_nm"), (K.LG_FS, "fs_nm"), (K.LG_VS, "vs_rad_s"), (K.LG_S0, "sigma0_nm_per_rad"),
                         (K.LG_S1, "sigma1_nms_per_rad"), (K.LG_S2, "sigma2_nms_per_rad")):
            rows[row, col] = e[key]
    elif family == "stiction":
        rows[K.KP_FS, col], rows[K.KP_FC, col], rows[K.KP_DV, col] = e["fs_nm"], e["fc_nm"], e["stick_band_rad_s"]
    elif family == "viscous_friction":
        rows[K.VS_B0, col], rows[K.VS_B1, col] = e["b0_nms"], e["b1_nms_per_pa"]
    elif family == "valve_leak":
        rows[K.UL_G, col], rows[K.UL_B, col] = e["conductance_kg_s_pa"], e["band"]
    elif family == "external_leak":
        rows[K.EX_G, col] = e["g_kg_s_pa2"]
    elif family == "piston_leak":
        rows[K.PL_G, col] = e["g_kg_s_pa2"]
    elif family == "valve_hysteresis":
        hidden.bw_half_width_v[col] = e["half_width_v"]
    elif family == "valve_lag":
        rows[K.SP_W, col], rows[K.SP_Z, col] = 2 * 3.141592653589793 * e["natural_hz"], e["zeta"]
    elif family == "line_dynamics":
        rows[K.LN_V, col], rows[K.LN_TAU, col] = e["tube_volume_m3"], e["tube_time_constant_s"]
    elif family == "heat_transfer":
        rows[K.HT_NAT, col], rows[K.HT_F, col] = e["ha_natural_w_k"], e["ha_forced_w_k"]
        rows[K.HT_SCALE, col] = e["contribution_scale"]
    elif family == "pressure_sensor_offset":
        hidden.pressure_offset_pa[col], hidden.pressure_gain_error[col] = e["offset_pa"], e["gain_error"]
    elif family == "angle_sensor_offset":
        hidden.angle_offset_rad[col] = e["offset_rad"]
    elif family == "supply_droop":
        rows[K.SU_A, 0], rows[K.SU_V, 0] = e["regulator_area_m2"], e["reservoir_volume_m3"]
    elif family == "backlash":
        rows[K.BL_GAP, col], rows[K.BL_K, col] = e["gap_rad"], e["contact_stiffness_nm_rad"]
        rows[K.BL_C, col] = e["contact_damping_nms_rad"]
    else:
        raise KeyError(f"unknown variant family {family!r}; known: {sorted(FAMILIES)}")


def hidden_for(effects: list[dict], k: float) -> Hidden:
    """A Hidden with every effect ({family, place, parameters}) at concealment scale k."""
    h = Hidden()
    for eff in effects:
        apply(eff["family"], eff["place"], effective(eff["family"], eff["parameters"], k), h)
    return h
