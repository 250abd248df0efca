"""Physical effects the jet-pipe simulator can switch on (DESIGN.md effect vocabulary): the
mismatch finder's concealed truths and its hypotheses (identification/doctor/jetpipe/diagnose.py).

The bench of paper 000 (Fig. 8): piston on the rod stopper, force sensor on the rod, chamber
pressure transducers, coil current and a jet-position sensor (PSD).  Each effect is a small
physical model with unit-carrying parameters (:class:`JetpipeEffects`), implemented twice with the
same arithmetic -- :func:`rhs` / :func:`rk4_step` in numpy (readable reference) and
:func:`step` compiled with numba -- on the extended state

    y (7,) = [i, z1, x_jp, dx_jp/dt, P1, P2, i_lag]      (A, m, m, m/s, Pa, Pa, A)

(plant.py's 6 states plus the lagged current that drives the torque motor when ``valve_lag_s``
> 0).  Two inputs are held over each RK4 substep, computed from the state at its start (as
plant.py holds the hysteresis): the hysteresis output and the drooped supply pressure.
Sensor offsets change only what is observed (:meth:`JetpipeEffects.observe`).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import ConfigError
from ..medium import orifice_flow
from . import kernel as k
from .params import JetpipeCfg
from .plant import rhs as plant_rhs
from .ports import orifice_areas

I_LAG = 6
N_STATE = 7
(FX_LAG, FX_EXT_A, FX_EXT_B, FX_PISTON, FX_DROOP) = range(5)


@dataclass(frozen=True)
class JetpipeEffects:
    """Effects beyond paper 000's model; all zero = the paper's model (plus our hysteresis)."""

    pressure_sensor_offset_a_pa: float = 0.0
    """pressure_sensor_offset: chamber-1 ('a') transducer reads P1 + this [Pa] (zero drift of a
    strain-gauge transducer; observation only)."""
    pressure_sensor_offset_b_pa: float = 0.0
    """pressure_sensor_offset: chamber-2 ('b') transducer reads P2 + this [Pa] (observation only)."""
    force_sensor_offset_n: float = 0.0
    """force_sensor_offset: the rod's load cell reads the force + this [N] (bridge zero drift;
    observation only, but the force controller acts on the reading, so the true force moves)."""
    external_leak_a_m2: float = 0.0
    """external_leak: effective area C_d A [m^2] of a leak from chamber 1 to the room (worn rod or
    fitting seal), isentropic orifice flow (paper 000 eq. 5, pneumatics.medium.orifice_flow)."""
    external_leak_b_m2: float = 0.0
    """external_leak: the same from chamber 2 [m^2]."""
    piston_leak_m2: float = 0.0
    """piston_leak: effective area [m^2] of a cross-piston leak added to the paper's eq. 6 leak
    (a scored graphite piston), orifice flow from the higher to the lower chamber (eq. 5)."""
    valve_lag_s: float = 0.0
    """valve_lag: time constant [s] of a first-order lag between the measured coil current and
    the torque-motor force k_m i (eddy currents in the armature, magnetic flux lag: Merritt,
    *Hydraulic Control Systems*, 1967, Sec. 8); the recorded current does not show it."""
    supply_droop_pa_per_kg_s: float = 0.0
    """supply_droop: the supply pressure falls by this [Pa per kg/s] times the valve's total
    supply mass flow (the regulator and supply line's resistance: a linear droop, as a
    pressure regulator's flow characteristic), evaluated at the start of each substep."""
    hysteresis_extra_half_width_m: float = 0.0
    """valve_hysteresis: change [m] of the current -> jet-position hysteresis half-width from
    the model's [hysteresis] half_width_m (Prandtl-Ishlinskii plays, hysteresis.py; e.g.
    magnetic hysteresis of the torque motor that differs from the paper's 8 %)."""

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"JetpipeEffects.{f.name} = {v!r}: expected a finite number")
        for name in ("external_leak_a_m2", "external_leak_b_m2", "piston_leak_m2", "valve_lag_s",
                     "supply_droop_pa_per_kg_s"):
            if getattr(self, name) < 0:
                raise ConfigError(f"JetpipeEffects.{name} = {getattr(self, name)!r}: must be >= 0")

    def pack(self) -> np.ndarray:
        """(5,) the dynamic effects for the compiled step (FX_* indices)."""
        return np.array([self.valve_lag_s, self.external_leak_a_m2, self.external_leak_b_m2,
                         self.piston_leak_m2, self.supply_droop_pa_per_kg_s], dtype=np.float64)

    def half_width_n(self, cfg: JetpipeCfg) -> float:
        """The hysteresis half-width as tip force [N] with the extra width (params.py's mapping)."""
        h = cfg.hysteresis.half_width_m + self.hysteresis_extra_half_width_m
        if not 0.0 <= h < cfg.jet.saturation_m:
            raise ConfigError(f"JetpipeEffects.hysteresis_extra_half_width_m = {self.hysteresis_extra_half_width_m!r}: "
                              f"total half-width {h:g} m must be in [0, x_sat = {cfg.jet.saturation_m:g} m)")
        return cfg.jet.saturation_force_n * math.atanh(min(h / cfg.jet.saturation_m, 0.999))

    def observe(self, p_pa, force_n):
        """(pressures (2,), force) as the sensors read them [Pa abs, N]."""
        p = np.asarray(p_pa, float) + np.array([self.pressure_sensor_offset_a_pa, self.pressure_sensor_offset_b_pa])
        return p, np.asarray(force_n, float) + self.force_sensor_offset_n


