"""line_dynamics: the tube between a valve and its chamber, in two forms.

``delay_volume``: a line of length L and bore d adds its volume pi d^2 L / 4 to the chamber's
dead volume and delays the flow: the acoustic transport delay L / c, stretched by the line's
resistance and capacitance into an effective dead time of several ms per metre (Richer &
Hurmuzlu, "A high performance pneumatic force actuator system", ASME JDSMC 122, 2000, §3 "the
connecting tubes", eqs. 12-15, whose distributed line they reduce to a delay and a volume).
The delay is modelled on the valve side: the spool position the chamber sees is the one of
``delay_s`` earlier (:func:`.valve_dynamics.dead_time` on a series)::

    x_seen(t) = x(t - delay),     V_dead -> V_dead + V_line

``lumped_rc``: the line as one lumped capacitance and one resistance (the lumped-parameter
line, one segment of the RC ladder a distributed line discretises into; Richer & Hurmuzlu
2000 §3, Krichel & Sawodny 2011's segmented lines with the inertance left out).  The valve
fills a tube of volume V_t at its own pressure p_t; the tube passes its air to the chamber
through a laminar resistance, linearised about the working pressure (conductance G)::

    dp_t/dt = n R T / V_t (mdot_valve(p_t) - G (p_t - p))
    mdot_into_chamber = G (p_t - p),      tau = V_t / (n R T G)

with tau the time constant of the tube emptying into a large chamber (n the chamber model's
polytropic exponent, paper 002 eq. 9, for the tube's gas too).  A fast valve into a tube of a
few cm^3 is stiff (relaxation rates up to ~1e4 1/s), so :func:`rc_line_step` integrates the
pair (p_t, p) in sub-steps of a linearly implicit (Rosenbrock) method, stable at any step.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .family import Family, param
from .valve_dynamics import dead_time

__all__ = ["DelayVolume", "LineDynamics", "LumpedRC", "dead_time", "rc_line_step", "rc_substeps",
           "tube_conductance", "tube_quasi_steady", "valve_into_tube"]

#: the sub-steps of :func:`rc_line_step` keep h x (the tube's relaxation rate) at most this
#: (for accuracy: the method is stable beyond)
SUBSTEP_RATE = 0.5
#: ROS2's parameter (pneumatics.chamber.GAMMA)
GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
#: and are at most this many a step (a valve wide open into a 0.1 cm^3 tube at 1 ms: ~40)
MAX_SUBSTEPS = 64


@dataclass(frozen=True)
class DelayVolume:
    """A tube reduced to a transport delay and a volume."""

    delay_s: float = param(0.0, "effective transport delay of the tube", "s", 0.0, 1.0)
    volume_m3: float = param(0.0, "the tube's volume, added to the chamber's dead volume", "m^3", 0.0, 1e-3)


@dataclass(frozen=True)
class LumpedRC:
    """A tube as one volume at its own pressure behind one laminar resistance."""

    tube_volume_m3: float = param(0.0, "the tube's volume, at its own pressure between valve and chamber", "m^3",
                                  0.0, 1e-3)
    time_constant_s: float = param(0.01, "time constant V_t / (n R T G) of the tube emptying through its "
                                   "resistance into a large chamber", "s", 1e-4, 1.0)


def valve_into_tube(a_s: float, a_e: float, g_s: float, g_e: float, supply_pa: float, room_pa: float, gas):
    """``valve_flow(p_t) -> (mdot, d mdot / d p_t)`` [kg/s, kg/(s Pa)] of :func:`rc_line_step`:
    the valve's supply and exhaust orifices of areas ``a_s``, ``a_e`` [m^2] (medium.orifice_flow)
    and its lands' clearances ``g_s``, ``g_e`` [kg/(s Pa)] (valve_leak.clearance_flows) into the
    tube at p_t, from the supply at ``supply_pa`` and to the room."""
    from ..medium import orifice_flow
    from .valve_leak import clearance_flows

    def valve_flow(q):
        m_s, _, dms = orifice_flow(a_s, supply_pa, q, gas)
        m_e, dme, _ = orifice_flow(a_e, q, room_pa, gas)
        m_c, dmc = clearance_flows(g_s, g_e, q, supply_pa, room_pa)
        return float(m_s - m_e + m_c), float(dms - dme + dmc)
    return valve_flow


def tube_conductance(tube_volume_m3, time_constant_s, n: float, rt: float):
    """G [kg/(s Pa)] of the lumped line's resistance: tau = V_t / (n R T G)."""
    return np.asarray(tube_volume_m3, float) / (n * rt * np.asarray(time_constant_s, float))


def rc_substeps(dt: float, tube_volume_m3: float, conductance: float, valve_slope: float, n: float, rt: float) -> int:
    """Sub-steps of :func:`rc_line_step` over ``dt`` for one tube: its relaxation rate
    n R T / V_t (|d mdot_valve / d p_t| + G) times the sub-step at most SUBSTEP_RATE."""
    rate = n * rt / tube_volume_m3 * (abs(valve_slope) + conductance)
    return int(min(MAX_SUBSTEPS, max(1, math.ceil(dt * rate / SUBSTEP_RATE))))


