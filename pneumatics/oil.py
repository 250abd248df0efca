"""Hydraulic oil as a working medium: the square-root orifice law and line elements.

The hydraulic counterpart of :mod:`pneumatics.medium` (which holds the gas and its isentropic
orifice flow).  Oil is nearly incompressible: the only compressibility the circuit sees is
the (effective) bulk modulus beta, which turns a volume-flow imbalance into a pressure rate
(paper 001 eqs. 8-9)::

    dp/dt = beta / V * (sum of volume flows in - dV/dt)

Sources
-------
* Orifice flow: paper 001 eq. 5 (turbulent orifice, square-root law)::

      Q = C_d A sqrt(2 |p_from - p_to| / rho) sign(p_from - p_to)

  The law has an infinite slope at zero pressure drop, where a real orifice flow turns
  laminar.  Below about ``laminar_dp_pa`` the flow is made linear in the drop by the smooth
  blend ``Q = C_d A sqrt(2/rho) dp (dp^2 + dp_t^2)^(-1/4)``, which equals the square-root law
  to 1 % for |dp| > 7 dp_t and keeps dQ/dp finite (= C_d A sqrt(2/rho) / sqrt(dp_t) at 0).
  Same role as ``GasCfg.laminar_ratio`` in the gas law; Merritt, *Hydraulic Control Systems*
  (1967) §3.2 for the laminar range of small orifices.
* Lines (paper 001 §2.3, "line losses as linear resistances, inertance and capacitance";
  Merritt §4): Hagen-Poiseuille resistance R = 128 mu l / (pi d^4) [Pa s/m^3], inertance
  I = rho l / A [Pa s^2/m^3], capacitance C = V / beta [m^3/Pa].

All functions broadcast over numpy arrays; flows are volume flows in m^3/s, positive from
``p_from`` to ``p_to``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import spec

CAVITATION_FLOOR_PA = 2.0e3
"""Hydraulic pressures (chambers, and the supply and return lines' ends) are kept above this
[Pa]: the oil releases vapour and dissolved air below it, which the bulk-modulus model does not
describe."""


@dataclass(frozen=True)
class OilCfg:
    """A hydraulic oil at constant temperature; all quantities SI."""

    density_kg_m3: float = spec(860.0, "oil density rho (mineral oil, MIL-H-5606: 850-870)",
                                "kg/m^3", 600.0, 1200.0)
    bulk_modulus_pa: float = spec(1.0e9, "effective bulk modulus beta of oil with its hoses and "
                                  "entrained air (pure oil 1.4-1.8e9)", "Pa", 1e7, 3e9)
    viscosity_pa_s: float = spec(0.02, "dynamic viscosity mu (sets the laminar line resistance)",
                                 "Pa s", 1e-4, 1.0)
    discharge_coefficient: float = spec(0.61, "orifice discharge coefficient C_d (sharp edge: 0.61)",
                                        "-", 0.1, 1.0)
    laminar_dp_pa: float = spec(5.0e4, "pressure drop below which orifice flow turns laminar "
                                "(linear); keeps dQ/dp finite at zero drop", "Pa", 1.0, 1e6)

    @property
    def orifice_coefficient(self) -> float:
        """C_d sqrt(2/rho) [m^1.5/kg^0.5]: Q = coefficient * A * sqrt(dp) on the square-root branch."""
        return self.discharge_coefficient * math.sqrt(2.0 / self.density_kg_m3)

    def chamber_stiffness(self, volume_m3):
        """beta / V [Pa/m^3]: pressure rise per unit volume of oil pushed into a closed volume."""
        return self.bulk_modulus_pa / np.asarray(volume_m3, float)


def orifice_flow(area_m2, p_from, p_to, oil: OilCfg):
    """Signed volume flow [m^3/s] through an orifice of geometric area ``area_m2`` (eq. 5).

    Positive from ``p_from`` to ``p_to``; reverses when ``p_to > p_from``.
    Returns ``(q, dq/dp_from, dq/dp_to)``; arrays broadcast.
    """
    dp = np.asarray(p_from, float) - np.asarray(p_to, float)
    k = oil.orifice_coefficient * np.asarray(area_m2, float)
    s = dp * dp + oil.laminar_dp_pa ** 2
    q = k * dp * s ** -0.25
    dq = k * (0.5 * dp * dp + oil.laminar_dp_pa ** 2) * s ** -1.25
    return q, dq, -dq


def orifice_flow_scalar(k_area: float, dp: float, dp_t2: float) -> tuple[float, float]:
    """Scalar fast path of :func:`orifice_flow` for the simulator's inner loop.

    ``k_area`` = C_d sqrt(2/rho) A, ``dp`` = p_from - p_to, ``dp_t2`` = laminar_dp_pa**2.
    Returns ``(q, dq/d dp)``.
    """
    s = dp * dp + dp_t2
    r = s ** -0.25
    return k_area * dp * r, k_area * (0.5 * dp * dp + dp_t2) * r / s


def line_resistance(length_m: float, diameter_m: float, oil: OilCfg) -> float:
    """Laminar (Hagen-Poiseuille) resistance 128 mu l / (pi d^4) [Pa s/m^3]."""
    return 128.0 * oil.viscosity_pa_s * length_m / (math.pi * diameter_m ** 4)


def line_inertance(length_m: float, diameter_m: float, oil: OilCfg) -> float:
    """Fluid inertance rho l / A [Pa s^2/m^3] (paper 001 eq. 6: A/(rho l) multiplies the drop)."""
    return oil.density_kg_m3 * length_m / (math.pi * diameter_m ** 2 / 4.0)


def line_capacitance(length_m: float, diameter_m: float, oil: OilCfg) -> float:
    """Compressibility of the oil in the line, V / beta [m^3/Pa]."""
    return (math.pi * diameter_m ** 2 / 4.0) * length_m / oil.bulk_modulus_pa
