"""supply_droop: the supply pressure falls with the flow the valves draw.

A supply line and regulator of finite capacity: its pressure at the valves falls about
linearly with the total mass flow (the regulator's flow characteristic, ISO 6953-2; the
line's resistance, Beater, *Pneumatic Drives*, 2007, §4.2)::

    p_supply = p_supply,nominal - k sum_i max(m_supply,i, 0)

evaluated with the flows of the previous step (the simulator's and the doctor's step alike).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .family import Family, param


def supply_pressure(nominal_pa: float, droop_pa_per_kg_s: float, supply_flows_kg_s) -> float:
    """Supply pressure [Pa] in effect when the valves draw ``supply_flows_kg_s`` [kg/s] (n,)."""
    return nominal_pa - droop_pa_per_kg_s * float(np.maximum(supply_flows_kg_s, 0.0).sum())


@dataclass(frozen=True)
class Linear:
    """A linear droop of the supply pressure with the total supply flow."""

    droop_pa_per_kg_s: float = param(0.0, "pressure drop per kg/s of total supply flow", "Pa/(kg/s)", 0.0, 1e10)


class SupplyDroop(Family):
    name = "supply_droop"
    place_kind = "supply"
    forms = {"linear": Linear}
    physics = "p_supply = nominal - k x total supply mass flow"
    sources = "ISO 6953-2 (regulator flow characteristic); Beater 2007 §4.2"
    simulator = "supply pressure per step from the last step's flows (kernel)"
    doctor = "pressure_replay"
    plants = ("valve_arm", "jetpipe")

    def effect_set_entry(self, params):
        return {"supply_droop_pa_per_kg_s": params.droop_pa_per_kg_s}

    def mods_entry(self, params):
        return {"supply_droop_pa_per_kg_s": params.droop_pa_per_kg_s}

    def draw(self, rng):
        return Linear(rng.uniform(4e7, 1e8))