def extend(y6, lag_current_a: float | None = None) -> np.ndarray:
    """(7,) extended state from plant.py's (6,) state; the lagged current starts at i."""
    y = np.empty(N_STATE)
    y[:6] = y6
    y[I_LAG] = y6[0] if lag_current_a is None else lag_current_a
    return y


def torque_current(y, fx) -> float:
    """The current that drives the torque motor [A]: the lagged one when valve_lag_s > 0."""
    return float(y[I_LAG] if fx[FX_LAG] > 0.0 else y[0])


# -- numpy reference --------------------------------------------------------------------------
def supply_pressure(y, cfg: JetpipeCfg, fx) -> float:
    """Drooped supply pressure [Pa]: P_s - k_droop (m_s1 + m_s2), flows at the nominal P_s."""
    if fx[FX_DROOP] <= 0.0:
        return cfg.supply.supply_pa
    a_s1, _, a_s2, _ = orifice_areas(y[2] + cfg.jet.offset_m, cfg.ports)
    cd, ps = cfg.ports.discharge_coefficient, cfg.supply.supply_pa
    m = orifice_flow(cd * a_s1, ps, y[4], cfg.gas)[0] + orifice_flow(cd * a_s2, ps, y[5], cfg.gas)[0]
    return float(ps - fx[FX_DROOP] * m)


def rhs(y, current_cmd_a, hysteresis_force_n, piston_m, piston_speed_m_s, cfg: JetpipeCfg, fx) -> np.ndarray:
    """dy/dt (7,): plant.rhs with ``cfg``'s supply already drooped, plus the external and extra
    piston leaks in the pressure rates (eq. 12) and the current lag."""
    dy = np.empty(N_STATE)
    dy[:6] = plant_rhs(y[:6], current_cmd_a, hysteresis_force_n, piston_m, piston_speed_m_s, cfg)
    gas, pr = cfg.gas, cfg.supply.room_pa
    p1, p2 = y[4], y[5]
    m_e1 = orifice_flow(fx[FX_EXT_A], p1, pr, gas)[0]
    m_e2 = orifice_flow(fx[FX_EXT_B], p2, pr, gas)[0]
    m_l = orifice_flow(fx[FX_PISTON], p1, p2, gas)[0]
    c = cfg.cylinder
    v1 = c.dead_volume_1_m3 + c.piston_area_m2 * piston_m
    v2 = c.dead_volume_2_m3 + c.piston_area_m2 * (c.stroke_m - piston_m)
    n, rt = gas.polytropic_exponent, gas.gas_constant_j_per_kg_k * gas.temperature_k
    dy[4] += n / v1 * rt * float(-m_e1 - m_l)
    dy[5] += n / v2 * rt * float(-m_e2 + m_l)
    dy[I_LAG] = (y[0] - y[I_LAG]) / fx[FX_LAG] if fx[FX_LAG] > 0.0 else 0.0
    return dy


