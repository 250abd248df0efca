"""The one registry of effect families: the simulator, the doctor, the benchmarks' case makers
and the docs (docs/effects.md) read the families from here.

Adding a family is one new module (a :class:`~.family.Family` subclass with its law, forms and
hooks) listed in ``_MODULES`` below, plus its round-trip test (tests/effects/test_roundtrip.py).
The order is DESIGN.md's vocabulary order (extend it, never rename).
"""
from __future__ import annotations

from ..errors import UnknownNameError
from .angle_sensor_offset import AngleSensorOffset
from .backlash import Backlash
from .end_stop import EndStop
from .external_leak import ExternalLeak
from .family import Family
from .force_sensor_offset import ForceSensorOffset
from .friction import CoulombFriction, Stiction, ViscousFriction
from .heat_transfer import HeatTransfer
from .line_dynamics import LineDynamics
from .piston_leak import PistonLeak
from .pressure_sensor_offset import PressureSensorOffset
from .supply_droop import SupplyDroop
from .valve_hysteresis import ValveHysteresis
from .valve_lag import ValveLag
from .valve_leak import ValveLeak

_CLASSES = (CoulombFriction, Stiction, ViscousFriction, ValveLeak, PistonLeak, ValveHysteresis, ValveLag,
            LineDynamics, HeatTransfer, PressureSensorOffset, AngleSensorOffset, SupplyDroop, EndStop, Backlash,
            ExternalLeak, ForceSensorOffset)

#: family name -> its definition, in DESIGN.md's vocabulary order
FAMILIES: dict[str, Family] = {cls.name: cls() for cls in _CLASSES}


def get_family(name: str) -> Family:
    """The family called ``name`` (UnknownNameError listing the valid names otherwise)."""
    try:
        return FAMILIES[name]
    except KeyError:
        raise UnknownNameError("effect family", name, FAMILIES) from None


def families_of(plant: str) -> list[Family]:
    """The families a plant kind simulates (``valve_arm``, ``bench_chamber``, ``bench_cylinder``, ``jetpipe``)."""
    return [f for f in FAMILIES.values() if plant in f.plants]


def markdown_table() -> str:
    """The families as a Markdown table (docs/effects.md holds it; a test keeps the two equal)."""
    rows = ["| family | place | forms: parameters [unit] | law | simulator (arm) | doctor (arm) | plants | sources |",
            "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for f in FAMILIES.values():
        doctor = f.doctor.replace("_", " ") if f.doctor else "—"
        simulator = f.simulator or "—"
        if f.roundtrip_gap:
            doctor += f" (no arm2 round trip: {f.roundtrip_gap})"
        rows.append(f"| `{f.name}` | {f.place_kind} | {f.describe()} | {f.physics} | {simulator} | {doctor} | "
                    f"{', '.join(f.plants)} | {f.sources} |")
    return "\n".join(rows) + "\n"
