"""Supply and return lines: resistance, inertance and capacitance (paper 001 eqs. 6-7, 10).

Each line is a lumped R-I-C element (Merritt, *Hydraulic Control Systems* §4; paper 001
§2.3: "line losses are represented as linear resistances; fluid inertance due to fluid mass
in the lines as well as fluid capacitance due to fluid compressibility are taken into
account")::

    supply:  I_s dQ_s/dt = P_pump - P_s - R_s Q_s        (6)
             C_s dP_s/dt = Q_s - Q_valve,in              (7)
    return:  C_r dP_r/dt = Q_valve,out - Q_r
             I_r dQ_r/dt = P_r - P_tank - R_r Q_r        (10)

P_s and P_r are the pressures at the valve (what the manifold's taps measure).  C_s is the
oil in the supply line plus the accumulator at the joint (paper Table 1: C_p).
"""
from __future__ import annotations

from dataclasses import dataclass

from ..config import spec
from ..oil import OilCfg, line_capacitance, line_inertance, line_resistance


@dataclass(frozen=True)
class LineCfg:
    """A hose between the power unit and the servovalve."""

    length_m: float = spec(3.0, "line length l", "m", 0.01, 100.0)
    diameter_m: float = spec(3.2e-3, "inner diameter d", "m", 1e-4, 0.1)
    accumulator_m3_per_pa: float = spec(0.0, "extra capacitance at the valve end (gas "
                                        "accumulator C_p), added to the line's V/beta",
                                        "m^3/Pa", 0.0, 1e-9)

    def elements(self, oil: OilCfg) -> tuple[float, float, float]:
        """(R [Pa s/m^3], I [Pa s^2/m^3], C [m^3/Pa]) of this line with ``oil``."""
        return (line_resistance(self.length_m, self.diameter_m, oil),
                line_inertance(self.length_m, self.diameter_m, oil),
                line_capacitance(self.length_m, self.diameter_m, oil) + self.accumulator_m3_per_pa)


@dataclass(frozen=True)
class PowerCfg:
    """The hydraulic power unit: pump and tank pressures (absolute)."""

    pump_pa: float = spec(20.8e6, "pump outlet pressure, absolute (paper: 3000 psi = 20.7 MPa "
                          "gauge)", "Pa", 1e6, 1e8)
    tank_pa: float = spec(1.0e5, "tank pressure, absolute (atmospheric)", "Pa", 1e3, 1e7)
    pump_droop_pa_s_per_m3: float = spec(0.0, "fall of the pump's outlet pressure per unit of flow "
                                         "drawn (a pressure-compensated pump's droop; Merritt §8: a "
                                         "source resistance in series with the supply line)",
                                         "Pa s/m^3", 0.0, 1e14)
