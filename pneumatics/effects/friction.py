"""Joint friction: Coulomb, Stribeck (stiction) and viscous (Armstrong-Helouvry, Dupont and
Canudas de Wit, Automatica 30, 1994), as a torque opposing the joint velocity qd [rad/s]::

    tau_f = -( F_c s + (F_s - F_c) exp(-(qd/v_s)^2) s + b qd + b_n |qd|^n sign(qd) ),
    s = tanh(qd / v_eps)

The tanh replaces sign(qd) with a continuous law (v_eps = 0.01 rad/s), which any integrator
and any least-squares fit can handle; LuGre or other stick-slip friction of a real joint
projects onto these terms.  The last term is viscous friction growing as a power n of the speed
(a lubricated contact between boundary and full-film regimes, Andersson, Soderberg & Bjorklund,
Tribology International 40:580, 2007: n < 1 shear-thinning, n > 1 a film thickening with speed);
below v_eps it is continued linearly, so its slope stays finite at rest when n < 1.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .family import Family, joint_column, param

SMOOTH_RAD_S = 0.01


def coulomb_shape(qd, smooth_rad_s: float = SMOOTH_RAD_S):
    return np.tanh(np.asarray(qd) / smooth_rad_s)


def stribeck_shape(qd, stribeck_rad_s: float = 0.1, smooth_rad_s: float = SMOOTH_RAD_S):
    qd = np.asarray(qd)
    return np.exp(-(qd / stribeck_rad_s) ** 2) * np.tanh(qd / smooth_rad_s)


def velocity_power_shape(qd, exponent, linear_below_rad_s: float = SMOOTH_RAD_S):
    """|qd|^n sign(qd), continued linearly (qd v_0^(n-1)) below v_0 = ``linear_below_rad_s``;
    ``exponent`` n broadcasts against qd [rad/s]."""
    qd = np.asarray(qd, float)
    speed = np.maximum(np.abs(qd), linear_below_rad_s)
    return qd * speed ** (np.asarray(exponent, float) - 1.0)


def friction_torque(qd, coulomb_nm=0.0, stiction_extra_nm=0.0, stribeck_rad_s=0.1, viscous_nm_s=0.0,
                    power_viscous_nm=0.0, viscous_exponent=1.0):
    """Friction torque [N m] on a joint moving at qd [rad/s] (opposes the motion); the power
    term b_n |qd|^n sign(qd) has b_n = ``power_viscous_nm`` [N m (s/rad)^n], n = ``viscous_exponent``."""
    return -(coulomb_nm * coulomb_shape(qd) + stiction_extra_nm * stribeck_shape(qd, stribeck_rad_s)
             + viscous_nm_s * np.asarray(qd) + power_viscous_nm * velocity_power_shape(qd, viscous_exponent))


# -- the three families of this law ------------------------------------------------------------
# coulomb_friction, stiction and viscous_friction are terms of one Stribeck curve (Armstrong-
# Helouvry et al. 1994): one module, three families, since the doctor tells them apart (a pure
# Coulomb level, a breakaway excess at low speed, a torque growing with speed) while the
# simulator adds them into one torque per joint (EffectSet.friction).


@dataclass(frozen=True)
class CoulombParams:
    """Coulomb friction of a joint."""

    coulomb_nm: float = param(0.0, "Coulomb level F_c, opposing the motion", "N m", 0.0, 50.0)


@dataclass(frozen=True)
class StribeckParams:
    """Stiction as Stribeck friction: a Coulomb level plus a breakaway excess at low speed."""

    coulomb_nm: float = param(0.0, "Coulomb level F_c", "N m", 0.0, 50.0)
    breakaway_extra_nm: float = param(0.0, "breakaway excess F_s - F_c at zero speed", "N m", 0.0, 50.0)
    stribeck_rad_s: float = param(0.1, "Stribeck velocity v_s over which the excess fades", "rad/s", 1e-3, 10.0,
                                  magnitude=False)


@dataclass(frozen=True)
class ViscousParams:
    """Viscous friction of a joint."""

    viscous_nm_s_per_rad: float = param(0.0, "viscous coefficient b", "N m s/rad", 0.0, 100.0)


@dataclass(frozen=True)
class VelocityPowerParams:
    """Viscous friction growing as a power of the speed, b_n |qd|^n against the motion."""

    power_coefficient_nm: float = param(0.0, "coefficient b_n: the torque at 1 rad/s", "N m (s/rad)^n", 0.0, 100.0)
    exponent: float = param(1.0, "exponent n of the speed", "-", 0.1, 3.0, magnitude=False)


class _JointFriction(Family):
    place_kind = "joint"
    sources = "Armstrong-Helouvry, Dupont & Canudas de Wit, Automatica 30 (1994)"
    simulator = "torque into data.qfrc_applied every physics step (kernel)"
    doctor = "torque_balance"

    def torque(self, qd, params) -> np.ndarray:
        """The friction torque [N m] at joint velocities qd [rad/s] (opposes the motion)."""
        raise NotImplementedError

    def add_to(self, effects, place: str, params) -> None:
        """Friction terms at one joint add up (a Coulomb and a Stribeck friction found apart are
        one friction curve); the Stribeck velocity and the viscous exponent are shapes, set
        rather than added."""
        fr = effects.friction.setdefault(place, {})
        for k, x in self.effect_set_entry(params)["friction"].items():
            if k in ("stribeck_rad_s", "viscous_exponent"):
                fr[k] = x
            elif x:
                fr[k] = fr.get(k, 0.0) + x

    def torque_balance_term(self, exp, td, joint: int, params) -> np.ndarray:
        # tau_act + tau_friction = tau_inv, so the equation error carries -tau_friction
        qd = exp.qd[:, joint]
        return joint_column(qd.size, exp.qd.shape[1], joint, -self.torque(qd, params))


class CoulombFriction(_JointFriction):
    name = "coulomb_friction"
    plants = ("valve_arm", "bench_cylinder")  # the bench's rod seal: seal_friction.py
    forms = {"coulomb": CoulombParams}
    physics = "F_c tanh(qd / v_eps) against the motion"

    def torque(self, qd, params):
        return friction_torque(qd, coulomb_nm=params.coulomb_nm)

    def effect_set_entry(self, params):
        return {"friction": {"coulomb_nm": params.coulomb_nm}}

    def draw(self, rng):
        return CoulombParams(rng.uniform(0.04, 0.10))


class Stiction(_JointFriction):
    name = "stiction"
    forms = {"stribeck": StribeckParams}
    physics = "(F_c + (F_s - F_c) exp(-(qd/v_s)^2)) tanh(qd / v_eps) against the motion"

    def torque(self, qd, params):
        return friction_torque(qd, coulomb_nm=params.coulomb_nm, stiction_extra_nm=params.breakaway_extra_nm,
                               stribeck_rad_s=params.stribeck_rad_s)

    def effect_set_entry(self, params):
        return {"friction": {"coulomb_nm": params.coulomb_nm, "stiction_extra_nm": params.breakaway_extra_nm,
                             "stribeck_rad_s": params.stribeck_rad_s}}

    def draw(self, rng):
        return StribeckParams(rng.uniform(0.02, 0.04), rng.uniform(0.06, 0.12), rng.uniform(0.05, 0.15))


class ViscousFriction(_JointFriction):
    name = "viscous_friction"
    plants = ("valve_arm", "bench_cylinder")
    forms = {"linear": ViscousParams, "velocity_power": VelocityPowerParams}
    sources = ("Armstrong-Helouvry, Dupont & Canudas de Wit, Automatica 30 (1994); velocity_power: Andersson, "
               "Soderberg & Bjorklund, Tribology International 40 (2007)")
    physics = "b qd, or b_n sign(qd) abs(qd)^n, against the motion"

    def torque(self, qd, params):
        if isinstance(params, VelocityPowerParams):
            return friction_torque(qd, power_viscous_nm=params.power_coefficient_nm, viscous_exponent=params.exponent)
        return friction_torque(qd, viscous_nm_s=params.viscous_nm_s_per_rad)

    def effect_set_entry(self, params):
        if isinstance(params, VelocityPowerParams):
            return {"friction": {"power_viscous_nm": params.power_coefficient_nm, "viscous_exponent": params.exponent}}
        return {"friction": {"viscous_nm_s": params.viscous_nm_s_per_rad}}

    def draw(self, rng):
        return ViscousParams(rng.uniform(0.06, 0.15))
