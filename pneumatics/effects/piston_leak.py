"""piston_leak: air passing the piston seal from chamber a to chamber b of one cylinder.

Two forms, the same laws as a leak to the room (:mod:`.external_leak`) between the two chambers:

* ``orifice`` — a short gap: isentropic orifice flow, choked or subsonic (paper 002 eqs. 6-8;
  pneumatics.medium.orifice_flow), effective area A;
* ``laminar`` — a worn seal, a long thin gap: compressible Hagen-Poiseuille,
  m = G (p_a^2 - p_b^2) / (2 p_room) (:func:`.external_leak.laminar_flow`).

The flow leaves a and enters b, so the cylinder's air is conserved.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..medium import orifice_flow
from .external_leak import laminar_flow
from .family import Family, param


def piston_leak_flow(p_a, p_b, area_m2, conductance_kg_s_pa, gas, room_pa: float):
    """(m, dm/dp_a, dm/dp_b): mass flow [kg/s] from a to b through the orifice and laminar
    forms together; arrays broadcast."""
    m, da, db = orifice_flow(area_m2, p_a, p_b, gas)
    ml, dla, dlb = laminar_flow(conductance_kg_s_pa, p_a, p_b, room_pa)
    return m + ml, da + dla, db + dlb


@dataclass(frozen=True)
class OrificeLeak:
    """A short gap past the piston."""

    leak_area_m2: float = param(0.0, "effective area Cd A of the gap", "m^2", 0.0, 1e-5)


@dataclass(frozen=True)
class LaminarLeak:
    """A long thin gap past the piston (worn seal)."""

    conductance_kg_s_pa: float = param(0.0, "conductance G at room pressure", "kg/(s Pa)", 0.0, 1e-6)


class PistonLeak(Family):
    name = "piston_leak"
    place_kind = "actuator"
    forms = {"orifice": OrificeLeak, "laminar": LaminarLeak}
    physics = "flow a -> b past the piston: orifice (choked/subsonic) or laminar G (p_a^2 - p_b^2) / (2 p_room)"
    sources = "paper 002 eqs. 6-8; White, Viscous Fluid Flow §3.3"
    simulator = "leak flows held over each step (chamber.leak_flows, kernel)"
    doctor = "pressure_replay"
    plants = ("valve_arm", "jetpipe")

    def effect_set_entry(self, params):
        if isinstance(params, LaminarLeak):
            return {"piston_leak_laminar_kg_s_pa": params.conductance_kg_s_pa}
        return {"piston_leak_m2": params.leak_area_m2}

    def mods_entry(self, params):
        if isinstance(params, LaminarLeak):
            return {"piston_leak_g": params.conductance_kg_s_pa}
        return {"piston_leak_m2": params.leak_area_m2}

    def draw(self, rng):
        return OrificeLeak(rng.uniform(1e-8, 3e-8))
