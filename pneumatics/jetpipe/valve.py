"""The electrical and mechanical part of the jet-pipe valve (paper 000 Sec. II-B, III-A).

    current driver   di/dt = w_d (clip(i_cmd, +-i_max) - i),  w_d = 2 pi 1122 Hz      (Sec. II-B)
    tip force        F_jp = k_m i,  k_m = 1.946 N/A                                    (eq. 1)
    hysteresis       F_h = H(F_jp)   (hysteresis.py; the paper excludes it from its model)
    static position  x_st = f3(F_h) = x_sat tanh(F_h / F_sat)                          (eq. 2)
    dynamics         X(s)/X_st(s) = w1/(s + w1) * w2^2/(s^2 + 2 zeta w2 s + w2^2)      (eq. 3)
    offset           x_abs = x_jp + x_offset                                           (eq. 4)

f3 is the midpoint line of the paper's position/force loop (Fig. 6b), which is not legible in
our copy: tanh has the measured shape (linear about the centre, saturating at the 1 mm range);
models/jetpipe/README.md derives x_sat and F_sat.  Eq. 3 is realised as the state space
z = (z1, x, xdot): z1' = w1 (x_st - z1), x'' = w2^2 (z1 - x) - 2 zeta w2 x'.
"""
from __future__ import annotations

import math

import numpy as np

from .params import DriverCfg, JetCfg


def driver_omega(cfg: DriverCfg) -> float:
    """Corner of the current driver [rad/s] (Table II: pole at -7049.7 rad/s)."""
    return 2.0 * math.pi * cfg.corner_hz


def driver_rate(current_a, command_a, cfg: DriverCfg):
    """di/dt [A/s] of the first-order driver; the command saturates at the rated current."""
    cmd = np.clip(command_a, -cfg.current_limit_a, cfg.current_limit_a)
    return driver_omega(cfg) * (cmd - current_a)


def tip_force(current_a, cfg: DriverCfg):
    """F_jp = k_m i [N] (eq. 1)."""
    return cfg.force_constant_n_per_a * np.asarray(current_a, float)


def static_position(force_n, cfg: JetCfg):
    """x_st = f3(F) [m], the static jet position for tip force ``force_n`` [N] (eq. 2)."""
    return cfg.saturation_m * np.tanh(np.asarray(force_n, float) / cfg.saturation_force_n)


def static_force(position_m, cfg: JetCfg):
    """f3^-1: tip force [N] that holds the jet statically at ``position_m`` (|x| < x_sat)."""
    return cfg.saturation_force_n * np.arctanh(np.asarray(position_m, float) / cfg.saturation_m)


def jet_matrices(cfg: JetCfg):
    """(A (3, 3), B (3,)) of z' = A z + B x_st for eq. 3; the position is z[1], unit DC gain."""
    w1, w2, zeta = cfg.omega1_rad_s, cfg.omega2_rad_s, cfg.damping_ratio
    a = np.array([[-w1, 0.0, 0.0], [0.0, 0.0, 1.0], [w2 * w2, -w2 * w2, -2.0 * zeta * w2]])
    b = np.array([w1, 0.0, 0.0])
    return a, b


def jet_rate(z, x_static_m, cfg: JetCfg):
    """dz/dt (3,) of the jet-pipe dynamics (eq. 3) for state ``z`` (3,) and input x_st [m]."""
    a, b = jet_matrices(cfg)
    return a @ np.asarray(z, float) + b * x_static_m
