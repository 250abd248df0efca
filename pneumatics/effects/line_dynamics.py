"""line_dynamics: the tube between a valve and its chamber.

A line of length L and bore d adds its volume pi d^2 L / 4 to the chamber's dead volume and
delays the flow: the acoustic transport delay L / c, stretched by the line's resistance and
capacitance into an effective dead time of several ms per metre (Richer & Hurmuzlu, "A high
performance pneumatic force actuator system", ASME JDSMC 122, 2000, §3 "the connecting
tubes", eqs. 12-15, whose distributed line they reduce to a delay and a volume).  The delay is
modelled on the valve side: the spool position the chamber sees is the one of ``delay_s``
earlier (:func:`.valve_dynamics.dead_time` on a series)::

    x_seen(t) = x(t - delay),     V_dead -> V_dead + V_line
"""
from __future__ import annotations

from dataclasses import dataclass

from .family import Family, param
from .valve_dynamics import dead_time

__all__ = ["DelayVolume", "LineDynamics", "dead_time"]


@dataclass(frozen=True)
class DelayVolume:
    """A tube reduced to a transport delay and a volume."""

    delay_s: float = param(0.0, "effective transport delay of the tube", "s", 0.0, 1.0)
    volume_m3: float = param(0.0, "the tube's volume, added to the chamber's dead volume", "m^3", 0.0, 1e-3)


class LineDynamics(Family):
    name = "line_dynamics"
    place_kind = "chamber"
    forms = {"delay_volume": DelayVolume}
    physics = "flow delayed by the tube's transport delay; its volume added to the dead volume"
    sources = "Richer & Hurmuzlu 2000, eqs. 12-15"
    simulator = "spool history delayed per chamber; dead volume + tube volume"
    doctor = "pressure_replay"

    def effect_set_entry(self, params):
        return {"line_dynamics": {"delay_s": params.delay_s, "volume_m3": params.volume_m3}}

    def add_to(self, effects, place: str, params) -> None:
        """Delays in series add up (a valve dead time at the same chamber, valve_lag.py)."""
        line = effects.line_dynamics.setdefault(place, {})
        line["delay_s"] = line.get("delay_s", 0.0) + params.delay_s
        line["volume_m3"] = line.get("volume_m3", 0.0) + params.volume_m3

    def mods_entry(self, params):
        return {"delay_s": params.delay_s, "extra_volume_m3": params.volume_m3}

    def draw(self, rng):
        # a longer tube than the model knows: 1-3 cm^3 more (4 mm bore, 8-24 cm; arm2's dead
        # volumes are 3-4 cm^3) and an effective delay of 10-30 ms (Richer & Hurmuzlu 2000)
        return DelayVolume(rng.uniform(0.01, 0.03), rng.uniform(1e-6, 3e-6))
