"""Flat arrays of a model's fluid parameters, one row per chamber or actuator.

Both the numpy reference (:mod:`pneumatics.chamber`) and the compiled kernel
(:mod:`pneumatics.kernel`) read these; chambers are ordered a0, b0, a1, b1, ...
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .medium import GasCfg
from .params import FluidCfg
from .valve import valve_areas


@dataclass
class FluidTables:
    """Arrays (shapes in brackets) for the fluid update; SI units."""

    gas: GasCfg
    supply_pa: float
    room_pa: float
    area_a: np.ndarray          # (n_act,) m^2 or m^3/rad
    area_b: np.ndarray          # (n_act,)
    stroke: np.ndarray          # (n_act,) m or rad
    length_zero: np.ndarray     # (n_act,) actuator length at piston position 0
    area: np.ndarray            # (n_ch,)
    dead_volume: np.ndarray     # (n_ch,) m^3
    is_a: np.ndarray            # (n_ch,) bool
    actuator_of_chamber: np.ndarray  # (n_ch,) int
    valve: np.ndarray           # (n_ch, 8) valve rows, pneumatics.valve.VALVE_COLUMNS
    external_leak_m2: np.ndarray = None  # (n_ch,) leak to the room (effect), 0 = none
    piston_leak_m2: np.ndarray = None    # (n_act,) leak across the piston a -> b (effect)
    external_leak_g: np.ndarray = None   # (n_ch,) laminar leak to the room, conductance [kg/(s Pa)]
    piston_leak_g: np.ndarray = None     # (n_act,) laminar leak across the piston [kg/(s Pa)]
    supply_droop_pa_per_kg_s: float = 0.0  # supply pressure drop per kg/s of total supply flow (effect)
    supply_droop_pa_per_kg2_s2: float = 0.0  # ... per (kg/s)^2 of it (regulator_orifice form)
    supply_droop_tau_s: float = 0.0  # its time constant behind a receiver [s] (reservoir form; 0 = none)
    supply_compressor: np.ndarray = None  # (5,) compressor_cycling's receiver (effects.supply_droop.COMPRESSOR_FIELDS) or None

    def __post_init__(self):
        if self.external_leak_m2 is None:
            self.external_leak_m2 = np.zeros(self.area.size)
        if self.piston_leak_m2 is None:
            self.piston_leak_m2 = np.zeros(self.area_a.size)
        if self.external_leak_g is None:
            self.external_leak_g = np.zeros(self.area.size)
        if self.piston_leak_g is None:
            self.piston_leak_g = np.zeros(self.area_a.size)

    @property
    def n_chambers(self) -> int:
        return self.area.size

    @classmethod
    def build(cls, fluid: FluidCfg, length_zero: np.ndarray) -> "FluidTables":
        acts = fluid.actuators
        n = len(acts)
        area, dead, valve = [], [], []
        for a in acts:
            area += [a.area_a, a.area_b]
            dead += [a.dead_volume_a_m3, a.dead_volume_b_m3]
            valve += [a.valve_a.as_row(), a.valve_b.as_row()]
        return cls(
            gas=fluid.gas, supply_pa=fluid.supply.supply_pa, room_pa=fluid.supply.room_pa,
            area_a=np.array([a.area_a for a in acts]), area_b=np.array([a.area_b for a in acts]),
            stroke=np.array([a.stroke for a in acts]), length_zero=np.asarray(length_zero, float),
            area=np.array(area), dead_volume=np.array(dead),
            is_a=np.tile([True, False], n), actuator_of_chamber=np.repeat(np.arange(n), 2),
            valve=np.array(valve).reshape(2 * n, 8),
        )

    def packed(self):
        """(actuator table (n_act, 4), chamber table (n_ch, 12), globals (10,)) for the kernel."""
        act = np.column_stack([self.area_a, self.area_b, self.stroke, self.length_zero])
        ch = np.column_stack([self.area, self.dead_volume, self.is_a.astype(float),
                              self.actuator_of_chamber.astype(float), self.valve])
        glob = np.concatenate([self.gas.as_array(), [self.supply_pa, self.room_pa]])
        return np.ascontiguousarray(act), np.ascontiguousarray(ch), glob


def valve_areas_table(tables: FluidTables, command_v):
    """(supply, exhaust) effective areas [m^2] of every chamber's valve, each (n_ch,)."""
    return valve_areas(np.asarray(command_v, float), tables.valve)
