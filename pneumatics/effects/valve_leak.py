"""valve_leak: a proportional valve that does not shut near its null.

A spool with underlap (or worn lands) leaves both the supply and the exhaust path of a chamber
slightly open around the null command.  The extra effective areas [m^2] are a Gaussian of the
spool's distance from the null (the underlap closing as the spool opens one land fully; the
measured leakage flow of an underlapped spool valve peaks at null and falls within a small
fraction of the stroke: Merritt, *Hydraulic Control Systems*, 1967, §3.6 "underlapped valves";
Sorli, Gastaldi, Codina & Heras, "Dynamic analysis of pneumatic actuators", Simul. Pract.
Theory 7, 1999, for the pneumatic spool's leakage near null)::

    A_s,leak = a_s exp(-((u - u_null) / w)^2),   A_e,leak = a_e exp(-((u - u_null) / w)^2)

Two forms: ``symmetric`` (both lands alike, a_s = a_e) and ``asymmetric`` (two areas: the lands
underlapped unequally, which moves the pressure a chamber at null settles at).

A third, ``underlap``, is the underlapped spool of Merritt (1967, §3.6, the orifice areas of
an underlapped four-way valve, w (U + x) and w (U - x)): each land is open by the underlap at
null; the land the spool moves away from closes over the underlap width, the one it opens stays
open by the underlap on top of the valve's own opening (the area curve shifted, not a bump)::

    A_s,leak = a clip(1 + (u - u_null) / w_u, 0, 1),   A_e,leak = a clip(1 - (u - u_null) / w_u, 0, 1)

with a the area at null and w_u the underlap in command volts.

A fourth, ``clearance``, is an overlapped spool whose lands seal by a radial clearance
(Merritt 1967, ch. 5, the laminar clearance flow of a spool in its bore, pi d c^3 / (12 mu L)
per unit pressure difference for a liquid; isothermal for a gas, as
effects.external_leak.laminar_flow): both lands pass a laminar flow, each inversely as the
length its land still covers, which the spool shortens on one land as it lengthens the other::

    m_s = G / max(c_min, 1 - x) (p_s^2 - p^2) / (2 p_room),
    m_e = G / max(c_min, 1 + x) (p^2 - p_room^2) / (2 p_room),     x = (u - u_null) / w_o

with G the conductance of each land at null, w_o the overlap in command volts and c_min the
least share of the overlap left covering a land (nearer to opening, the land's own orifice
carries the flow).  Unlike the other forms it is a laminar flow, not an area: it grows with
the square of the pressures and persists away from null on the land that stays shut.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UnknownNameError
from .external_leak import laminar_flow
from .family import Family, param, place_names

WIDTH_V = 0.6
"""w [V]: the command distance from null over which the leak closes (simulator and doctor alike)"""


def leak_areas(u, null_v, supply_m2, exhaust_m2, width_v: float = WIDTH_V):
    """(supply, exhaust) extra areas [m^2] at commands ``u`` [V] of valves whose null is
    ``null_v`` [V]; arrays broadcast."""
    g = np.exp(-((np.asarray(u, float) - null_v) / width_v) ** 2)
    return supply_m2 * g, exhaust_m2 * g


UNDERLAP_WIDTH_V = 0.6
"""w_u [V]: the underlap width the doctor assumes (it fits the area; 0.6 V, the Gaussian's width)"""


def underlap_areas(u, null_v, area_m2, width_v):
    """(supply, exhaust) extra areas [m^2] of an underlapped spool (the ``underlap`` form) at
    commands ``u`` [V] of valves whose null is ``null_v`` [V]; arrays broadcast."""
    x = (np.asarray(u, float) - null_v) / width_v
    return area_m2 * np.clip(1.0 + x, 0.0, 1.0), area_m2 * np.clip(1.0 - x, 0.0, 1.0)


CLEARANCE_WIDTH_V = 0.6
"""w_o [V]: the overlap the doctor assumes for the clearance form (it fits the conductance)"""
COVER_MIN = 0.1
"""c_min: the least share of a land's overlap left covering it in the clearance form"""


def clearance_conductances(u, null_v, conductance_kg_s_pa, width_v):
    """(supply, exhaust) conductances [kg/(s Pa)] of an overlapped spool's two lands (the
    ``clearance`` form) at commands ``u`` [V] of valves whose null is ``null_v`` [V]: the
    conductance at null over each land's covered share of the overlap; arrays broadcast."""
    x = (np.asarray(u, float) - null_v) / width_v
    g = np.asarray(conductance_kg_s_pa, float)
    return g / np.maximum(COVER_MIN, 1.0 - x), g / np.maximum(COVER_MIN, 1.0 + x)


def clearance_flows(g_supply, g_exhaust, p, supply_pa, room_pa: float):
    """(m, dm/dp) [kg/s, kg/(s Pa)] into chambers at pressures ``p`` through their valves'
    clearances of land conductances ``g_supply``, ``g_exhaust`` (clearance_conductances):
    in from the supply at ``supply_pa``, out to the room (laminar_flow's isothermal law)."""
    m_s, _, dms = laminar_flow(g_supply, supply_pa, p, room_pa)
    m_e, dme, _ = laminar_flow(g_exhaust, p, room_pa, room_pa)
    return m_s - m_e, dms - dme


@dataclass(frozen=True)
class SymmetricLeak:
    """Both lands of the spool leak alike."""

    leak_area_m2: float = param(0.0, "extra effective area at null, supply and exhaust alike", "m^2", 0.0, 1e-5)


@dataclass(frozen=True)
class AsymmetricLeak:
    """The two lands leak differently."""

    supply_leak_area_m2: float = param(0.0, "extra supply-side area at null", "m^2", 0.0, 1e-5)
    exhaust_leak_area_m2: float = param(0.0, "extra exhaust-side area at null", "m^2", 0.0, 1e-5)


@dataclass(frozen=True)
class UnderlapLeak:
    """An underlapped spool: both lands open at null, the opening one stays open by the underlap."""

    underlap_area_m2: float = param(0.0, "area each land is open at null (the underlap's)", "m^2", 0.0, 1e-5)
    underlap_width_v: float = param(UNDERLAP_WIDTH_V, "the underlap in command volts: a land closes over it",
                                    "V", 0.05, 5.0, magnitude=False)


@dataclass(frozen=True)
class ClearanceLeak:
    """An overlapped spool's lands seal by a radial clearance: a laminar flow through each."""

    clearance_conductance_kg_s_pa: float = param(0.0, "laminar conductance of each land at null", "kg/(s Pa)",
                                                 0.0, 1e-8)
    overlap_width_v: float = param(CLEARANCE_WIDTH_V, "the overlap in command volts: a land's covered length "
                                   "falls to nothing over it", "V", 0.05, 5.0, magnitude=False)


def _with_chamber_pair(mods, c: int, n: int, attrs: tuple, values: tuple, default_width_v: float):
    """``mods`` with chamber c's (magnitude, width) set in its per-chamber arrays ``attrs`` (the
    underlap and clearance forms'), the other chambers keeping theirs (0 and default_width_v
    where none was set)."""
    mag, width = (getattr(mods, a) for a in attrs)
    mag = np.zeros(n) if mag is None else mag.copy()
    width = np.full(n, default_width_v) if width is None else width.copy()
    mag[c], width[c] = values
    return mods.copy(**dict(zip(attrs, (mag, width))))


class ValveLeak(Family):
    name = "valve_leak"
    place_kind = "chamber"
    forms = {"symmetric": SymmetricLeak, "asymmetric": AsymmetricLeak, "underlap": UnderlapLeak,
             "clearance": ClearanceLeak}
    physics = ("extra supply and exhaust areas, a Gaussian of width 0.6 V around the valve's null; or an "
               "underlapped spool's area curve, shifted by the underlap; or an overlapped spool's laminar "
               "clearance flow through each land, inversely as its covered length")
    sources = "Merritt 1967 §3.6 (underlapped spools) and ch. 5 (clearance flow); Sorli et al. 1999"
    simulator = ("valve areas at each spool position (valve_bank.ValveBank.update_areas); the clearance form's land "
                 "conductances there too, its flows with the leaks (chamber.leak_flows, kernel)")
    doctor = "pressure_replay"

    def _areas(self, params) -> tuple[float, float]:
        if isinstance(params, AsymmetricLeak):
            return params.supply_leak_area_m2, params.exhaust_leak_area_m2
        return params.leak_area_m2, params.leak_area_m2

    def effect_set_entry(self, params):
        if isinstance(params, ClearanceLeak):
            return {"valve_clearance": {"conductance_kg_s_pa": params.clearance_conductance_kg_s_pa,
                                        "width_v": params.overlap_width_v}}
        if isinstance(params, UnderlapLeak):
            return {"valve_underlap": {"area_m2": params.underlap_area_m2, "width_v": params.underlap_width_v}}
        if isinstance(params, AsymmetricLeak):
            return {"valve_leak_m2": params.supply_leak_area_m2, "valve_leak_exhaust_m2": params.exhaust_leak_area_m2}
        return {"valve_leak_m2": params.leak_area_m2}

    def apply_to_mods(self, mods, robot, place, params):
        """PneumaticMods.valve_leak_m2 at the chamber; its exhaust side where it differs (the other
        chambers' leaks keep their own, symmetric unless set); the underlap and clearance forms'
        own arrays."""
        names = place_names(robot, "chamber")
        if place not in names:
            raise UnknownNameError("chamber", place, names)
        c = names.index(place)
        if isinstance(params, ClearanceLeak):
            return _with_chamber_pair(mods, c, len(names), ("valve_clearance_g", "valve_clearance_width_v"),
                                      (params.clearance_conductance_kg_s_pa, params.overlap_width_v), CLEARANCE_WIDTH_V)
        if isinstance(params, UnderlapLeak):
            return _with_chamber_pair(mods, c, len(names), ("valve_underlap_m2", "valve_underlap_width_v"),
                                      (params.underlap_area_m2, params.underlap_width_v), UNDERLAP_WIDTH_V)
        supply, exhaust = self._areas(params)
        sup = np.zeros(len(names)) if mods.valve_leak_m2 is None else mods.valve_leak_m2.copy()
        exh = None if mods.valve_leak_exhaust_m2 is None else mods.valve_leak_exhaust_m2.copy()
        sup[c] = supply
        if isinstance(params, AsymmetricLeak) and exh is None:
            exh = sup.copy()
        if exh is not None:
            exh[c] = exhaust
        return mods.copy(valve_leak_m2=sup, valve_leak_exhaust_m2=exh)

    def draw(self, rng):
        return SymmetricLeak(rng.uniform(2e-8, 5e-8))
