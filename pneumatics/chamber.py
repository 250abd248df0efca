"""Chamber pressure dynamics and the integration step (numpy reference implementation).

Pressure ODE, paper 002 eq. 9 (paper 000 eq. 12), with a polytropic exponent n in [1, k]::

    dp/dt = n / V * (R T mdot - p dV/dt),     mdot = mdot_supply(p) - mdot_exhaust(p)

Integration over one physics step h (1 ms) uses the two-stage, second-order, L-stable
Rosenbrock method ROS2 (Verwer et al., SIAM J. Sci. Comput. 20, 1999), gamma = 1 + 1/sqrt 2,
with the exact scalar Jacobian J = dp'/dp of each chamber::

    (1 - gamma h J) k1 = f(p)
    (1 - gamma h J) k2 = f(p + h k1) - 2 k1
    p+ = p + 3/2 h k1 + 1/2 h k2

Explicit Euler is unstable at 1 ms for the smallest dead volumes (|J h| > 2 near the
zero-flow point), while ROS2 is stable for any stiffness.  Volume and volume rate are taken at
the step's midpoint and held over it.  A chamber whose pressure would change by more than a
quarter in one step (a violent expansion of a small volume) is re-integrated with 2, 4, ..
64 equal sub-steps, so pressures stay positive without clamping.

This module is the readable reference; :mod:`pneumatics.kernel` is the compiled fast path
with the same arithmetic, tested against it to round-off.
"""
from __future__ import annotations

import numpy as np

from .medium import GasCfg, orifice_flow
from .tables import FluidTables, valve_areas_table

GAMMA = 1.0 + 1.0 / np.sqrt(2.0)
MAX_HALVINGS = 6
MAX_REL_CHANGE = 0.25


def pressure_rate(p, volume, volume_rate, a_supply, a_exhaust, gas: GasCfg, supply_pa, room_pa):
    """dp/dt [Pa/s] and its derivative d(dp/dt)/dp [1/s] for chambers (all arrays (n,))."""
    m_s, _, dms_dp = orifice_flow(a_supply, supply_pa, p, gas)
    m_e, dme_dp, _ = orifice_flow(a_exhaust, p, room_pa, gas)
    rt = gas.gas_constant_j_per_kg_k * gas.temperature_k
    n = gas.polytropic_exponent
    rate = n / volume * (rt * (m_s - m_e) - p * volume_rate)
    jac = n / volume * (rt * (dms_dp - dme_dp) - volume_rate)
    return rate, jac


def ros2_step(p, h, rhs):
    """One ROS2 step of size h for the scalar ODEs p' = rhs(p) -> (rate, jac)."""
    f0, jac = rhs(p)
    denom = 1.0 - GAMMA * h * jac
    k1 = f0 / denom
    f1, _ = rhs(p + h * k1)
    k2 = (f1 - 2.0 * k1) / denom
    return p + 1.5 * h * k1 + 0.5 * h * k2


def chamber_geometry(tables: FluidTables, length, velocity, dt):
    """Midpoint volume [m^3] and volume rate [m^3/s] of every chamber, each (n_ch,)."""
    act = tables.actuator_of_chamber
    x = length[act] - tables.length_zero[act]
    xdot = velocity[act]
    stroke = tables.stroke[act]
    x_mid = np.clip(x + 0.5 * dt * xdot, 0.0, stroke)
    travel = np.where(tables.is_a, x_mid, stroke - x_mid)
    volume = tables.dead_volume + tables.area * travel
    at_stop = ((x_mid <= 0.0) & (xdot < 0)) | ((x_mid >= stroke) & (xdot > 0))
    volume_rate = np.where(at_stop, 0.0, np.where(tables.is_a, 1.0, -1.0) * tables.area * xdot)
    return volume, volume_rate


def actuator_force(tables: FluidTables, p):
    """Force [N] (torque [N m] for vanes) of every actuator, (n_act,), from pressures (n_ch,)."""
    p_a, p_b = p[0::2], p[1::2]
    return tables.area_a * p_a - tables.area_b * p_b - (tables.area_a - tables.area_b) * tables.room_pa


def fluid_step(tables: FluidTables, p, command_v, length, velocity, dt):
    """Advance chamber pressures by one step.

    Args:
      tables: the model's fluid tables.
      p: (n_ch,) pressures [Pa abs] at t, chambers ordered a0, b0, a1, b1, ...
      command_v: (n_ch,) valve commands [V], already clipped to the valve range.
      length, velocity: (n_act,) MuJoCo actuator length [m or rad] and velocity at t.
      dt: step [s].
    Returns:
      (n_ch,) pressures at t + dt.
    """
    volume, volume_rate = chamber_geometry(tables, length, velocity, dt)
    a_s, a_e = valve_areas_table(tables, command_v)
    gas = tables.gas

    def rhs(q, idx):
        return pressure_rate(q, volume[idx], volume_rate[idx], a_s[idx], a_e[idx], gas,
                             tables.supply_pa, tables.room_pa)

    out = np.empty_like(p)
    todo = np.arange(p.size)
    for level in range(MAX_HALVINGS + 1):
        n_sub = 2 ** level
        h = dt / n_sub
        q = p[todo].copy()
        ok = np.ones(todo.size, bool)
        for _ in range(n_sub):
            q_new = ros2_step(q, h, lambda y: rhs(y, todo))
            ok &= np.isfinite(q_new) & (np.abs(q_new - q) <= MAX_REL_CHANGE * q)
            q = q_new
        if level == MAX_HALVINGS:
            ok[:] = True
        out[todo[ok]] = q[ok]
        todo = todo[~ok]
        if todo.size == 0:
            break
    return out
