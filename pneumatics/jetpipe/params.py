"""Parameters of the jet-pipe actuator (paper 000): ``models/jetpipe/fluid.toml`` as dataclasses.

File layout (``kind = "jetpipe"``; every field documented below, SI units, pressures absolute)::

    [gas]         GasCfg         air; polytropic exponent 1.4 = adiabatic chambers (000 eq. 11)
    [supply]      SupplyCfg      supply and room pressures
    [driver]      DriverCfg      current driver and coil (000 Sec. II-B, III-A)
    [jet]         JetCfg         static nonlinearity, third-order dynamics, offset (eqs. 2-4)
    [hysteresis]  HysteresisCfg  current -> jet position hysteresis (Sec. III-A, ~8 %)
    [ports]       PortsCfg       receiver geometry and discharge coefficient (Sec. II-C, eq. 5)
    [leak]        LeakCfg        piston leakage, pressure-ratio dependent (eq. 6)
    [cylinder]    CylinderCfg    piston area, stroke, dead volumes, stopper position x_s
    [control]     ControlCfg     default servo rate
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

from ..config import from_table, read_toml, spec
from ..errors import ConfigError
from ..medium import GasCfg
from ..params import ControlCfg, gas_cfg


@dataclass(frozen=True)
class SupplyCfg:
    supply_pa: float = spec(651.325e3, "supply pressure, absolute (Table I: 550 kPa gauge)", "Pa", 1.1e5, 2e6)
    room_pa: float = spec(101.325e3, "room (vent) pressure, absolute", "Pa", 5e4, 2e5)


@dataclass(frozen=True)
class DriverCfg:
    corner_hz: float = spec(1122.0, "corner frequency of the first-order current driver (Sec. II-B)", "Hz", 1.0, 1e5)
    force_constant_n_per_a: float = spec(1.946, "k_m: jet-pipe tip force per coil current (eq. 1, Fig. 6c)", "N/A", 0.01, 100.0)
    current_limit_a: float = spec(0.4, "rated current of the coil; the driver saturates here (Sec. III-A)", "A", 0.01, 10.0)


@dataclass(frozen=True)
class JetCfg:
    omega1_rad_s: float = spec(973.8, "w1, first-order break of the jet-pipe dynamics (eq. 3)", "rad/s", 1.0, 1e5)
    omega2_rad_s: float = spec(1856.7, "w2, second-order break of the jet-pipe dynamics (eq. 3)", "rad/s", 1.0, 1e5)
    damping_ratio: float = spec(0.419, "zeta of the second-order part (eq. 3)", "-", 0.01, 5.0)
    saturation_m: float = spec(0.5e-3, "x_sat: the jet position saturates at +-x_sat (1 mm range, Sec. III-A)", "m", 1e-5, 5e-3)
    saturation_force_n: float = spec(0.1303, "F_sat in f3(F) = x_sat tanh(F/F_sat) (eq. 2); sets k = 550 N/A at 45 N, see README", "N", 0.01, 10.0)
    offset_m: float = spec(0.099e-3, "x_jp,offset: misalignment of the jet origin (eq. 4), identified 0.099 mm", "m", -1e-3, 1e-3)


@dataclass(frozen=True)
class HysteresisCfg:
    half_width_m: float = spec(0.08e-3, "distance midpoint line - major loop in jet position (0.08 mm = 8 % of 1 mm)", "m", 0.0, 1e-3)
    n_operators: int = spec(8, "number of play operators of the Prandtl-Ishlinskii model", "-", 1, 200)


@dataclass(frozen=True)
class PortsCfg:
    jet_diameter_m: float = spec(0.9652e-3, "D_o: jet exit and receiver port diameter (Table I)", "m", 1e-5, 1e-2)
    port_centre_m: float = spec(0.9652e-3, "distance of each port centre from the receiver centre (one D: ports one diameter apart)", "m", 1e-5, 1e-2)
    flange_diameter_m: float = spec(2.8956e-3, "diameter of the jet-tip flange (3 D_o, Sec. II-C)", "m", 1e-5, 3e-2)
    discharge_coefficient: float = spec(0.696, "C_d of the supply and vent orifices (identified, Sec. III-B)", "-", 0.05, 1.0)


@dataclass(frozen=True)
class LeakCfg:
    slope_m2: float = spec(-0.0475e-6, "C_dm A_lpp: leak effective area per unit pressure ratio P_down/P_up (eq. 6)", "m^2", -1e-5, 1e-5)
    offset_m2: float = spec(0.0971e-6, "C_dc A_lpp: leak effective area at zero pressure ratio (eq. 6)", "m^2", 0.0, 1e-5)


@dataclass(frozen=True)
class CylinderCfg:
    piston_area_m2: float = spec(1.24e-4, "A_p: piston area (Table I)", "m^2", 1e-6, 1e-2)
    stroke_m: float = spec(0.0508, "actuator movement range (Table I)", "m", 1e-3, 1.0)
    dead_volume_1_m3: float = spec(7.5e-6, "chamber 1 volume at zero piston travel (valve passages, line); fits Table II", "m^3", 1e-9, 1e-3)
    dead_volume_2_m3: float = spec(7.5e-6, "chamber 2 volume at full piston travel (valve passages, line)", "m^3", 1e-9, 1e-3)
    stopper_position_m: float = spec(0.054, "x_s: rod stopper position (54 mm = mid-stroke in Sec. III-B)", "m", 0.0, 1.0)
    stopper_datum_m: float = spec(0.0286, "x_s at which chamber 1 has zero length (54 mm - half stroke)", "m", 0.0, 1.0)

    @property
    def chamber1_length_m(self) -> float:
        """Piston travel from the chamber-1 end cap when it rests on the stopper [m]."""
        return self.stopper_position_m - self.stopper_datum_m


@dataclass(frozen=True)
class JetpipeCfg:
    """All fluid-power parameters of the jet-pipe actuator."""

    gas: GasCfg = field(default_factory=GasCfg)
    supply: SupplyCfg = field(default_factory=SupplyCfg)
    driver: DriverCfg = field(default_factory=DriverCfg)
    jet: JetCfg = field(default_factory=JetCfg)
    hysteresis: HysteresisCfg = field(default_factory=HysteresisCfg)
    ports: PortsCfg = field(default_factory=PortsCfg)
    leak: LeakCfg = field(default_factory=LeakCfg)
    cylinder: CylinderCfg = field(default_factory=CylinderCfg)
    control: ControlCfg = field(default_factory=lambda: ControlCfg(rate_hz=1000.0))

    def replace(self, section: str, **changes) -> JetpipeCfg:
        """A copy with fields of one section changed, e.g. ``cfg.replace("cylinder", stopper_position_m=0.07)``."""
        return dataclasses.replace(self, **{section: dataclasses.replace(getattr(self, section), **changes)})

    @property
    def hysteresis_half_width_n(self) -> float:
        """The hysteresis half-width as tip force [N]: the play radius that moves the static jet
        position f3 by ``half_width_m`` at the centre (f3 inverted)."""
        j, h = self.jet, self.hysteresis.half_width_m
        return j.saturation_force_n * math.atanh(min(h / j.saturation_m, 0.999))


_SECTIONS = {"supply": SupplyCfg, "driver": DriverCfg, "jet": JetCfg, "hysteresis": HysteresisCfg,
             "ports": PortsCfg, "leak": LeakCfg, "cylinder": CylinderCfg, "control": ControlCfg}


def parse_jetpipe(doc: dict, where: str) -> JetpipeCfg:
    """Build a :class:`JetpipeCfg` from a parsed TOML document; ``where`` names the file."""
    kind = doc.get("kind")
    if kind != "jetpipe":
        raise ConfigError(f"{where}: kind = {kind!r}; the jet-pipe loader needs kind = 'jetpipe'")
    for key in doc:
        if key != "kind" and key != "gas" and key not in _SECTIONS:
            raise ConfigError(f"{where}: unknown table [{key}]; valid: gas, {', '.join(_SECTIONS)}")
    parts = {name: from_table(cls, doc.get(name, {}), f"{where} [{name}]") for name, cls in _SECTIONS.items()}
    parts["hysteresis"] = dataclasses.replace(parts["hysteresis"], n_operators=int(parts["hysteresis"].n_operators))
    cfg = JetpipeCfg(gas=gas_cfg(doc.get("gas", {}), f"{where} [gas]"), **parts)
    s, c, p = cfg.supply, cfg.cylinder, cfg.ports
    if s.supply_pa <= s.room_pa:
        raise ConfigError(f"{where} [supply]: supply_pa = {s.supply_pa:g} Pa must exceed room_pa = {s.room_pa:g} Pa "
                          "(absolute pressures)")
    if not 0.0 <= c.chamber1_length_m <= c.stroke_m:
        raise ConfigError(f"{where} [cylinder]: stopper_position_m = {c.stopper_position_m:g} m puts the piston "
                          f"outside its stroke: need stopper_datum_m <= x_s <= stopper_datum_m + stroke_m "
                          f"= [{c.stopper_datum_m:g}, {c.stopper_datum_m + c.stroke_m:g}] m")
    if p.flange_diameter_m < p.jet_diameter_m:
        raise ConfigError(f"{where} [ports]: flange_diameter_m must be at least jet_diameter_m")
    if cfg.hysteresis.half_width_m >= cfg.jet.saturation_m:
        raise ConfigError(f"{where} [hysteresis]: half_width_m must be below [jet] saturation_m")
    return cfg


def load_jetpipe_cfg(path: str | Path) -> JetpipeCfg:
    """Read and validate a jet-pipe fluid.toml."""
    return parse_jetpipe(read_toml(path), str(path))
