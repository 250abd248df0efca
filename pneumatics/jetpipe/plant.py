"""The jet-pipe actuator's valve and chamber states as one ODE (paper 000 eq. 15), numpy reference.

State y (6,) = [i, z1, x_jp, dx_jp/dt, P1, P2]  (A, m, m, m/s, Pa, Pa), the paper's state vector
[i, x_jp (3 states), P1, P2] of Sec. IV-D.  Input: the current command [A], the piston position
q (chamber-1 length) [m] and speed [m/s] from MuJoCo, and the hysteresis output.

The hysteresis (rate independent, with memory) is advanced once per step from the driver current
at the start of the step and held over it (its input, the current, moves with a 0.14 ms time
constant, so a 0.1 ms step lags it by less than one step).  Every other state is integrated by
classical RK4 (:func:`rk4_step`), explicit and 4th order: at the default 0.1 ms step,
h |lambda| <= 0.71 for the stiffest pole (the driver's, 7050 rad/s) and about 0.8 for the
chamber pressures near zero flow with the smallest volume, inside RK4's stability region
(|h lambda| < 2.78 on the real axis).  tests/test_jetpipe.py checks convergence against 4x
smaller steps.  :mod:`pneumatics.jetpipe.kernel` is the same arithmetic compiled with numba.
"""
from __future__ import annotations

import numpy as np

from .chambers import pressure_rates
from .params import JetpipeCfg
from .valve import driver_rate, jet_rate, static_position, tip_force

I_CURRENT, I_Z1, I_X, I_XD, I_P1, I_P2 = range(6)
STATE_NAMES = ("current_a", "jet_filter_m", "jet_m", "jet_speed_m_s", "p1_pa", "p2_pa")


def initial_state(cfg: JetpipeCfg, p1_pa: float | None = None, p2_pa: float | None = None) -> np.ndarray:
    """(6,) state at rest: no current, jet at its static position for zero force, chambers at
    the given pressures (default: room)."""
    y = np.zeros(6)
    room = cfg.supply.room_pa
    y[I_P1] = room if p1_pa is None else p1_pa
    y[I_P2] = room if p2_pa is None else p2_pa
    return y


def rhs(y, current_cmd_a, hysteresis_force_n, piston_m, piston_speed_m_s, cfg: JetpipeCfg) -> np.ndarray:
    """dy/dt (6,).  ``hysteresis_force_n`` is the tip force after the hysteresis operator
    (pass k_m i itself for the hysteresis-free model of the paper)."""
    dy = np.empty(6)
    dy[I_CURRENT] = driver_rate(y[I_CURRENT], current_cmd_a, cfg.driver)
    x_st = static_position(hysteresis_force_n, cfg.jet)
    dy[I_Z1:I_XD + 1] = jet_rate(y[I_Z1:I_XD + 1], x_st, cfg.jet)
    x_abs = y[I_X] + cfg.jet.offset_m
    dp1, dp2 = pressure_rates(x_abs, y[I_P1], y[I_P2], piston_m, piston_speed_m_s, cfg)
    dy[I_P1], dy[I_P2] = dp1, dp2
    return dy


def rhs_no_hysteresis(y, current_cmd_a, piston_m, cfg: JetpipeCfg) -> np.ndarray:
    """dy/dt of the paper's model (hysteresis excluded), piston held still: for linearisation."""
    return rhs(y, current_cmd_a, float(tip_force(y[I_CURRENT], cfg.driver)), piston_m, 0.0, cfg)


def rk4_step(y, h, current_cmd_a, hysteresis_force_n, piston_m, piston_speed_m_s, cfg: JetpipeCfg) -> np.ndarray:
    """One classical Runge-Kutta step of size ``h`` [s]; the inputs are held over the step."""
    args = (current_cmd_a, hysteresis_force_n, piston_m, piston_speed_m_s, cfg)
    k1 = rhs(y, *args)
    k2 = rhs(y + 0.5 * h * k1, *args)
    k3 = rhs(y + 0.5 * h * k2, *args)
    k4 = rhs(y + h * k3, *args)
    return y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
