"""valve_lag: the spool follows its command through a first-order lag.

A proportional valve's spool is a position servo of finite bandwidth (paper 002: about 100 Hz
for the Kokoro valves; a slower or damaged one lags more): tau x' = u - x, discretised exactly
for a command held over each step (zero-order hold; e.g. Franklin, Powell & Workman, *Digital
Control of Dynamic Systems*, 3rd ed., §4.3)::

    x_{k+1} = u_k + (x_k - u_k) exp(-dt / tau)

The simulator advances the spool by it every physics step (taking the areas at mid-step), the
doctor's replays filter the recorded commands on the same 1 ms grid
(:func:`.valve_dynamics.first_order_lag`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .family import Family, param
from .valve_dynamics import first_order_lag

__all__ = ["FirstOrder", "ValveLag", "first_order_lag", "lag_decay"]


def lag_decay(tau_s, dt: float):
    """exp(-dt / tau) per step [-], 0 where there is no lag (tau <= 0)."""
    tau = np.asarray(tau_s, float)
    return np.where(tau > 0, np.exp(-dt / np.maximum(tau, 1e-300)), 0.0)


@dataclass(frozen=True)
class FirstOrder:
    """First-order lag of the spool."""

    time_constant_s: float = param(0.0, "time constant tau of the spool", "s", 0.0, 1.0)


class ValveLag(Family):
    name = "valve_lag"
    place_kind = "chamber"
    forms = {"first_order": FirstOrder}
    physics = "spool x follows the command u: tau x' = u - x"
    sources = "paper 002 (valve bandwidth); Franklin, Powell & Workman §4.3 (exact discretisation)"
    simulator = "spool stepped every physics step (Simulation._advance_spool)"
    doctor = "pressure_replay"
    plants = ("valve_arm", "jetpipe")

    def effect_set_entry(self, params):
        return {"valve_lag_s": params.time_constant_s}

    def mods_entry(self, params):
        return {"lag_s": params.time_constant_s}

    def draw(self, rng):
        return FirstOrder(rng.uniform(0.015, 0.04))
