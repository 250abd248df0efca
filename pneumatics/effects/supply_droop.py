"""supply_droop: the supply pressure falls with the flow the valves draw.

A supply line and regulator of finite capacity: its pressure at the valves falls about
linearly with the total mass flow (the regulator's flow characteristic, ISO 6953-2; the
line's resistance, Beater, *Pneumatic Drives*, 2007, §4.2)::

    p_supply = p_supply,nominal - k sum_i max(m_supply,i, 0)                      (linear)

A receiver (or the line's own volume) between the regulator and the valves gives that droop a
time constant: the receiver's air balance, the regulator's flow linearised about the nominal
pressure as (p_nominal - p) / k (Beater 2007, ch. 2, compressed-air supply; a lumped
capacitance V / (R T))::

    V / (R T) dp/dt = (p_nominal - p) / k - m_total
    =>  p_supply = p_nominal - k m_f,   tau dm_f/dt = m_total - m_f,   tau = k V / (R T)   (reservoir)

A regulator whose seat passes the flow as an orifice close to its set pressure (subsonic, the
pressure ratio near 1) drops the pressure with the flow squared, m = C_d A sqrt(2 rho dp)
(Beater 2007, ch. 2 and §4.2; ISO 6358-1's subsonic branch as the ratio tends to 1), behind the
same receiver::

    p_supply = p_nominal - k2 m_f^2,   tau dm_f/dt = m_total - m_f              (regulator_orifice)

A compressor whose pressure switch runs it between a cut-in and a cut-out pressure fills a
receiver the valves and the system's leaks drain (Beater 2007, ch. 2: compressed-air supply;
the receiver isothermal)::

    V / (R T) dp/dt = m_c s - m_total - g (p - p_room),
    s -> 1 when p <= p_cut-in,  s -> 0 when p >= p_cut-out                 (compressor_cycling)

so the supply pressure saw-tooths between the two; it starts at the cut-out pressure with the
compressor off.  The flows are those of the previous step (the simulator's and the doctor's step alike); the
filter steps by backward Euler, m_f += (m_total - m_f) dt / (tau + dt), which is the linear
form for tau = 0.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .family import Family, param


def droop_pa(flow_kg_s, droop_pa_per_kg_s: float, droop_pa_per_kg2_s2: float = 0.0):
    """The supply's pressure drop [Pa] at a total (filtered) draw ``flow_kg_s`` >= 0: k m + k2 m^2."""
    return droop_pa_per_kg_s * flow_kg_s + droop_pa_per_kg2_s2 * flow_kg_s * flow_kg_s


def flow_of_droop(drop_pa: float, droop_pa_per_kg_s: float, droop_pa_per_kg2_s2: float = 0.0) -> float:
    """The draw [kg/s] a pressure drop ``drop_pa`` >= 0 stands for: :func:`droop_pa` inverted
    (the positive root; the simulator keeps the drop in effect, the reservoir's filter the flow)."""
    k, k2 = droop_pa_per_kg_s, droop_pa_per_kg2_s2
    if drop_pa <= 0.0:
        return 0.0
    if k2 <= 0.0:
        return drop_pa / k
    return 2.0 * drop_pa / (k + float(np.sqrt(k * k + 4.0 * k2 * drop_pa)))  # no cancellation at k2 m << k


def supply_pressure(nominal_pa: float, droop_pa_per_kg_s: float, supply_flows_kg_s,
                    droop_pa_per_kg2_s2: float = 0.0) -> float:
    """Supply pressure [Pa] in effect when the valves draw ``supply_flows_kg_s`` [kg/s] (n,)."""
    return nominal_pa - droop_pa(float(np.maximum(supply_flows_kg_s, 0.0).sum()), droop_pa_per_kg_s,
                                 droop_pa_per_kg2_s2)


def filtered_flow(previous_kg_s: float, total_kg_s: float, tau_s: float, dt_s: float) -> float:
    """The reservoir form's filtered total flow m_f [kg/s] one step of dt_s after
    ``previous_kg_s``, the valves drawing ``total_kg_s`` (backward Euler; tau_s = 0: the total)."""
    return previous_kg_s + (total_kg_s - previous_kg_s) * dt_s / (tau_s + dt_s)


@dataclass(frozen=True)
class Linear:
    """A linear droop of the supply pressure with the total supply flow."""

    droop_pa_per_kg_s: float = param(0.0, "pressure drop per kg/s of total supply flow", "Pa/(kg/s)", 0.0, 1e10)


