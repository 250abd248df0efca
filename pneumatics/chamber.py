"""Chamber pressure dynamics and the integration step (numpy reference implementation).

Pressure ODE, paper 002 eq. 9 (paper 000 eq. 12), with a polytropic exponent n in [1, k]::

    dp/dt = n / V * (R T mdot - p dV/dt),     mdot = mdot_supply(p) - mdot_exhaust(p)

Integration over one physics step h (1 ms), once MuJoCo has made it (so the volume change
over the step is known exactly), uses the two-stage, second-order, L-stable
Rosenbrock method ROS2 (Verwer et al., SIAM J. Sci. Comput. 20, 1999), gamma = 1 + 1/sqrt 2,
with the exact scalar Jacobian J = dp'/dp of each chamber::

    (1 - gamma h J) k1 = f(p)
    (1 - gamma h J) k2 = f(p + h k1) - 2 k1
    p+ = p + 3/2 h k1 + 1/2 h k2

Explicit Euler is unstable at 1 ms for the smallest dead volumes (|J h| > 2 near the
zero-flow point), while ROS2 is stable for any stiffness.  Volume (at the step's midpoint) and volume
rate are held over the step.  A chamber whose pressure would change by more than a
quarter in one step (a violent expansion of a small volume), or whose embedded first-order
solution p + h k1 differs from p+ by more than ERR_TOL = 0.1 % of p, is re-integrated with
2, 4, .. 64 equal sub-steps, so pressures stay positive and bounded without clamping; at 1 ms
with the shipped models this refinement is rare (counted in tests/test_kernel.py).

This module is the readable reference; :mod:`pneumatics.kernel` is the compiled fast path
with the same arithmetic, tested against it to round-off.
"""
from __future__ import annotations

import numpy as np

from .effects.external_leak import laminar_flow
from .effects.piston_leak import piston_leak_flow
from .effects.supply_droop import (CompressorCycling, droop_pa, filtered_flow, flow_of_droop, receiver_step,
                                   supply_pressure)
from .effects.valve_leak import clearance_flows
from .medium import GasCfg, orifice_flow
from .tables import FluidTables, valve_areas_table
from .valve import valve_areas

GAMMA = 1.0 + 1.0 / np.sqrt(2.0)
MAX_HALVINGS = 6
MAX_REL_CHANGE = 0.25
ERR_TOL = 1e-3


def pressure_rate(p, volume, volume_rate, a_supply, a_exhaust, gas: GasCfg, supply_pa, room_pa, extra_flow=0.0):
    """dp/dt [Pa/s] and its derivative d(dp/dt)/dp [1/s] for chambers (all arrays (n,)).

    ``extra_flow`` [kg/s] (leak effects) is held over the step and not in the Jacobian."""
    m_s, _, dms_dp = orifice_flow(a_supply, supply_pa, p, gas)
    m_e, dme_dp, _ = orifice_flow(a_exhaust, p, room_pa, gas)
    rt = gas.gas_constant_j_per_kg_k * gas.temperature_k
    n = gas.polytropic_exponent
    rate = n / volume * (rt * (m_s - m_e + extra_flow) - p * volume_rate)
    jac = n / volume * (rt * (dms_dp - dme_dp) - volume_rate)
    return rate, jac


def ros2_step(p, h, rhs):
    """One ROS2 step of size h for the scalar ODEs p' = rhs(p) -> (rate, jac).

    Returns (p+, error estimate): the difference to the embedded first-order solution
    p + h k1 (Verwer et al. 1999), used to refine the step."""
    f0, jac = rhs(p)
    denom = 1.0 - GAMMA * h * jac
    k1 = f0 / denom
    f1, _ = rhs(p + h * k1)
    k2 = (f1 - 2.0 * k1) / denom
    return p + 1.5 * h * k1 + 0.5 * h * k2, 0.5 * h * np.abs(k1 + k2)


