"""heat_transfer: finite heat exchange between the gas in a chamber and its wall.

Chamber gas state: pressure p [Pa abs] and temperature T [K] (volume V [m^3], mass
m = p V / (R T)).  Energy balance of the gas as an open control volume (first law, ideal gas,
constant c_v; Richer & Hurmuzlu, "A high performance pneumatic force actuator system",
ASME J. Dyn. Sys. Meas. Control 122, 2000, eqs. 7-11; Carneiro & de Almeida, Proc. IMechE I
220, 2006, "Heat transfer evaluation of industrial pneumatic cylinders")::

    d(m c_v T)/dt = c_p T_in m_in - c_p T m_out - p dV/dt + Q,      Q = h A_w (T_w - T)
    dm/dt        = m_in - m_out

which with p V = m R T and c_p - c_v = R, k = c_p / c_v gives

    dp/dt = (k R / V) (T_in m_in - T m_out) - k p (dV/dt) / V + (k - 1) Q / V     (R&H eq. 11)
    dT/dt = T ( dp/dt / p + (dV/dt) / V - (dm/dt) / m )

With Q = 0 this is the adiabatic chamber (polytropic exponent k) and with h A -> infinity the
isothermal one: the constant polytropic exponent of pneumatics.chamber sits between the two.
In a closed rigid chamber (no flow, dV = 0) the gas temperature relaxes exponentially to the
wall, T - T_w = (T0 - T_w) exp(-t / tau), tau = m c_v / (h A_w), and the pressure follows
p = m R T / V: the pressure sag after charging a chamber that :func:`closed_chamber` gives in
closed form.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import spec
from .family import Family, param


@dataclass(frozen=True)
class HeatTransferCfg:
    """Gas-wall heat exchange of one chamber."""

    coefficient_w_m2k: float = spec(10.0, "convective heat-transfer coefficient h (natural convection "
                                    "in a closed vessel: 5-30 W/(m^2 K), Carneiro & de Almeida 2006)",
                                    "W/(m^2 K)", 0.0, 1e4)
    wall_area_m2: float = spec(0.01, "wetted wall area A_w", "m^2", 0.0, 10.0)
    wall_temperature_k: float = spec(293.15, "wall (room) temperature T_w, constant", "K", 200.0, 400.0)

    @property
    def conductance_w_k(self) -> float:
        """h A_w [W/K]."""
        return self.coefficient_w_m2k * self.wall_area_m2


def chamber_rates(p, T, volume_m3, heat_w_k, wall_k, *, dvolume_m3_s=0.0, mdot_in=0.0, t_in_k=None,
                  mdot_out=0.0, gas_constant: float = 287.0, k: float = 1.4):
    """(dp/dt [Pa/s], dT/dt [K/s]) of chambers (floats or arrays broadcasting together).

    ``heat_w_k`` = h A_w [W/K] (0 = adiabatic), ``wall_k`` = T_w [K]; ``mdot_in`` enters at
    ``t_in_k`` (default: the supply at wall temperature), ``mdot_out`` [kg/s] leaves at the gas
    temperature T (a leak or an exhaust).  Richer & Hurmuzlu (2000) eq. 11 and the ideal-gas law.
    """
    t_in = wall_k if t_in_k is None else t_in_k
    q = heat_w_k * (wall_k - T)
    R = gas_constant
    dp = (k * R / volume_m3) * (t_in * mdot_in - T * mdot_out) - k * p * dvolume_m3_s / volume_m3 \
        + (k - 1.0) * q / volume_m3
    m = p * volume_m3 / (R * T)
    dT = T * (dp / p + dvolume_m3_s / volume_m3 - (mdot_in - mdot_out) / m)
    return dp, dT


def thermal_time_constant_s(p, T, volume_m3, heat_w_k, gas_constant: float = 287.0, k: float = 1.4):
    """tau = m c_v / (h A_w) [s] of a closed chamber at (p, T): c_v = R / (k - 1)."""
    m = p * volume_m3 / (gas_constant * T)
    return m * gas_constant / (k - 1.0) / heat_w_k


def closed_chamber(t, p0, T0, wall_k, tau_s):
    """Closed rigid chamber relaxing to the wall: (p(t), T(t)) for t >= 0 [s], arrays like t.

    m and V constant, so p / T = p0 / T0 throughout (ideal gas)."""
    t = np.asarray(t, float)
    T = wall_k + (T0 - wall_k) * np.exp(-t / tau_s)
    return p0 * T / T0, T


def integrate(t, p0, T0, rates, substeps: int = 1):
    """Classical RK4 of (p, T) on the sample times ``t`` (N,): ``rates(p, T) -> (dp, dT)``.

    Floats in, two (N,) arrays out.  ``substeps`` RK4 steps per sample interval."""
    t = np.asarray(t, float)
    P = np.empty(t.size)
    Ts = np.empty(t.size)
    p, T = float(p0), float(T0)
    P[0], Ts[0] = p, T
    for i in range(t.size - 1):
        h = (t[i + 1] - t[i]) / substeps
        for _ in range(substeps):
            a1, b1 = rates(p, T)
            a2, b2 = rates(p + 0.5 * h * a1, T + 0.5 * h * b1)
            a3, b3 = rates(p + 0.5 * h * a2, T + 0.5 * h * b2)
            a4, b4 = rates(p + h * a3, T + h * b3)
            p += h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
            T += h / 6.0 * (b1 + 2 * b2 + 2 * b3 + b4)
            if not (math.isfinite(p) and math.isfinite(T)) or T <= 0 or p <= 0:
                P[i + 1:], Ts[i + 1:] = np.nan, np.nan
                return P, Ts
        P[i + 1], Ts[i + 1] = p, T
    return P, Ts


# -- the robots' chambers: the energy equation with valve flows --------------------------------
#
# A robot chamber with heat_transfer on carries its gas temperature T [K] as a state and obeys
# Richer & Hurmuzlu (2000) eq. 11 instead of paper 002 eq. 9.  Eq. 9 is what this equation
# gives if T stayed at the supply temperature in every flow term (adiabatic compression, but air
# leaving at the temperature it came in with); with T a state the exhaust carries the gas's own
# enthalpy, an orifice passes less mass of hotter gas (mass flow ~ p_up / sqrt(T_up), ISO 6358),
# and the wall exchange h A (T_w - T) relaxes T with tau = m c_v / (h A).


def chamber_flows(p, T, a_supply, a_exhaust, gas, supply_pa, room_pa, t_ref_k, extra_flow=0.0):
    """Flows into chambers at (p, T): (mdot [kg/s], sum of T_j mdot_j [K kg/s], its d/dp).

    Arrays broadcast.  Air entering (from the supply or the room, or a leak inflow) comes at the
    reference temperature ``t_ref_k``; air leaving is the chamber's, at T, its mass flow scaled
    by sqrt(t_ref / T) (the orifice law's 1/sqrt(T_up)).  ``extra_flow`` [kg/s] (leaks, signed
    into the chamber) is held over the step."""
    from ..medium import orifice_flow
    m_s, _, dms = orifice_flow(a_supply, supply_pa, p, gas)      # supply -> chamber
    m_e, dme, _ = orifice_flow(a_exhaust, p, room_pa, gas)       # chamber -> room
    scale = np.sqrt(t_ref_k / T)
    flows = [(m_s, dms), (-m_e, -dme), (extra_flow, 0.0)]
    mdot = 0.0
    enthalpy = 0.0
    d_enthalpy = 0.0
    for m, dm in flows:
        out = m < 0
        m_eff = np.where(out, m * scale, m)
        dm_eff = np.where(out, dm * scale, dm)
        t_j = np.where(out, T, t_ref_k)
        mdot = mdot + m_eff
        enthalpy = enthalpy + t_j * m_eff
        d_enthalpy = d_enthalpy + t_j * dm_eff
    return mdot, enthalpy, d_enthalpy


def thermal_step(p, T, volume, volume_rate, a_supply, a_exhaust, gas, supply_pa, room_pa, conductance_w_k,
                 wall_k, dt, extra_flow=0.0):
    """Advance chambers with a gas temperature over one step ``dt`` [s]: arrays broadcasting
    together ((n,) or (W, C)); returns (p [Pa abs], T [K]) at t + dt.

    ``volume`` is the mid-step volume [m^3] and ``volume_rate`` [m^3/s] is held over the step,
    as in :func:`pneumatics.chamber.chamber_geometry`.  The pressure follows R&H eq. 11 by ROS2
    (pneumatics.chamber's scheme: exact scalar Jacobian in p, T held over the step); the
    temperature then follows from the mass balance, T = p V / (R m) with
    m+ = m + dt mdot(p at mid-step), so the air in a closed chamber is conserved exactly.
    The heat term is explicit in T: keep tau = m c_v / (h A) well above dt (>= 20 dt)."""
    from ..chamber import GAMMA
    k, R = gas.heat_capacity_ratio, gas.gas_constant_j_per_kg_k
    t_ref = gas.temperature_k
    heat = (k - 1.0) * conductance_w_k * (wall_k - T)

    def rhs(q):
        _, h_in, dh = chamber_flows(q, T, a_supply, a_exhaust, gas, supply_pa, room_pa, t_ref, extra_flow)
        return (k * R * h_in - k * q * volume_rate + heat) / volume, (k * R * dh - k * volume_rate) / volume

    f0, jac = rhs(p)
    denom = 1.0 - GAMMA * dt * jac
    k1 = f0 / denom
    f1, _ = rhs(p + dt * k1)
    k2 = (f1 - 2.0 * k1) / denom
    p_new = p + 1.5 * dt * k1 + 0.5 * dt * k2
    mdot, _, _ = chamber_flows(0.5 * (p + p_new), T, a_supply, a_exhaust, gas, supply_pa, room_pa, t_ref, extra_flow)
    v0 = volume - 0.5 * dt * volume_rate
    v1 = volume + 0.5 * dt * volume_rate
    m0 = p * v0 / (R * T)
    m1 = np.maximum(m0 + dt * mdot, 1e-3 * m0)
    return p_new, p_new * v1 / (R * m1)


# -- the family ------------------------------------------------------------------------------

@dataclass(frozen=True)
class NewtonCooling:
    """Gas-wall exchange Q = h A_w (T_w - T) of one chamber, the wall at the gas table's temperature."""

    conductance_w_k: float = param(0.0, "h A_w between gas and wall", "W/K", 0.0, 1e3)


class HeatTransfer(Family):
    name = "heat_transfer"
    place_kind = "chamber"
    forms = {"newton": NewtonCooling}
    physics = "gas temperature as a state; energy equation with Q = h A (T_wall - T)"
    sources = "Richer & Hurmuzlu 2000 eq. 11; Carneiro & de Almeida 2006"
    simulator = "per chamber, stepped in Python (thermal_step)"
    doctor = "pressure_replay"
    plants = ("valve_arm", "bench_chamber")
    mods_off_value = float("nan")  # PneumaticMods.heat_w_k: NaN = paper 002 eq. 9 (no gas temperature)

    def effect_set_entry(self, params):
        return {"heat_transfer": {"conductance_w_k": params.conductance_w_k}}

    def mods_entry(self, params):
        return {"heat_w_k": params.conductance_w_k}

    def draw(self, rng):
        # h A = 0.05-0.3 W/K (walls of 20-50 cm^2, h = 20-100 W/(m^2 K) with the flow's forced
        # convection; Carneiro & de Almeida 2006), a thermal time constant of 0.1-1 s
        return NewtonCooling(rng.uniform(0.05, 0.3))
