"""Rotary vane actuator: chamber volumes, torque and cross-chamber leakage (paper 001 §2.3-2.4).

Chamber a turns the vane positive (DESIGN.md: chamber a extends / positive joint direction)::

    V_a = V_line + V_dead + D_v (theta_half + theta)      V_b = V_line + V_dead + D_v (theta_half - theta)
    (plus ``extra_line_volume_a_m3`` / ``_b_m3``: a passage of one chamber longer than the other's)
    torque on the vane   tau = D_v (P_a - P_b)                      (eqs. 13, 19)
    load flow            Q_L = D_v omega                            (eq. 19)
    cross-chamber leak   Q_leak = R_l (P_a - P_b), from a to b      (eqs. 8-9)

Coulomb and viscous friction of the vane are MuJoCo's ``frictionloss`` and ``damping`` of the
vane joint (eq. 13), so MuJoCo's constraint solver handles sticking; see sarcos_elbow.xml.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..config import spec


@dataclass(frozen=True)
class VaneCfg:
    """Geometry and leakage of the rotary vane actuator."""

    displacement_m3_per_rad: float = spec(4.72e-6, "volumetric displacement D_v (paper 001 "
                                          "§3.2.3: 0.288 in^3/rad)", "m^3/rad", 1e-8, 1e-3)
    half_stroke_rad: float = spec(1.7, "vane travel from mid-stroke to either end", "rad", 0.1, 3.2)
    dead_volume_m3: float = spec(0.5e-6, "chamber volume left at the end of the stroke",
                                 "m^3", 1e-9, 1e-3)
    line_volume_m3: float = spec(2.0e-6, "volume of the passage from the valve port to each "
                                 "chamber (Table 1: V_l1, V_l2)", "m^3", 0.0, 1e-3)
    extra_line_volume_a_m3: float = spec(0.0, "line volume added to chamber a's passage alone (a longer "
                                         "or softer hose to that port; paper 001 Table 1: V_l1)", "m^3", 0.0, 1e-3)
    extra_line_volume_b_m3: float = spec(0.0, "line volume added to chamber b's passage alone (V_l2)",
                                         "m^3", 0.0, 1e-3)
    leak_coefficient_m3_per_pa_s: float = spec(1.96e-13, "cross-chamber leakage coefficient R_l "
                                               "(paper 001 §3.2.3: 1.96e-7 m^3/(MPa s))",
                                               "m^3/(Pa s)", 0.0, 1e-9)

    def volumes(self, theta: float) -> tuple[float, float]:
        """(V_a, V_b) [m^3] at vane angle ``theta`` [rad] (0 = mid-stroke)."""
        base = self.line_volume_m3 + self.dead_volume_m3
        d = self.displacement_m3_per_rad
        return (base + self.extra_line_volume_a_m3 + d * (self.half_stroke_rad + theta),
                base + self.extra_line_volume_b_m3 + d * (self.half_stroke_rad - theta))

    def torque(self, p_a: float, p_b: float) -> float:
        """Hydraulic torque on the vane [N m], positive turning the joint positive."""
        return self.displacement_m3_per_rad * (p_a - p_b)
