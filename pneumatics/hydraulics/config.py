"""Loader of a hydraulic model's ``fluid.toml`` (top-level ``kind = "hydraulic"``).

File layout (every field documented in the dataclasses named)::

    kind = "hydraulic"
    [oil]          OilCfg          density, bulk modulus, viscosity, discharge coefficient
    [power]        PowerCfg        pump and tank pressures
    [supply_line]  LineCfg         hose to the valve (+ accumulator)
    [return_line]  LineCfg         hose back to the tank
    [hysteresis]   HysteresisCfg   Jiles-Atherton parameters of the valve
    [servovalve]   ServovalveCfg   valve tip dynamics, ports, clearance leakage
    [vane]         VaneCfg         rotary actuator geometry and cross-chamber leakage
    [sensors]      HydraulicSensorCfg  recording rate and sensor noise

The mechanical parameters (inertias, shaft stiffness, friction, gravity) are in the MJCF.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..config import from_table, read_toml, spec
from ..errors import ConfigError
from ..oil import OilCfg
from .hysteresis import HysteresisCfg
from .lines import LineCfg, PowerCfg
from .servovalve import ServovalveCfg
from .vane import VaneCfg

KIND = "hydraulic"


@dataclass(frozen=True)
class HydraulicSensorCfg:
    rate_hz: float = spec(100.0, "recording rate (paper 001 §4: sampled at 10 ms)", "Hz", 1.0, 1e5)
    control_rate_hz: float = spec(1000.0, "rate at which the current command is updated (zero-"
                                  "order hold)", "Hz", 1.0, 1e5)
    angle_noise_rad: float = spec(3.0e-4, "white noise on recorded angles (encoder/RVDT)", "rad", 0.0, 0.1)
    pressure_noise_pa: float = spec(2.0e4, "white noise on recorded pressures (~0.1 % of 3000 psi)",
                                    "Pa", 0.0, 1e6)
    torque_noise_nm: float = spec(0.1, "white noise on the recorded joint torque (strain gauge)",
                                  "N m", 0.0, 10.0)


@dataclass(frozen=True)
class HydraulicCfg:
    """All fluid-power parameters of one hydraulic joint."""

    oil: OilCfg = field(default_factory=OilCfg)
    power: PowerCfg = field(default_factory=PowerCfg)
    supply_line: LineCfg = field(default_factory=LineCfg)
    return_line: LineCfg = field(default_factory=LineCfg)
    hysteresis: HysteresisCfg = field(default_factory=HysteresisCfg)
    servovalve: ServovalveCfg = field(default_factory=ServovalveCfg)
    vane: VaneCfg = field(default_factory=VaneCfg)
    sensors: HydraulicSensorCfg = field(default_factory=HydraulicSensorCfg)


SECTIONS = {"oil": OilCfg, "power": PowerCfg, "supply_line": LineCfg, "return_line": LineCfg,
            "hysteresis": HysteresisCfg, "servovalve": ServovalveCfg, "vane": VaneCfg,
            "sensors": HydraulicSensorCfg}


def parse_hydraulic(doc: dict, where: str) -> HydraulicCfg:
    """Build :class:`HydraulicCfg` from a parsed TOML document; ``where`` names it in errors."""
    kind = doc.get("kind")
    if kind != KIND:
        raise ConfigError(f"{where}: kind = {kind!r}, expected {KIND!r} for a hydraulic model")
    unknown = set(doc) - set(SECTIONS) - {"kind"}
    if unknown:
        raise ConfigError(f"{where}: unknown section(s) {', '.join(sorted(unknown))}; "
                          f"valid: kind, {', '.join(SECTIONS)}")
    parts = {name: from_table(cls, doc.get(name, {}), f"{where} [{name}]")
             for name, cls in SECTIONS.items()}
    return HydraulicCfg(**parts)


def load_hydraulic_cfg(path: str | Path) -> HydraulicCfg:
    """Read and validate a hydraulic ``fluid.toml``."""
    return parse_hydraulic(read_toml(path), str(path))
