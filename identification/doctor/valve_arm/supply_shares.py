"""Each chamber's share of the valves' supply flow at the measured pressures, kept between
replays so that a change at one chamber recomputes that chamber's share alone.

A drooping supply's replays start every window from the total flow the valves draw at the
measured chamber pressures (pneumatic.filtered_supply_flow, receiver.receiver_trajectory):
each valve's supply-side orifice flow (paper 002 eqs. 6-8, pneumatics.medium.orifice_flow) on
the 1 ms grid, summed over the chambers.  The sum is recomputed at every replay, yet a
calibration's finite-difference step or a candidate's fit moves one chamber's (one cylinder's)
parameters: the other chambers' shares are what they were.  On humanoid38 (76 chambers, 60 s:
4.6 million orifice flows a call) the recomputation took 0.61 s a replay, 150 s of a 622 s
doctor run on a supply-droop case (development seed 151639048, profiled 2026-12-03).

:class:`SupplyShares` keeps the last (F, C) shares of one recording set and recomputes the
columns whose inputs changed: the chamber's commands on the grid and its fields of the chamber
model that the flow reads (:data:`SHARE_FIELDS`); a change of a field every chamber reads
alike (:data:`SHARED_FIELDS`), of the supply pressure or of the recording set recomputes them
all.  receiver.measured_supply_flow is the reference it
is tested against (tests/test_supply_shares.py).
"""
from __future__ import annotations

import hashlib

import numpy as np

from pneumatics.medium import orifice_flow

from .data import Experiment, fine_pressures

#: PneumaticMods' per-chamber (C,) fields a chamber's supply flow at the measured pressures
#: reads: the valve's supply-area scale and leaks (pneumatic.model_areas) and the sensor's
#: offset taken out of the measured pressure (data.fine_pressures)
SHARE_FIELDS = ("supply_scale", "valve_leak_m2", "valve_leak_exhaust_m2", "valve_underlap_m2",
                "valve_underlap_width_v", "sensor_offset_pa", "sensor_drift_pa", "sensor_drift_tau_s")
#: ... and its fields every chamber's share reads alike
SHARED_FIELDS = ("valve_leak_width_v",)


class SupplyShares:
    """The valves' supply flows (F, C) [kg/s] at the measured pressures of one recording set,
    with what each column was computed from."""

    def __init__(self):
        self.data = None        # (p_at_t, fine_t, clock) arrays of the recording set (identity)
        self.shares = None      # (F, C) each chamber's flow from the supply [kg/s]
        self.inputs = None      # per chamber: a digest of its commands and its SHARE_FIELDS values
        self.shared = None      # SHARED_FIELDS' values, the supply pressure, the gas, the valve table

    def total(self, exp: Experiment, model, u_fine: np.ndarray, supply_pa: float) -> np.ndarray:
        """(F,) the total supply flow [kg/s], as receiver.measured_supply_flow gives it, from a
        supply at the scalar ``supply_pa``."""
        data = (exp.p_at_t, exp.fine_t, exp.clock)
        shared = (tuple(_value(model.mods, f) for f in SHARED_FIELDS), float(supply_pa), model.gas, model.tab.valve.tobytes())
        F = exp.fine_t.size
        inputs = [_chamber_inputs(model.mods, u_fine[:F, c], c) for c in range(u_fine.shape[1])]
        if self.shares is None or not _same_arrays(data, self.data) or shared != self.shared:
            stale = list(range(len(inputs)))
        else:
            stale = [c for c, (new, old) in enumerate(zip(inputs, self.inputs)) if new != old]
        if stale:
            if len(stale) == len(inputs):  # every column made anew (and the first time)
                self.shares = np.empty((F, len(inputs)))
            self.shares[:, stale] = chamber_supply_flows(exp, model, u_fine, float(supply_pa), np.array(stale))
        self.data, self.shared, self.inputs = data, shared, inputs
        return self.shares.sum(axis=1)


def chamber_supply_flows(exp: Experiment, model, u_fine: np.ndarray, supply_pa: float, chambers: np.ndarray) -> np.ndarray:
    """(F, len(chambers)) the flow [kg/s] each of ``chambers``' valves draws from the supply at
    the measured pressures (sensor offsets of the model removed), 0 where it would flow back."""
    p = fine_pressures(exp, model.mods, chambers)
    a_s = model.areas(u_fine[: p.shape[0]][:, chambers], chambers)[0]
    return np.maximum(orifice_flow(a_s, supply_pa, p, model.gas, derivatives=False)[0], 0.0)


def _chamber_inputs(mods, u_column: np.ndarray, c: int) -> tuple:
    """What chamber ``c``'s share is computed from: a digest of its commands (F,) and its
    SHARE_FIELDS values."""
    digest = hashlib.blake2b(np.ascontiguousarray(u_column), digest_size=16).digest()
    return (digest, *(_value(mods, f, c) for f in SHARE_FIELDS))


def _value(mods, name: str, c: int | None = None):
    v = getattr(mods, name)
    if v is None or c is None:
        return v
    return float(np.asarray(v)[c])


def _same_arrays(a: tuple, b: tuple | None) -> bool:
    return b is not None and all(x is y for x, y in zip(a, b))
