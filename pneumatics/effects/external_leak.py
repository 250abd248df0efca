"""external_leak: a chamber leaking to the room.

Mass flow out of a chamber at absolute pressure ``p`` [Pa] and gas temperature ``T`` [K] into
the room at ``room_pa``, for three leak paths (all return kg/s, positive out of the chamber,
negative if the room pressure is higher):

* ``"laminar"`` (default) — a porous wall or a long narrow gap: isothermal viscous flow of an
  ideal gas through a capillary, the compressible Hagen-Poiseuille law
  m = pi d^4 / (256 mu L R T) (p^2 - p_room^2) (e.g. White, *Viscous Fluid Flow*, 3rd ed.,
  §3.3 "compressible flow in a tube"; Beater, *Pneumatic Drives*, 2007, §2.4 for laminar
  leakage).  Written with the conductance at room pressure ``conductance_kg_s_pa`` = G so
  that m = G (p^2 - p_room^2) / (2 p_room) = G (p - p_room) (p + p_room) / (2 p_room), which
  equals the linear law for small differences.  The leaks of 3D-printed chambers run through
  the pores between layers — many long, thin channels with a Reynolds number far below 1 —
  so this is the doctor's leak law.  On the two leaky prints of the thesis data the orifice
  law fits worst; laminar beats linear on one, and on the other linear fits the first 70 %
  better while laminar predicts the rest better (numbers in docs/real_bench.md).
* ``"linear"`` — m = G (p - p_room): a linearised conductance (small pressure differences).
* ``"orifice"`` — a short hole: isentropic orifice flow with choked and subsonic branches
  (pneumatics.medium.orifice_flow, papers 002 eqs. 6-8), effective area ``area_m2``, with the
  flow scaled by sqrt(T_gas_cfg / T) for the chamber's actual temperature.

The energy the leaking gas carries away (c_p T per kg) is booked by
:func:`pneumatics.effects.heat_transfer.chamber_rates`, so mass and energy stay balanced.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..medium import GasCfg, orifice_flow
from .family import Family, param

LAWS = ("laminar", "linear", "orifice")


def leak_mass_flow(p, room_pa: float, coefficient, law: str = "laminar", temperature_k=None,
                   gas: GasCfg | None = None):
    """Mass flow [kg/s] out of chambers at ``p`` [Pa] (float or (n,)) into the room.

    ``coefficient`` is the conductance G [kg/(s Pa)] for "laminar"/"linear", the effective
    area Cd*A [m^2] for "orifice".  ``temperature_k`` (gas temperature) only matters for the
    orifice law; the viscous laws are written for gas at room temperature.
    """
    if law == "laminar":
        return coefficient * (p - room_pa) * (p + room_pa) / (2.0 * room_pa)
    if law == "linear":
        return coefficient * (p - room_pa)
    if law == "orifice":
        gas = gas or GasCfg()
        m, _, _ = orifice_flow(coefficient, p, room_pa, gas)
        if temperature_k is not None:
            m = m * np.sqrt(gas.temperature_k / np.asarray(temperature_k, float))
        return m
    raise ValueError(f"unknown leak law {law!r}; valid: {', '.join(LAWS)}")


def laminar_flow(conductance_kg_s_pa, p_from, p_to, room_pa: float):
    """Signed laminar (capillary) mass flow [kg/s] from ``p_from`` to ``p_to`` [Pa] and its
    derivatives (m, dm/dp_from, dm/dp_to): m = G (p_from^2 - p_to^2) / (2 p_room), the
    compressible Hagen-Poiseuille law above written with the conductance G at room pressure.
    The simulator's and the doctor's laminar external and piston leaks (the orifice laws'
    second form; a worn seal or a porous wall is a long thin gap, not a hole)."""
    g = np.asarray(conductance_kg_s_pa, float)
    return (g * (p_from - p_to) * (p_from + p_to) / (2.0 * room_pa), g * p_from / room_pa, -g * p_to / room_pa)


def isothermal_time_constant_s(volume_m3: float, conductance_kg_s_pa: float, temperature_k: float,
                               gas_constant: float = 287.0) -> float:
    """tau [s] of the gauge-pressure decay of an isothermal chamber with a linear leak:
    V/(R T) dp/dt = -G (p - p_room)  =>  tau = V / (R T G)."""
    return volume_m3 / (gas_constant * temperature_k * conductance_kg_s_pa)


def conductance_from_time_constant(volume_m3: float, tau_s: float, temperature_k: float,
                                   gas_constant: float = 287.0) -> float:
    """G [kg/(s Pa)] of a leak whose isothermal decay time constant is tau_s (inverse of the above)."""
    return volume_m3 / (gas_constant * temperature_k * tau_s)


# -- the family ------------------------------------------------------------------------------

@dataclass(frozen=True)
class OrificeLeak:
    """A short hole from the chamber to the room."""

    leak_area_m2: float = param(0.0, "effective area Cd A of the hole", "m^2", 0.0, 1e-5)


@dataclass(frozen=True)
class LaminarLeak:
    """A capillary or porous path from the chamber to the room."""

    conductance_kg_s_pa: float = param(0.0, "conductance G at room pressure", "kg/(s Pa)", 0.0, 1e-6)


class ExternalLeak(Family):
    name = "external_leak"
    place_kind = "chamber"
    forms = {"orifice": OrificeLeak, "laminar": LaminarLeak}
    physics = "flow to the room: orifice (choked/subsonic) or laminar G (p^2 - p_room^2) / (2 p_room)"
    sources = "paper 002 eqs. 6-8; White, Viscous Fluid Flow §3.3; Beater 2007 §2.4"
    simulator = "leak flows held over each step (chamber.leak_flows, kernel)"
    doctor = "pressure_replay"
    plants = ("valve_arm", "bench_chamber", "jetpipe")

    def effect_set_entry(self, params):
        if isinstance(params, LaminarLeak):
            return {"external_leak_laminar_kg_s_pa": params.conductance_kg_s_pa}
        return {"external_leak_m2": params.leak_area_m2}

    def mods_entry(self, params):
        if isinstance(params, LaminarLeak):
            return {"external_leak_g": params.conductance_kg_s_pa}
        return {"external_leak_m2": params.leak_area_m2}

    def draw(self, rng):
        return OrificeLeak(rng.uniform(1e-8, 3e-8))
