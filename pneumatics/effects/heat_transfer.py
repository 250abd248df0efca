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
