"""valve_hysteresis: a play between a valve's command and its spool.

The spool follows the command only once the command has reversed by more than the play's
full width 2h: the play (backlash) operator, the simplest rate-independent hysteresis with
closing minor loops (Krasnosel'skii & Pokrovskii, *Systems with Hysteresis*, 1989, §2.1;
:func:`.valve_dynamics.play` on a whole command series)::

    y_k = min(max(y_{k-1}, u_k - h), u_k + h)

The simulator applies it at each new command (:func:`play_step`), the doctor's replays on the
recorded commands row by row: the same sequence of operations.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .family import Family, param
from .valve_dynamics import play

__all__ = ["Play", "ValveHysteresis", "play", "play_step"]


def play_step(spool_v, command_v, half_width_v):
    """The spool [V] after one new command [V] through a play of half-width h [V]; arrays broadcast."""
    return np.minimum(np.maximum(spool_v, command_v - half_width_v), command_v + half_width_v)


@dataclass(frozen=True)
class Play:
    """Play operator on a valve's command."""

    half_width_v: float = param(0.0, "half-width h of the play (the command reverses by 2h before the spool moves)",
                                "V", 0.0, 5.0)


class ValveHysteresis(Family):
    name = "valve_hysteresis"
    place_kind = "chamber"
    forms = {"play": Play}
    physics = "play operator of half-width h between command and spool"
    sources = "Krasnosel'skii & Pokrovskii 1989"
    simulator = "spool through the play at each command (Simulation.set_command)"
    doctor = "pressure_replay"
    plants = ("valve_arm", "jetpipe")

    def effect_set_entry(self, params):
        return {"valve_hysteresis_v": params.half_width_v}

    def mods_entry(self, params):
        return {"hysteresis_v": params.half_width_v}

    def draw(self, rng):
        return Play(rng.uniform(0.2, 0.45))