def rk4_step(y, h, current_cmd_a, hysteresis_force_n, piston_m, piston_speed_m_s, cfg: JetpipeCfg, fx) -> np.ndarray:
    """One RK4 step of (7,) ``y``; the supply pressure is drooped from the state at the start."""
    cfg_s = cfg.replace("supply", supply_pa=supply_pressure(y, cfg, fx)) if fx[FX_DROOP] > 0.0 else cfg
    args = (current_cmd_a, hysteresis_force_n, piston_m, piston_speed_m_s, cfg_s, fx)
    k1 = rhs(y, *args)
    k2 = rhs(y + 0.5 * h * k1, *args)
    k3 = rhs(y + 0.5 * h * k2, *args)
    k4 = rhs(y + h * k3, *args)
    y_new = y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    if fx[FX_LAG] <= 0.0:
        y_new[I_LAG] = y_new[0]
    return y_new


# -- compiled ---------------------------------------------------------------------------------
@njit(cache=True)
def _supply(y, prm, fx):
    if fx[FX_DROOP] <= 0.0:
        return prm[k.P_S]
    x = y[2] + prm[k.X_OFF]
    r, c, ps = prm[k.R_JET], prm[k.C_PORT], prm[k.P_S]
    cd = prm[k.CD]
    m = k.flow(cd * k.lens(r, r, abs(c - x)), ps, y[4], prm) + k.flow(cd * k.lens(r, r, abs(c + x)), ps, y[5], prm)
    return ps - fx[FX_DROOP] * m


@njit(cache=True)
def _rhs(y, out, i_cmd, f_h, q, qd, prm, fx):
    k.rhs(y, out, i_cmd, f_h, q, qd, prm)
    p1, p2, pr = y[4], y[5], prm[k.P_R]
    m_e1 = k.flow(fx[FX_EXT_A], p1, pr, prm)
    m_e2 = k.flow(fx[FX_EXT_B], p2, pr, prm)
    m_l = k.flow(fx[FX_PISTON], p1, p2, prm)
    ap = prm[k.A_P]
    v1 = prm[k.VD1] + ap * q
    v2 = prm[k.VD2] + ap * (prm[k.STROKE] - q)
    n, rt = prm[k.N_POLY], prm[k.RT]
    out[4] += n / v1 * rt * (-m_e1 - m_l)
    out[5] += n / v2 * rt * (-m_e2 + m_l)
    out[6] = (y[0] - y[6]) / fx[FX_LAG] if fx[FX_LAG] > 0.0 else 0.0


@njit(cache=True)
def step(y, plays, radii, i_cmd, q, qd, h, n_sub, prm, fx):
    """Advance the (7,) state ``y`` and the play outputs in place by ``n_sub`` RK4 substeps of
    ``h`` [s] (kernel.step with the effects ``fx`` = JetpipeEffects.pack())."""
    k1 = np.empty(7)
    k2 = np.empty(7)
    k3 = np.empty(7)
    k4 = np.empty(7)
    tmp = np.empty(7)
    p = prm.copy()
    n = plays.size
    for _ in range(n_sub):
        i_t = y[6] if fx[FX_LAG] > 0.0 else y[0]
        f_tip = prm[k.K_M] * i_t
        total = 0.0
        for j in range(n):
            plays[j] = min(max(plays[j], f_tip - radii[j]), f_tip + radii[j])
            total += plays[j]
        f_h = total / n
        p[k.P_S] = _supply(y, prm, fx)
        _rhs(y, k1, i_cmd, f_h, q, qd, p, fx)
        for j in range(7):
            tmp[j] = y[j] + 0.5 * h * k1[j]
        _rhs(tmp, k2, i_cmd, f_h, q, qd, p, fx)
        for j in range(7):
            tmp[j] = y[j] + 0.5 * h * k2[j]
        _rhs(tmp, k3, i_cmd, f_h, q, qd, p, fx)
        for j in range(7):
            tmp[j] = y[j] + h * k3[j]
        _rhs(tmp, k4, i_cmd, f_h, q, qd, p, fx)
        for j in range(7):
            y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        if fx[FX_LAG] <= 0.0:
            y[6] = y[0]


def reference_step(y, hyst, i_cmd, q, qd, h, n_sub, cfg: JetpipeCfg, fx):
    """The numpy twin of :func:`step` (y (7,) and the PlayHysteresis ``hyst`` advanced in place)."""
    for _ in range(n_sub):
        f_h = hyst(cfg.driver.force_constant_n_per_a * torque_current(y, fx))
        y[:] = rk4_step(y, h, i_cmd, f_h, q, qd, cfg, fx)
