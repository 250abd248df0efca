"""Orifice areas of the jet-pipe receiver from the geometric overlap of circles (paper 000 Sec. II-C, Fig. 4).

Geometry (all circles in the receiver plane; x = jet-tip position toward port 1, eq. 4)::

    jet bore      radius r = D/2,      centre x
    flange        radius R_f = 1.5 D,  centre x      (solid ring around the bore)
    port 1        radius r,            centre +c     (c = D: ports one diameter apart)
    port 2        radius r,            centre -c

    supply area of port i  = overlap(bore, port i)                 (jet blows into the port)
    vent area of port i    = pi r^2 - overlap(flange disc, port i) (uncovered part is open to the room)

With c = D and R_f = 1.5 D the valve is critically lapped: centred, the bore just touches both
ports and the flange just covers them (all four areas 0).  Deflected toward port 1, port 1 is
charged and port 2 vents, while the flange keeps the vent of port 1 and the supply of port 2
shut, as the paper states.  At x = D port 1 sees the whole bore and port 2 is fully uncovered.

The circle-circle intersection ("lens") area is the closed form of e.g. Weisstein,
*Circle-Circle Intersection*, MathWorld::

    A = r^2 acos((d^2 + r^2 - R^2) / (2 d r)) + R^2 acos((d^2 + R^2 - r^2) / (2 d R))
        - 0.5 sqrt((-d + r + R)(d + r - R)(d - r + R)(d + r + R))
"""
from __future__ import annotations

import numpy as np

from .params import PortsCfg


def circle_overlap(r1, r2, d):
    """Area [m^2] common to two circles of radii ``r1``, ``r2`` [m] whose centres are ``d`` [m] apart.

    Arrays broadcast.  0 when apart (d >= r1 + r2); the smaller circle's area when one lies
    inside the other (d <= |r1 - r2|).
    """
    r1, r2, d = np.broadcast_arrays(np.asarray(r1, float), np.asarray(r2, float), np.abs(np.asarray(d, float)))
    small, big = np.minimum(r1, r2), np.maximum(r1, r2)
    out = np.zeros(d.shape)
    inside = d <= big - small
    out[inside] = np.pi * small[inside] ** 2
    part = ~inside & (d < r1 + r2)
    if np.any(part):
        a, b, dd = small[part], big[part], d[part]
        ca = np.clip((dd * dd + a * a - b * b) / (2 * dd * a), -1.0, 1.0)
        cb = np.clip((dd * dd + b * b - a * a) / (2 * dd * b), -1.0, 1.0)
        k = (-dd + a + b) * (dd + a - b) * (dd - a + b) * (dd + a + b)
        out[part] = a * a * np.arccos(ca) + b * b * np.arccos(cb) - 0.5 * np.sqrt(np.maximum(k, 0.0))
    return out


def port_area_m2(cfg: PortsCfg) -> float:
    """Geometric area of one receiver port [m^2]."""
    return np.pi * cfg.jet_diameter_m ** 2 / 4.0


def orifice_areas(x_abs_m, cfg: PortsCfg):
    """Geometric orifice areas [m^2] at jet-tip positions ``x_abs_m`` (N,) [m] (eq. 4's x_jp,abs).

    Returns ``(a_supply_1, a_vent_1, a_supply_2, a_vent_2)``, each (N,), without the discharge
    coefficient.
    """
    x = np.asarray(x_abs_m, float)
    r, rf, c = cfg.jet_diameter_m / 2.0, cfg.flange_diameter_m / 2.0, cfg.port_centre_m
    port = np.pi * r * r
    d1, d2 = np.abs(c - x), np.abs(c + x)
    # vents clipped at 0: at the lap point the lens formula leaves a rounding residue (~1e-14 m^2)
    return (circle_overlap(r, r, d1), np.maximum(port - circle_overlap(rf, r, d1), 0.0),
            circle_overlap(r, r, d2), np.maximum(port - circle_overlap(rf, r, d2), 0.0))