def chamber_geometry(tables: FluidTables, prev_length, length, dt):
    """Mean volume [m^3] and volume rate [m^3/s] of every chamber, each (n_ch,), over a step
    in which the actuators moved from ``prev_length`` to ``length`` (n_act,).

    Using the volume change MuJoCo actually made (rather than the velocity at the step's
    start) keeps closed chambers exactly consistent with the motion: p V^n stays constant
    to third order per step, even through impacts at the joint limits.
    """
    act = tables.actuator_of_chamber
    stroke = tables.stroke[act]
    x0 = np.clip(prev_length[act] - tables.length_zero[act], 0.0, stroke)
    x1 = np.clip(length[act] - tables.length_zero[act], 0.0, stroke)
    x_mid = 0.5 * (x0 + x1)
    travel = np.where(tables.is_a, x_mid, stroke - x_mid)
    volume = tables.dead_volume + tables.area * travel
    volume_rate = np.where(tables.is_a, 1.0, -1.0) * tables.area * (x1 - x0) / dt
    return volume, volume_rate


def actuator_force(tables: FluidTables, p):
    """Force [N] (torque [N m] for vanes) of every actuator from chamber pressures.

    ``p`` is (..., n_ch), chambers a0, b0, a1, b1, ...; returns (..., n_act)."""
    p_a, p_b = p[..., 0::2], p[..., 1::2]
    return tables.area_a * p_a - tables.area_b * p_b - (tables.area_a - tables.area_b) * tables.room_pa


def fluid_step(tables: FluidTables, p, command_v, prev_length, length, dt):
    """Advance chamber pressures over one step.

    Args:
      tables: the model's fluid tables.
      p: (n_ch,) pressures [Pa abs] at t, chambers ordered a0, b0, a1, b1, ...
      command_v: (n_ch,) valve commands [V] held over the step, already clipped.
      prev_length, length: (n_act,) MuJoCo actuator lengths [m or rad] at t and t + dt.
      dt: step [s].
    Returns:
      (n_ch,) pressures at t + dt.
    """
    a_s, a_e = valve_areas_table(tables, command_v)
    return fluid_step_areas(tables, p, a_s, a_e, prev_length, length, dt)


def fluid_step_areas(tables: FluidTables, p, a_supply, a_exhaust, prev_length, length, dt, supply_pa=None,
                     clearance=None):
    """:func:`fluid_step` with the valves' (n_ch,) supply and exhaust areas [m^2] given, and
    the supply pressure in effect (``supply_pa``, default the nominal one; see supply_flow);
    ``clearance`` (n_ch, 2) the valves' land conductances of the valve_leak's clearance form
    [kg/(s Pa)] at the present spool positions, or None."""
    a_s, a_e = a_supply, a_exhaust
    volume, volume_rate = chamber_geometry(tables, prev_length, length, dt)
    ps = tables.supply_pa if supply_pa is None else supply_pa
    return integrate(p, volume, volume_rate, a_s, a_e, tables.gas, ps, tables.room_pa, dt,
                     leak_flows(tables, p, clearance, ps))


def supply_pressure_after(tables: FluidTables, p, a_supply, previous_pa: float | None = None,
                          dt: float = 0.0) -> float:
    """Supply pressure [Pa] in effect for the next step under the supply_droop effect: the
    nominal supply minus the droop (k m + k2 m^2) of the total mass flow the chambers draw at pressures p, that
    flow low-passed over ``dt`` [s] with the reservoir form's time constant from the
    ``previous_pa`` supply pressure in effect (effects.supply_droop)."""
    k, k2 = tables.supply_droop_pa_per_kg_s, tables.supply_droop_pa_per_kg2_s2
    if k <= 0 and k2 <= 0:
        return tables.supply_pa
    m = orifice_flow(a_supply, tables.supply_pa, p, tables.gas)[0]
    if tables.supply_droop_tau_s <= 0 or previous_pa is None:
        return supply_pressure(tables.supply_pa, k, m, k2)
    before = flow_of_droop(tables.supply_pa - previous_pa, k, k2)
    total = float(np.maximum(m, 0.0).sum())
    return tables.supply_pa - droop_pa(filtered_flow(before, total, tables.supply_droop_tau_s, dt), k, k2)


def receiver_after(tables: FluidTables, p, a_supply, previous_pa: float, running: bool, dt: float) -> tuple[float, bool]:
    """(supply pressure [Pa], compressor running) for the next step under the supply_droop
    effect's compressor_cycling form: its receiver (at ``previous_pa``) one step of dt on, the
    valves drawing their flows at chamber pressures p (effects.supply_droop.receiver_step)."""
    c = CompressorCycling(*tables.supply_compressor)
    m = np.maximum(orifice_flow(a_supply, previous_pa, p, tables.gas)[0], 0.0).sum()
    gas = tables.gas
    return receiver_step(previous_pa, running, float(m), c, gas.gas_constant_j_per_kg_k * gas.temperature_k,
                         tables.room_pa, dt)


