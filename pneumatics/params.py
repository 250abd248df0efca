"""A model's fluid-power parameters: the TOML file in its folder, validated, as dataclasses.

File layout (every field documented in the dataclasses below)::

    [gas]        GasCfg           medium and polytropic exponent
    [supply]     SupplyCfg        supply and room pressures
    [control]    ControlCfg       controller rate
    [sensors]    SensorCfg        noise and DAQ averaging of the recorded sensors
    [valve]      ValveCfg         defaults for every valve
    [[actuator]] ActuatorCfg      one per cylinder; [actuator.valve_a] / [actuator.valve_b]
                                  override the valve defaults field by field
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

from .actuator import ActuatorCfg
from .config import from_table, read_toml, spec
from .errors import ConfigError
from .medium import GasCfg
from .valve import ValveCfg


@dataclass(frozen=True)
class SupplyCfg:
    supply_pa: float = spec(7.0e5, "supply (compressor) pressure, absolute", "Pa", 1.1e5, 5e7)
    room_pa: float = spec(1.0e5, "room (exhaust) pressure, absolute", "Pa", 5e4, 2e5)


@dataclass(frozen=True)
class ControlCfg:
    rate_hz: float = spec(100.0, "controller and recording rate", "Hz", 1.0, 1e5)


@dataclass(frozen=True)
class SensorCfg:
    angle_noise_rad: float = spec(0.00087, "white noise on recorded joint angles after averaging", "rad", 0.0, 0.1)
    pressure_noise_pa: float = spec(300.0, "white noise on recorded pressures after averaging", "Pa", 0.0, 1e5)
    average: bool = spec(True, "record the mean over each control period (DAQ averaging) instead of a sample")


@dataclass(frozen=True)
class FluidCfg:
    """All fluid-power parameters of one model."""

    gas: GasCfg = field(default_factory=GasCfg)
    supply: SupplyCfg = field(default_factory=SupplyCfg)
    control: ControlCfg = field(default_factory=ControlCfg)
    sensors: SensorCfg = field(default_factory=SensorCfg)
    actuators: tuple[ActuatorCfg, ...] = ()

    @property
    def actuator_names(self) -> list[str]:
        return [a.name for a in self.actuators]

    def replace_actuator(self, name: str, **changes) -> "FluidCfg":
        """A copy with fields of actuator ``name`` changed (e.g. for perturbation studies)."""
        acts = tuple(dataclasses.replace(a, **changes) if a.name == name else a for a in self.actuators)
        return dataclasses.replace(self, actuators=acts)


_GAS_RANGES = {
    "gas_constant_j_per_kg_k": (50.0, 5000.0), "heat_capacity_ratio": (1.0, 1.7),
    "temperature_k": (150.0, 500.0), "polytropic_exponent": (1.0, 1.7), "laminar_ratio": (0.9, 0.9999),
}


def gas_cfg(table, where) -> GasCfg:
    """The [gas] table of a fluid.toml as a checked GasCfg (``where`` names the file for errors)."""
    gas = from_table(GasCfg, table, where)
    for key, (lo, hi) in _GAS_RANGES.items():
        v = getattr(gas, key)
        if not isinstance(v, (int, float)) or not lo <= v <= hi:
            raise ConfigError(f"{where}.{key} = {v!r} is outside the plausible range [{lo:g}, {hi:g}]")
    if gas.polytropic_exponent > gas.heat_capacity_ratio:
        raise ConfigError(f"{where}.polytropic_exponent = {gas.polytropic_exponent:g} must lie between 1 "
                          f"(isothermal) and heat_capacity_ratio = {gas.heat_capacity_ratio:g} (adiabatic)")
    return gas


def parse_fluid(doc: dict, where: str) -> FluidCfg:
    """Build a :class:`FluidCfg` from a parsed TOML document; ``where`` names the file."""
    known = {"gas", "supply", "control", "sensors", "valve", "actuator"}
    kind = doc.get("kind", "valve_arm")
    if kind != "valve_arm":
        raise ConfigError(f"{where}: kind = {kind!r}; this loader builds only kind = 'valve_arm' models "
                          "(Kokoro valves and cylinders)")
    for key in doc:
        if key == "kind":
            continue
        if key not in known:
            raise ConfigError(f"{where}: unknown table [{key}]; valid: {', '.join(sorted(known))}")
    valve_defaults = doc.get("valve", {})
    from_table(ValveCfg, valve_defaults, f"{where} [valve]")  # validate the defaults alone

    def valve(table, w):
        return from_table(ValveCfg, {**valve_defaults, **table}, w)

    acts = doc.get("actuator")
    if not acts:
        raise ConfigError(f"{where}: no [[actuator]] tables; a model needs at least one actuator")
    actuators = []
    for i, t in enumerate(acts):
        w = f"{where} [[actuator]] #{i + 1}" + (f" ({t['name']})" if isinstance(t, dict) and "name" in t else "")
        a = from_table(ActuatorCfg, t, w, nested={"valve_a": valve, "valve_b": valve},
                       defaults={"valve_a": valve({}, w + ".valve_a"), "valve_b": valve({}, w + ".valve_b")})
        actuators.append(a)
    names = [a.name for a in actuators]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise ConfigError(f"{where}: actuator names repeat: {sorted(dup)}")
    supply = from_table(SupplyCfg, doc.get("supply", {}), f"{where} [supply]")
    if supply.supply_pa <= supply.room_pa:
        raise ConfigError(f"{where} [supply]: supply_pa = {supply.supply_pa:g} Pa must exceed room_pa = {supply.room_pa:g} Pa (absolute pressures)")
    return FluidCfg(
        gas=gas_cfg(doc.get("gas", {}), f"{where} [gas]"),
        supply=supply,
        control=from_table(ControlCfg, doc.get("control", {}), f"{where} [control]"),
        sensors=from_table(SensorCfg, doc.get("sensors", {}), f"{where} [sensors]"),
        actuators=tuple(actuators),
    )


def load_fluid(path: str | Path) -> FluidCfg:
    """Read and validate a fluid-power TOML file."""
    return parse_fluid(read_toml(path), str(path))
