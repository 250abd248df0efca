"""pressure_sensor_offset: a pressure transducer that reads the true pressure plus a constant.

    p_measured = p + offset

A zero drift of a strain-gauge transducer (e.g. Doebelin, *Measurement Systems*, 5th ed.,
§3.2 "zero drift").  The simulator adds it to what the sensors report, never to the physics;
the doctor's replays start from the measured pressure minus the offset and report the
replayed pressure plus it; the torque balance sees it as a constant force error (area x offset).
"""
from __future__ import annotations

from dataclasses import dataclass

from .family import Family, param


def reading(true_pa, offset_pa):
    """What the transducer reports [Pa] for a true absolute pressure [Pa]."""
    return true_pa + offset_pa


@dataclass(frozen=True)
class Additive:
    """A constant zero offset."""

    offset_pa: float = param(0.0, "reading minus true pressure", "Pa", -1e6, 1e6)


class PressureSensorOffset(Family):
    name = "pressure_sensor_offset"
    place_kind = "chamber"
    forms = {"additive": Additive}
    physics = "p_measured = p + offset"
    sources = "Doebelin, Measurement Systems §3.2"
    simulator = "added to the observed pressures"
    doctor = "pressure_replay"
    plants = ("valve_arm", "bench_chamber", "jetpipe")

    def effect_set_entry(self, params):
        return {"pressure_offset_pa": params.offset_pa}

    def mods_entry(self, params):
        return {"sensor_offset_pa": params.offset_pa}

    def draw(self, rng):
        return Additive(rng.choice([-1, 1]) * rng.uniform(8e3, 2e4))
