"""force_sensor_offset: a load cell that reads the true force plus a constant.

    F_measured = gain F + offset

(:func:`.seal_friction.load_cell_reading`; a zero drift, Doebelin, *Measurement Systems*,
5th ed., §3.2).  A symmetric seal friction plus an offset equals an asymmetric Coulomb
friction, which is why one constant-speed run cannot tell the two apart.  Only the plants with
a load cell have it: the bench cylinder (bench doctor) and the jet-pipe actuator (jet-pipe
doctor), each with its own plant; the valve-driven arms measure no force.
"""
from __future__ import annotations

from dataclasses import dataclass

from .family import Family, param
from .seal_friction import load_cell_reading

__all__ = ["Additive", "ForceSensorOffset", "load_cell_reading"]


@dataclass(frozen=True)
class Additive:
    """A constant zero offset of the load cell."""

    offset_n: float = param(0.0, "reading minus true force", "N", -1e5, 1e5)


class ForceSensorOffset(Family):
    name = "force_sensor_offset"
    place_kind = "actuator"
    forms = {"additive": Additive}
    physics = "F_measured = F + offset"
    sources = "Doebelin, Measurement Systems §3.2"
    plants = ("bench_cylinder", "jetpipe")
    roundtrip_gap = "arm2 has no load cell; the bench-cylinder and jet-pipe doctors test it on their own plants"
