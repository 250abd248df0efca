"""pressure_sensor_offset: a pressure transducer that reads the true pressure plus an offset.

    p_measured = p + offset                                   (form additive)
    p_measured = p + offset + drift (1 - exp(-t / tau))       (form warm_up_drift)

A zero drift of a strain-gauge transducer (e.g. Doebelin, *Measurement Systems*, 5th ed.,
§3.2 "zero drift").  The second form is the zero settling while the transducer warms up after
power-on: its temperature, and with it the bridge's zero, follows a first-order thermal system
(Doebelin §3.3, first-order instruments), t counted from the start of the recording (the
sensor switched on with it; a long tau is a linear drift over the recording).  The simulator
adds the offset to what the sensors report, never to the physics; the doctor's replays start
from the measured pressure minus it and report the replayed pressure plus it; the torque
balance sees it as a force error (area x offset, constant or settling in time).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .family import Family, param


def offset_at(t_s, offset_pa, drift_pa=0.0, time_constant_s=0.0):
    """The reading's offset [Pa] at times ``t_s`` [s] since the recording's start:
    offset + drift (1 - exp(-t / tau)); no drift where tau <= 0.  Broadcasts: t (N, 1) against
    per-chamber arrays (C,) gives (N, C)."""
    tau = np.asarray(time_constant_s, float)
    settled = np.where(tau > 0, -np.expm1(-np.asarray(t_s, float) / np.where(tau > 0, tau, 1.0)), 0.0)
    return offset_pa + np.asarray(drift_pa, float) * settled


def reading(true_pa, offset_pa, t_s=0.0, drift_pa=0.0, time_constant_s=0.0):
    """What the transducer reports [Pa] for a true absolute pressure [Pa] at ``t_s`` [s]."""
    return true_pa + offset_at(t_s, offset_pa, drift_pa, time_constant_s)


@dataclass(frozen=True)
class Additive:
    """A constant zero offset."""

    offset_pa: float = param(0.0, "reading minus true pressure", "Pa", -1e6, 1e6)


@dataclass(frozen=True)
class WarmUpDrift:
    """A zero offset that settles to offset + drift while the transducer warms up."""

    offset_pa: float = param(0.0, "reading minus true pressure at the recording's start", "Pa", -1e6, 1e6)
    drift_pa: float = param(0.0, "change of the offset from the start to its settled value", "Pa", -1e6, 1e6)
    time_constant_s: float = param(20.0, "time constant of the warm-up", "s", 0.1, 1e4, magnitude=False)


class PressureSensorOffset(Family):
    name = "pressure_sensor_offset"
    place_kind = "chamber"
    forms = {"additive": Additive, "warm_up_drift": WarmUpDrift}
    physics = "p_measured = p + offset, or + offset + drift (1 - exp(-t / tau)) from the recording's start"
    sources = "Doebelin, Measurement Systems §3.2 (zero drift), §3.3 (first-order warm-up)"
    simulator = "added to the observed pressures"
    doctor = "pressure_replay"
    plants = ("valve_arm", "bench_chamber", "jetpipe")

    def effect_set_entry(self, params):
        if isinstance(params, WarmUpDrift):
            return {"pressure_offset_pa": params.offset_pa,
                    "pressure_drift": {"drift_pa": params.drift_pa, "time_constant_s": params.time_constant_s}}
        return {"pressure_offset_pa": params.offset_pa}

    def mods_entry(self, params):
        if isinstance(params, WarmUpDrift):
            return {"sensor_offset_pa": params.offset_pa, "sensor_drift_pa": params.drift_pa,
                    "sensor_drift_tau_s": params.time_constant_s}
        return {"sensor_offset_pa": params.offset_pa}

    def draw(self, rng):
        return Additive(rng.choice([-1, 1]) * rng.uniform(8e3, 2e4))