def leak_flows(tables: FluidTables, p, clearance=None, supply_pa: float | None = None):
    """(n_ch,) mass flows [kg/s] into each chamber from the leak effects: to the room
    (external_leak) and across the piston a -> b (piston_leak), orifices and laminar gaps.  Equal and opposite across a
    piston, so a piston leak conserves the cylinder's air.  ``clearance`` (n_ch, 2): the valves'
    land conductances [kg/(s Pa)] of valve_leak's clearance form, their flows from the supply
    at ``supply_pa`` (default the nominal) and to the room (effects.valve_leak.clearance_flows)."""
    m = -orifice_flow(tables.external_leak_m2, p, tables.room_pa, tables.gas)[0]
    # the laminar form (effects.external_leak.laminar_flow)
    m = m - laminar_flow(tables.external_leak_g, p, tables.room_pa, tables.room_pa)[0]
    m_ab = piston_leak_flow(p[0::2], p[1::2], tables.piston_leak_m2, tables.piston_leak_g, tables.gas,
                            tables.room_pa)[0]
    m[0::2] -= m_ab
    m[1::2] += m_ab
    if clearance is not None:
        ps = tables.supply_pa if supply_pa is None else supply_pa
        m = m + clearance_flows(clearance[:, 0], clearance[:, 1], p, ps, tables.room_pa)[0]
    return m


def integrate(p, volume, volume_rate, a_supply, a_exhaust, gas: GasCfg, supply_pa, room_pa, dt, extra_flow=None):
    """Adaptive ROS2 over one step dt for chambers with volume and volume rate held.

    All arrays (n,); returns the (n,) pressures at t + dt.  A chamber whose pressure would
    change by more than MAX_REL_CHANGE in a sub-step is redone with twice as many sub-steps.
    """
    extra_flow = np.zeros(p.size) if extra_flow is None else extra_flow

    def rhs(q, idx):
        return pressure_rate(q, volume[idx], volume_rate[idx], a_supply[idx], a_exhaust[idx], gas,
                             supply_pa, room_pa, extra_flow[idx])

    out = np.empty_like(p)
    todo = np.arange(p.size)
    for level in range(MAX_HALVINGS + 1):
        n_sub = 2 ** level
        h = dt / n_sub
        q = p[todo].copy()
        ok = np.ones(todo.size, bool)
        for _ in range(n_sub):
            q_new, err = ros2_step(q, h, lambda y: rhs(y, todo))
            ok &= np.isfinite(q_new) & (np.abs(q_new - q) <= MAX_REL_CHANGE * q) & (err <= ERR_TOL * q)
            q = q_new
        if level == MAX_HALVINGS:
            ok[:] = True
        out[todo[ok]] = q[ok]
        todo = todo[~ok]
        if todo.size == 0:
            break
    return out


def static_transient(valve_rows, volume_m3, p0_pa, command_v, duration_s, dt, gas: GasCfg,
                     supply_pa, room_pa):
    """Pressure transients of chambers at fixed volume (the calibration test of 002 eq. 10).

    Args:
      valve_rows: (n, 8) or (1, 8) valve parameters (pneumatics.valve.VALVE_COLUMNS).
      volume_m3: scalar or (n,) chamber volumes.
      p0_pa: scalar or (n,) initial pressures; command_v: (n,) constant commands.
    Returns:
      (time (T,), pressure (T, n)) with T = round(duration_s / dt) + 1.
    """
    command_v = np.asarray(command_v, float)
    n = command_v.size
    a_s, a_e = valve_areas(command_v, np.asarray(valve_rows, float))
    volume = np.broadcast_to(np.asarray(volume_m3, float), (n,)).copy()
    rate = np.zeros(n)
    steps = int(round(duration_s / dt))
    out = np.empty((steps + 1, n))
    out[0] = np.broadcast_to(np.asarray(p0_pa, float), (n,))
    for k in range(steps):
        out[k + 1] = integrate(out[k], volume, rate, a_s, a_e, gas, supply_pa, room_pa, dt)
    return np.arange(steps + 1) * dt, out
