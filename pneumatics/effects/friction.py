"""Joint friction: Coulomb, Stribeck (stiction) and viscous (Armstrong-Helouvry, Dupont and
Canudas de Wit, Automatica 30, 1994), as a torque opposing the joint velocity qd [rad/s]::

    tau_f = -( F_c s + (F_s - F_c) exp(-(qd/v_s)^2) s + b qd ),   s = tanh(qd / v_eps)

The tanh replaces sign(qd) with a continuous law (v_eps = 0.01 rad/s), which any integrator
and any least-squares fit can handle; LuGre or other stick-slip friction of a real joint
projects onto these terms.
"""
from __future__ import annotations

import numpy as np

SMOOTH_RAD_S = 0.01


def coulomb_shape(qd, smooth_rad_s: float = SMOOTH_RAD_S):
    return np.tanh(np.asarray(qd) / smooth_rad_s)


def stribeck_shape(qd, stribeck_rad_s: float = 0.1, smooth_rad_s: float = SMOOTH_RAD_S):
    qd = np.asarray(qd)
    return np.exp(-(qd / stribeck_rad_s) ** 2) * np.tanh(qd / smooth_rad_s)


def friction_torque(qd, coulomb_nm=0.0, stiction_extra_nm=0.0, stribeck_rad_s=0.1, viscous_nm_s=0.0):
    """Friction torque [N m] on a joint moving at qd [rad/s] (opposes the motion)."""
    return -(coulomb_nm * coulomb_shape(qd) + stiction_extra_nm * stribeck_shape(qd, stribeck_rad_s)
             + viscous_nm_s * np.asarray(qd))