@dataclass(frozen=True)
class Reservoir:
    """The linear droop behind a receiver: the pressure falls by k times the total flow low-passed
    with the receiver's time constant tau = k V / (R T)."""

    droop_pa_per_kg_s: float = param(0.0, "steady pressure drop per kg/s of total supply flow", "Pa/(kg/s)", 0.0, 1e10)
    time_constant_s: float = param(0.05, "time constant of the receiver behind the regulator", "s", 0.0, 10.0,
                                   magnitude=False)


@dataclass(frozen=True)
class RegulatorOrifice:
    """A regulator whose seat is an orifice: the pressure falls with the square of the total flow
    low-passed by the receiver behind it."""

    droop_pa_per_kg2_s2: float = param(0.0, "pressure drop per (kg/s)^2 of total supply flow", "Pa/(kg/s)^2",
                                       0.0, 1e14)
    time_constant_s: float = param(0.0, "time constant of the receiver behind the regulator", "s", 0.0, 10.0,
                                   magnitude=False)


@dataclass(frozen=True)
class CompressorCycling:
    """A receiver filled by a compressor that a pressure switch runs between two pressures."""

    receiver_volume_m3: float = param(1e-3, "the receiver's volume", "m^3", 0.0, 10.0, magnitude=False)
    compressor_kg_s: float = param(3e-4, "the compressor's delivery while it runs", "kg/s", 0.0, 1.0,
                                   magnitude=False)
    band_pa: float = param(0.0, "cut-out minus cut-in pressure of the switch", "Pa", 0.0, 1e6)
    cut_out_pa: float = param(7e5, "the pressure the switch stops the compressor at", "Pa", 1e5, 2e6,
                              magnitude=False)
    leak_kg_s_pa: float = param(3e-11, "the system's leak conductance to the room", "kg/(s Pa)", 0.0, 1e-6,
                                magnitude=False)


def receiver_step(p_pa: float, running: bool, total_kg_s: float, c: CompressorCycling, rt: float, room_pa: float,
                  dt: float) -> tuple[float, bool]:
    """(pressure [Pa], compressor running) of the compressor_cycling form's receiver one step
    of dt [s] on, the valves drawing ``total_kg_s``; rt = R T [J/kg] (explicit Euler: the
    receiver's time constants are seconds)."""
    if p_pa >= c.cut_out_pa:
        running = False
    elif p_pa <= c.cut_out_pa - c.band_pa:
        running = True
    m_in = c.compressor_kg_s * running - total_kg_s - c.leak_kg_s_pa * (p_pa - room_pa)
    return p_pa + dt * rt / c.receiver_volume_m3 * m_in, running


#: the EffectSet (and PneumaticMods) fields of the compressor_cycling form, in its field order
COMPRESSOR_FIELDS = ("supply_receiver_m3", "supply_compressor_kg_s", "supply_band_pa", "supply_cut_out_pa",
                     "supply_leak_kg_s_pa")


class SupplyDroop(Family):
    name = "supply_droop"
    place_kind = "supply"
    forms = {"linear": Linear, "reservoir": Reservoir, "compressor_cycling": CompressorCycling,
             "regulator_orifice": RegulatorOrifice}
    physics = ("p_supply = nominal - k x total supply mass flow (low-passed with tau behind a receiver), or "
               "- k2 x its square (a regulator's orifice); or a receiver a switched compressor refills")
    sources = ("ISO 6953-2 (regulator flow characteristic); Beater 2007 §4.2 and ch. 2 (receiver, compressor, "
               "regulator orifice)")
    simulator = "supply pressure per step from the last step's flows, filtered with tau, or the receiver's (kernel)"
    doctor = "pressure_replay"
    plants = ("valve_arm", "jetpipe")

    def effect_set_entry(self, params):
        if isinstance(params, CompressorCycling):
            return dict(zip(COMPRESSOR_FIELDS, dataclasses.astuple(params)))
        return {"supply_droop_pa_per_kg_s": getattr(params, "droop_pa_per_kg_s", 0.0),
                "supply_droop_pa_per_kg2_s2": getattr(params, "droop_pa_per_kg2_s2", 0.0),
                "supply_droop_tau_s": getattr(params, "time_constant_s", 0.0)}

    def mods_entry(self, params):
        return self.effect_set_entry(params)

    def draw(self, rng):
        return Linear(rng.uniform(4e7, 1e8))
