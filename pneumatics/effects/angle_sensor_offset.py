"""angle_sensor_offset: a joint encoder or potentiometer that reads the true angle plus a constant.

    q_measured = q + offset                       (additive)
    q_measured = q + offset + scale_error q       (offset_and_scale)

A mounting or zeroing error of the angle sensor, and in the second form a gain error as well
(e.g. Hollerbach, Khalil & Gautier, "Model identification", Springer Handbook of Robotics,
2008, §6.2: joint offsets and joint gain errors in kinematic calibration).  The second form is
also the closest law the doctor fits to an encoder disc's eccentricity, e sin(q + phi) (a
once-per-turn error; Heidenhain, Angle Encoders, accuracy chapter): over a joint's travel of
+-70 deg it is, to first order in q, an offset e sin(phi) and a gain e cos(phi).  The simulator
applies it to what the sensors report.  The doctor's torque balance evaluates gravity and
inertia at the measured angle, so the equation error carries -(d tau_inv / d q) (offset +
scale_error q) to first order (``TorqueData.dtau_dq``).
"""
from __future__ import annotations

from dataclasses import dataclass

from .family import Family, param


@dataclass(frozen=True)
class Additive:
    """A constant zero offset."""

    offset_rad: float = param(0.0, "reading minus true angle", "rad", -1.0, 1.0)


@dataclass(frozen=True)
class OffsetAndScale:
    """A zero offset and a gain error (a two-point calibration's two errors)."""

    offset_rad: float = param(0.0, "reading minus true angle at the zero", "rad", -1.0, 1.0)
    scale_error: float = param(0.0, "reading's gain minus 1: the reading grows by (1 + scale_error) per unit angle",
                               "-", -0.2, 0.2)


def reading_error(q, offset_rad, scale_error=0.0):
    """What the sensor adds to the true angle ``q`` [rad]: offset + scale_error q."""
    return offset_rad + scale_error * q


def true_angle(q_measured, offset_rad, scale_error=0.0):
    """The angle [rad] a sensor with these errors reads as ``q_measured`` (the law inverted)."""
    return (q_measured - offset_rad) / (1.0 + scale_error)


class AngleSensorOffset(Family):
    name = "angle_sensor_offset"
    place_kind = "joint"
    forms = {"additive": Additive, "offset_and_scale": OffsetAndScale}
    physics = "q_measured = q + offset (+ scale_error q)"
    sources = "Hollerbach, Khalil & Gautier 2008, §6.2"
    simulator = "added to the observed angles (and their rates scaled)"
    doctor = "torque_balance"

    def effect_set_entry(self, params):
        out = {"angle_offset_rad": params.offset_rad}
        if isinstance(params, OffsetAndScale):
            out["angle_scale_error"] = params.scale_error
        return out

    def torque_balance_term(self, exp, td, joint, params):
        # tau_inv(q + e(q)) - tau_inv(q) = dtau_dq e(q), on the tau_inv side: minus in the
        # error; e at the measured angle (the difference is second order in the errors).  A
        # gain error reads the rates differentiated from the angles (1 + g) times too
        scale = getattr(params, "scale_error", 0.0)
        if not scale:
            return -td.dtau_dq[:, :, joint] * params.offset_rad
        error = reading_error(exp.q_s[:, joint], params.offset_rad, scale)
        return -(td.dtau_dq[:, :, joint] * error[:, None] + td.dtau_drate[:, :, joint] * scale)

    def draw(self, rng):
        return Additive(rng.choice([-1, 1]) * rng.uniform(0.03, 0.06))
