"""Working media and isentropic orifice flow (numpy reference implementation).

Sources
-------
* Orifice mass flow: Todorov et al. (paper 002) eqs. 6-8; Henri et al. (paper 000) eq. 5;
  the textbook form is Beater, *Pneumatic Drives* (2007) §2.4.  For an upstream pressure
  ``p_up``, downstream ``p_down`` and pressure ratio ``r = p_down / p_up``::

      choked    (r <= r_c):   m = A p_up C_choke,     C_choke = sqrt(k/(R T)) (2/(k+1))^((k+1)/(2(k-1)))
      subsonic  (r >  r_c):   m = A p_up C_sub psi(r), C_sub = sqrt(2k/((k-1) R T)),
                                                       psi(r) = sqrt(r^(2/k) - r^((k+1)/k))

  with r_c = (2/(k+1))^(k/(k-1)) = 0.528 for air; both branches meet at r_c.
* Near r = 1 the subsonic law has an infinite slope (d psi/dr -> -inf), which makes the
  pressure ODE needlessly stiff at the zero-flow point.  Above ``laminar_ratio`` (0.995 by
  default, as in ``reference/arm2.md``) the flow is linear in the pressure difference, matched
  in value at ``laminar_ratio`` (a laminar-like branch; the physical flow there is small).
* Flow reverses when the pressures do: the signed flow is from the higher to the lower
  pressure, so a chamber driven above supply pushes air back into the supply line.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GasCfg:
    """An ideal gas at constant temperature; all quantities SI."""

    gas_constant_j_per_kg_k: float = 287.0
    """Specific gas constant R [J/(kg K)] (air: 287)."""
    heat_capacity_ratio: float = 1.4
    """k = c_p / c_v (air: 1.4); sets the orifice flow's critical ratio."""
    temperature_k: float = 293.15
    """Gas temperature T [K], constant (supply and chambers)."""
    polytropic_exponent: float = 1.4
    """n in the chamber pressure ODE, 1 (isothermal) <= n <= k (adiabatic)."""
    laminar_ratio: float = 0.995
    """Pressure ratio above which the orifice flow is linearised (keeps dm/dp finite)."""

    @property
    def critical_ratio(self) -> float:
        """r_c = (2/(k+1))^(k/(k-1)) [-] (0.528 for air)."""
        k = self.heat_capacity_ratio
        return (2.0 / (k + 1.0)) ** (k / (k - 1.0))

    @property
    def c_choke(self) -> float:
        """Choked flow coefficient [s/m]: m = A p_up c_choke."""
        k, rt = self.heat_capacity_ratio, self.gas_constant_j_per_kg_k * self.temperature_k
        return np.sqrt(k / rt) * (2.0 / (k + 1.0)) ** ((k + 1.0) / (2.0 * (k - 1.0)))

    @property
    def c_sub(self) -> float:
        """Subsonic flow coefficient [s/m]: m = A p_up c_sub psi(r)."""
        k, rt = self.heat_capacity_ratio, self.gas_constant_j_per_kg_k * self.temperature_k
        return np.sqrt(2.0 * k / ((k - 1.0) * rt))

    def as_array(self) -> np.ndarray:
        """[R, k, T, n, laminar_ratio, r_c, c_choke, c_sub] for compiled kernels."""
        return np.array([self.gas_constant_j_per_kg_k, self.heat_capacity_ratio,
                         self.temperature_k, self.polytropic_exponent, self.laminar_ratio,
                         self.critical_ratio, self.c_choke, self.c_sub])


def flow_function(r, k):
    """The flow function psi(r) = sqrt(r^(2/k) - r^((k+1)/k)) of the downstream-to-upstream
    pressure ratio r of isentropic orifice flow (paper 002 eqs. 6-8), clipped at 0 for r >= 1."""
    return np.sqrt(np.maximum(r ** (2.0 / k) - r ** ((k + 1.0) / k), 0.0))


def _dpsi_dr(r, k):
    g = r ** (2.0 / k) - r ** ((k + 1.0) / k)
    dg = (2.0 / k) * r ** (2.0 / k - 1.0) - ((k + 1.0) / k) * r ** (1.0 / k)
    return dg / (2.0 * np.sqrt(np.maximum(g, 1e-300)))


def unit_flow(p_up, p_down, gas: GasCfg, derivatives: bool = True):
    """Mass flow per unit effective area [kg/(s m^2)] from ``p_up`` to ``p_down`` >= 0 case.

    Arrays broadcast; requires ``p_up >= p_down > 0`` (use :func:`orifice_flow` for signs).
    Returns ``(flow, d_flow/d_p_up, d_flow/d_p_down)``; the derivatives are None when not
    asked for (``derivatives`` False: a third of the work on large arrays).
    """
    p_up = np.asarray(p_up, float)
    p_down = np.asarray(p_down, float)
    k, rc, rl = gas.heat_capacity_ratio, gas.critical_ratio, gas.laminar_ratio
    with np.errstate(invalid="ignore", divide="ignore"):  # every branch is evaluated; one is kept
        return _unit_flow_branches(p_up, p_down, p_down / p_up, gas, k, rc, rl, derivatives)


def _unit_flow_branches(p_up, p_down, r, gas, k, rc, rl, derivatives=True):
    # choked
    f_ch = gas.c_choke * p_up
    # subsonic
    psi = flow_function(r, k)
    f_sub = gas.c_sub * p_up * psi
    # linear branch, matched at r = laminar_ratio: f = c_sub psi(rl) (p_up - p_down) / (1 - rl)
    slope = gas.c_sub * flow_function(rl, k) / (1.0 - rl)
    f_lin = slope * (p_up - p_down)
    flow = np.where(r <= rc, f_ch, np.where(r <= rl, f_sub, f_lin))
    if not derivatives:
        return flow, None, None
    dpsi = _dpsi_dr(r, k)
    dsub_dup = gas.c_sub * (psi - r * dpsi)
    dsub_ddown = gas.c_sub * dpsi
    d_up = np.where(r <= rc, gas.c_choke, np.where(r <= rl, dsub_dup, slope))
    d_down = np.where(r <= rc, 0.0, np.where(r <= rl, dsub_ddown, -slope))
    return flow, d_up, d_down


def orifice_flow(area_m2, p_from, p_to, gas: GasCfg, derivatives: bool = True):
    """Signed mass flow [kg/s] through an orifice of effective area ``area_m2`` (Cd*A).

    Positive from ``p_from`` to ``p_to``; reverses when ``p_to > p_from``.
    Returns ``(mdot, d mdot / d p_from, d mdot / d p_to)``; arrays broadcast; the derivatives
    are None when ``derivatives`` is False.
    """
    p_from, p_to = np.broadcast_arrays(np.asarray(p_from, float), np.asarray(p_to, float))
    forward = p_from >= p_to
    hi = np.where(forward, p_from, p_to)
    lo = np.where(forward, p_to, p_from)
    f, d_hi, d_lo = unit_flow(hi, lo, gas, derivatives)
    s = np.where(forward, 1.0, -1.0)
    area_m2 = np.asarray(area_m2, float)
    mdot = s * area_m2 * f
    if not derivatives:
        return mdot, None, None
    d_from = area_m2 * np.where(forward, d_hi, -d_lo)
    d_to = area_m2 * np.where(forward, d_lo, -d_hi)
    return mdot, d_from, d_to
