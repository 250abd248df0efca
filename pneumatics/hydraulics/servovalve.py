"""The one-stage suspension (jet-pipe type) servovalve of the SARCOS joint (paper 001 §2.2-2.3).

Chain: current i -> hysteresis -> i_hys (:mod:`.hysteresis`, eqs. 2-3) -> valve tip position
x_v (second-order tip dynamics, eq. 4) -> orifice areas -> flows (square-root law, eq. 5) plus
the two-stage clearance leakage.

Tip dynamics (eq. 4)::

    m_v dv/dt = B i_hys + F_s - b_v v - k_v x_v,   dx_v/dt = v

with the flow force F_s lumped into the gain (the paper does the same for lack of a
characterisation), written with omega_v^2 = k_v/m_v, 2 zeta omega_v = b_v/m_v and the static
gain B/k_v = tip_travel_m / i_sat, so that i_hys = +-i_sat puts the tip at +-tip_travel_m.
Integrated exactly for a held input (zero-order hold, matrix exponential), so any timestep
is stable.

Metering (eq. 5): zero-lapped ports of width ``port_width_m``; x_v > 0 opens supply -> a and
b -> return (chamber a is the one that turns the joint positive)::

    A_sa = A_br = w max(x_v, 0),   A_sb = A_ar = w max(-x_v, 0)

Two-stage leakage (paper §2.3): oil crosses the clearance from the supply to the tip, where
it is at the tip pressure P_vt, and from there (stage 2) leaks to the control port and to the
return.  With linear resistances (as the paper assumes, to solve eqs. 11-12 for P_vt in
closed form) each port j has its own tip node with conductances G_s (supply -> tip),
G_r (tip -> return) and G_p (tip -> port)::

    P_vt,j = (G_s P_s + G_r P_r + G_p P_j) / (G_s + G_r + G_p)

which is the same as three direct conductances per port: supply -> port
g_sp = G_s G_p / G, port -> return g_pr = G_r G_p / G and supply -> return g_sr = G_s G_r / G
(G = G_s + G_r + G_p).  At null the ports then sit at the tip pressure, mid-way between
supply and return for G_s = G_r, and the valve passes its null leakage from supply to return.
The paper's P_vt also depends on x_v and Q (eqs. 11-12, partly illegible); here the clearance
is taken as independent of the tip position.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ..config import spec


@dataclass(frozen=True)
class ServovalveCfg:
    """Valve tip dynamics, port geometry and clearance leakage (paper 001 eqs. 4-5, §2.3)."""

    tip_natural_frequency_hz: float = spec(120.0, "natural frequency of the valve tip, "
                                           "sqrt(k_v/m_v)/(2 pi) (eq. 4)", "Hz", 1.0, 1e4)
    tip_damping_ratio: float = spec(0.7, "damping ratio of the valve tip, b_v/(2 sqrt(k_v m_v))",
                                    "-", 0.01, 5.0)
    tip_travel_m: float = spec(1.0e-4, "tip displacement at i_hys = i_sat (static gain times "
                               "i_sat)", "m", 1e-6, 1e-2)
    port_width_m: float = spec(2.0e-3, "width of each metering port: area = width * |x_v|",
                               "m", 1e-5, 0.1)
    supply_clearance_m3_per_pa_s: float = spec(1.5e-13, "G_s: conductance supply -> tip node "
                                               "(stage 1 clearance)", "m^3/(Pa s)", 0.0, 1e-9)
    return_clearance_m3_per_pa_s: float = spec(1.5e-13, "G_r: conductance tip node -> return",
                                               "m^3/(Pa s)", 0.0, 1e-9)
    port_clearance_m3_per_pa_s: float = spec(1.0e-12, "G_p: conductance tip node -> control "
                                             "port (stage 2 clearance)", "m^3/(Pa s)", 0.0, 1e-9)

    @property
    def full_area_m2(self) -> float:
        """Metering area at full tip travel [m^2]."""
        return self.port_width_m * self.tip_travel_m

    def leak_conductances(self) -> tuple[float, float, float]:
        """(g_sp, g_pr, g_sr) [m^3/(Pa s)]: supply->port, port->return, supply->return, per port."""
        gs, gr, gp = (self.supply_clearance_m3_per_pa_s, self.return_clearance_m3_per_pa_s,
                      self.port_clearance_m3_per_pa_s)
        g = gs + gr + gp
        if g <= 0.0:
            return 0.0, 0.0, 0.0
        return gs * gp / g, gr * gp / g, gs * gr / g

    def null_leakage_m3_s(self, supply_pa: float, return_pa: float) -> float:
        """Supply -> return flow of the whole valve at null with both ports at the tip pressure."""
        gs, gr = self.supply_clearance_m3_per_pa_s, self.return_clearance_m3_per_pa_s
        if gs + gr <= 0.0:
            return 0.0
        return 2.0 * gs * gr / (gs + gr) * (supply_pa - return_pa)


def metering_areas(x_v: float, cfg: ServovalveCfg) -> tuple[float, float, float, float]:
    """(A_sa, A_ar, A_sb, A_br) [m^2] at tip position ``x_v`` [m]; clipped at full travel."""
    x = min(max(x_v, -cfg.tip_travel_m), cfg.tip_travel_m)
    open_pos = cfg.port_width_m * max(x, 0.0)
    open_neg = cfg.port_width_m * max(-x, 0.0)
    return open_pos, open_neg, open_neg, open_pos


class ValveTip:
    """Second-order valve tip (eq. 4), exact zero-order-hold update at a fixed step ``dt``.

    State: position x_v [m] and velocity [m/s]; input i_hys [A].
    """

    def __init__(self, cfg: ServovalveCfg, saturation_current_a: float, dt: float):
        self.cfg, self.dt = cfg, dt
        w = 2.0 * math.pi * cfg.tip_natural_frequency_hz
        z = cfg.tip_damping_ratio
        a = np.array([[0.0, 1.0], [-w * w, -2.0 * z * w]])
        b = np.array([0.0, w * w * cfg.tip_travel_m / saturation_current_a])
        aug = np.zeros((3, 3))
        aug[:2, :2], aug[:2, 2] = a * dt, b * dt
        e = expm(aug)                       # [[Phi, Gamma], [0, 1]]
        self._phi = e[:2, :2].tolist()
        self._gamma = e[:2, 2].tolist()
        self.reset()

    def reset(self, x_v: float = 0.0):
        """Tip at rest at ``x_v`` [m]."""
        self.x, self.v = x_v, 0.0

    def step(self, i_hys: float) -> float:
        """Advance one ``dt`` with the input held; returns the new tip position [m]."""
        (p00, p01), (p10, p11) = self._phi
        g0, g1 = self._gamma
        self.x, self.v = (p00 * self.x + p01 * self.v + g0 * i_hys,
                          p10 * self.x + p11 * self.v + g1 * i_hys)
        return self.x
