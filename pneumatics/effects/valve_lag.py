"""valve_lag: the spool follows its command through a first-order lag, or a dead time.

A proportional valve's spool is a position servo of finite bandwidth (paper 002: about 100 Hz
for the Kokoro valves; a slower or damaged one lags more): tau x' = u - x, discretised exactly
for a command held over each step (zero-order hold; e.g. Franklin, Powell & Workman, *Digital
Control of Dynamic Systems*, 3rd ed., §4.3)::

    x_{k+1} = u_k + (x_k - u_k) exp(-dt / tau)

The simulator advances the spool by it every physics step (taking the areas at mid-step), the
doctor's replays filter the recorded commands on the same 1 ms grid
(:func:`.valve_dynamics.first_order_lag`).

The second form, a dead time (a valve driver's transport delay, a digital valve's update
period): the spool takes the command of ``dead_time_s`` earlier, x(t) = u(t - T).  It is the
delay of line_dynamics without the tube's volume, so it runs on that mechanism: the simulator's
delayed spool history and the replays' :func:`.valve_dynamics.dead_time` (a line and a valve
dead time at one chamber add their delays).

The third, a slew limit: the spool moves toward its command at most at the rate that crosses
the whole command range in ``full_stroke_time_s`` (a solenoid's force bounds the spool's
speed; a valve datasheet's "response time 0-100 %"), |x'| <= (u_max - u_min) / T.  Large steps
take the spool a fixed time, small ones none: no linear lag has that shape.  The simulator
limits the spool's step every physics step (after the lag), the replays filter the commands
on the 1 ms grid (:func:`.valve_dynamics.slew_limited`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .family import Family, param
from .valve_dynamics import first_order_lag

__all__ = ["COMMAND_SPAN_V", "DeadTime", "FirstOrder", "SlewLimit", "ValveLag", "first_order_lag", "lag_decay",
           "slew_step_v"]


def lag_decay(tau_s, dt: float):
    """exp(-dt / tau) per step [-], 0 where there is no lag (tau <= 0)."""
    tau = np.asarray(tau_s, float)
    return np.where(tau > 0, np.exp(-dt / np.maximum(tau, 1e-300)), 0.0)


@dataclass(frozen=True)
class FirstOrder:
    """First-order lag of the spool."""

    time_constant_s: float = param(0.0, "time constant tau of the spool", "s", 0.0, 1.0)


@dataclass(frozen=True)
class DeadTime:
    """A pure delay between command and spool."""

    dead_time_s: float = param(0.0, "dead time T between the command and the spool", "s", 0.0, 1.0)


@dataclass(frozen=True)
class SlewLimit:
    """A bound on the spool's speed."""

    full_stroke_time_s: float = param(0.0, "least time the spool takes to cross the whole command range "
                                      "(COMMAND_SPAN_V)", "s", 0.0, 2.0)


#: the command range a full stroke crosses [V] (pneumatics.sim.COMMAND_RANGE_V, 0-10 V)
COMMAND_SPAN_V = 10.0


def slew_step_v(full_stroke_time_s, dt: float):
    """The most the spool moves in one step of dt [V] (inf where there is no slew limit)."""
    t = np.asarray(full_stroke_time_s, float)
    return np.where(t > 0, COMMAND_SPAN_V * dt / np.maximum(t, 1e-300), np.inf)


class ValveLag(Family):
    name = "valve_lag"
    place_kind = "chamber"
    forms = {"first_order": FirstOrder, "dead_time": DeadTime, "slew_limit": SlewLimit}
    physics = "spool x follows the command u: tau x' = u - x, or x(t) = u(t - T), or |x'| <= span / T_stroke"
    sources = "paper 002 (valve bandwidth); Franklin, Powell & Workman §4.3 (exact discretisation)"
    simulator = "spool stepped every physics step (valve_bank.ValveBank.advance)"
    doctor = "pressure_replay"
    plants = ("valve_arm", "jetpipe")

    def effect_set_entry(self, params):
        if isinstance(params, DeadTime):
            return {"line_dynamics": {"delay_s": params.dead_time_s}}
        if isinstance(params, SlewLimit):
            return {"valve_slew_s": params.full_stroke_time_s}
        return {"valve_lag_s": params.time_constant_s}

    def add_to(self, effects, place: str, params) -> None:
        """A dead time adds to the delay of a line at the same chamber (the spool the chamber
        sees is delayed by both); the first-order lag is set as the base class does."""
        if not isinstance(params, DeadTime):
            return super().add_to(effects, place, params)
        line = effects.line_dynamics.setdefault(place, {})
        line["delay_s"] = line.get("delay_s", 0.0) + params.dead_time_s

    def mods_entry(self, params):
        if isinstance(params, DeadTime):
            return {"delay_s": params.dead_time_s}
        if isinstance(params, SlewLimit):
            return {"stroke_time_s": params.full_stroke_time_s}
        return {"lag_s": params.time_constant_s}

    def draw(self, rng):
        return FirstOrder(rng.uniform(0.015, 0.04))