def rc_line_step(p_tube: float, p: float, volume: float, volume_rate: float, tube_volume_m3: float,
                 time_constant_s: float, valve_flow, other_flow: float, n: float, rt: float, dt: float):
    """(p_t, p) [Pa] of one lumped line and its chamber after ``dt`` [s] (module docstring):
    ``valve_flow(p_t) -> (mdot, d mdot / d p_t)`` the valve's flow into the tube [kg/s],
    ``other_flow`` the chamber's other flows (leaks) [kg/s] held over the step, the chamber's
    ``volume`` [m^3] and ``volume_rate`` [m^3/s] held too.  Sub-steps (:func:`rc_substeps`) of
    the two-stage Rosenbrock method ROS2 (Verwer et al. 1999; the chambers' own step,
    pneumatics.chamber.ros2_step) with the pair's exact Jacobian: second order, L-stable, and
    it keeps the air tube and chamber exchange (a linear invariant).  The numpy reference of
    the compiled twin (pneumatics.tube_kernel) that the simulator and the doctor step."""
    g = float(tube_conductance(tube_volume_m3, time_constant_s, n, rt))
    k_t, k_c = n * rt / tube_volume_m3, n / volume

    def rates(q_t, q):
        m_v, dm_v = valve_flow(q_t)
        m_x = g * (q_t - q)
        return k_t * (m_v - m_x), k_c * (rt * (m_x + other_flow) - q * volume_rate), dm_v

    steps = rc_substeps(dt, tube_volume_m3, g, valve_flow(p_tube)[1], n, rt)
    h = dt / steps
    for _ in range(steps):
        f_t, f_c, dm_v = rates(p_tube, p)
        # I - GAMMA h J, J the pair's Jacobian, solved by Cramer's rule
        a11, a12 = 1.0 - GAMMA * h * k_t * (dm_v - g), -GAMMA * h * k_t * g
        a21, a22 = -GAMMA * h * k_c * rt * g, 1.0 + GAMMA * h * k_c * (rt * g + volume_rate)
        det = a11 * a22 - a12 * a21
        k1_t, k1_c = (f_t * a22 - a12 * f_c) / det, (a11 * f_c - a21 * f_t) / det
        f_t, f_c, _ = rates(p_tube + h * k1_t, p + h * k1_c)
        b_t, b_c = f_t - 2.0 * k1_t, f_c - 2.0 * k1_c
        k2_t, k2_c = (b_t * a22 - a12 * b_c) / det, (a11 * b_c - a21 * b_t) / det
        p_tube = max(p_tube + h * (1.5 * k1_t + 0.5 * k2_t), 1.0)
        p = max(p + h * (1.5 * k1_c + 0.5 * k2_c), 1.0)
    return p_tube, p


#: safeguarded Newton iterations of :func:`tube_quasi_steady` (a fixed count: the compiled twin
#: takes the same steps)
QUASI_STEADY_ITERATIONS = 40


def tube_quasi_steady(p: float, conductance: float, valve_flow, low_pa: float, high_pa: float) -> float:
    """The tube pressure [Pa] at which the valve's flow into it equals its flow on into the
    chamber at ``p``: mdot_valve(p_t) = G (p_t - p), the tube settled after a few of its time
    constants.  A replay window of the doctor starts here where only the chamber's pressure is
    measured (starting at p would begin every window with the whole resistance's drop
    missing: ~100 kPa for a valve wide open into a 10 ms tube).  The root is unique (the left
    side falls with p_t, the right rises) and bracketed by [low_pa, high_pa], the room's and
    the supply's pressures or p; Newton's steps, bisection where one leaves the bracket."""
    lo, hi = min(low_pa, p), max(high_pa, p)
    x = p
    for _ in range(QUASI_STEADY_ITERATIONS):
        m_v, dm_v = valve_flow(x)
        f, df = m_v - conductance * (x - p), dm_v - conductance
        if f > 0.0:
            lo = x
        else:
            hi = x
        step = x - f / df if df < 0.0 else 0.5 * (lo + hi)
        x = step if lo < step < hi else 0.5 * (lo + hi)
    return x


class LineDynamics(Family):
    name = "line_dynamics"
    place_kind = "chamber"
    forms = {"delay_volume": DelayVolume, "lumped_rc": LumpedRC}
    physics = ("flow delayed by the tube's transport delay, its volume added to the dead volume; or the tube a "
               "volume at its own pressure behind a laminar resistance")
    sources = "Richer & Hurmuzlu 2000, §3 and eqs. 12-15; Krichel & Sawodny 2011 (lumped segments)"
    simulator = ("spool history delayed per chamber, dead volume + tube volume; the lumped form's tube "
                 "pressure a state of its own (the simulation steps in Python)")
    doctor = "pressure_replay"

    def effect_set_entry(self, params):
        if isinstance(params, LumpedRC):
            return {"line_dynamics": {"tube_volume_m3": params.tube_volume_m3,
                                      "tube_time_constant_s": params.time_constant_s}}
        return {"line_dynamics": {"delay_s": params.delay_s, "volume_m3": params.volume_m3}}

    def add_to(self, effects, place: str, params) -> None:
        """Delays in series add up (a valve dead time at the same chamber, valve_lag.py); a
        chamber holds one lumped tube."""
        line = effects.line_dynamics.setdefault(place, {})
        if isinstance(params, LumpedRC):
            line.update(self.effect_set_entry(params)["line_dynamics"])
            return
        line["delay_s"] = line.get("delay_s", 0.0) + params.delay_s
        line["volume_m3"] = line.get("volume_m3", 0.0) + params.volume_m3

    def mods_entry(self, params):
        if isinstance(params, LumpedRC):
            return {"tube_volume_m3": params.tube_volume_m3, "tube_time_constant_s": params.time_constant_s}
        return {"delay_s": params.delay_s, "extra_volume_m3": params.volume_m3}

    def draw(self, rng):
        # a longer tube than the model knows: 1-3 cm^3 more (4 mm bore, 8-24 cm; arm2's dead
        # volumes are 3-4 cm^3) and an effective delay of 10-30 ms (Richer & Hurmuzlu 2000)
        return DelayVolume(rng.uniform(0.01, 0.03), rng.uniform(1e-6, 3e-6))
