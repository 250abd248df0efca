"""angle_sensor_offset: a joint encoder or potentiometer that reads the true angle plus a constant.

    q_measured = q + offset

A mounting or zeroing error of the angle sensor (e.g. Hollerbach, Khalil & Gautier, "Model
identification", Springer Handbook of Robotics, 2008, §6.2: joint offsets in kinematic
calibration).  The simulator adds it to what the sensors report.  The doctor's torque balance
evaluates gravity and inertia at the measured angle, so the equation error carries
-(d tau_inv / d q) offset to first order (``TorqueData.dtau_dq``).
"""
from __future__ import annotations

from dataclasses import dataclass

from .family import Family, param


@dataclass(frozen=True)
class Additive:
    """A constant zero offset."""

    offset_rad: float = param(0.0, "reading minus true angle", "rad", -1.0, 1.0)


class AngleSensorOffset(Family):
    name = "angle_sensor_offset"
    place_kind = "joint"
    forms = {"additive": Additive}
    physics = "q_measured = q + offset"
    sources = "Hollerbach, Khalil & Gautier 2008, §6.2"
    simulator = "added to the observed angles"
    doctor = "torque_balance"

    def effect_set_entry(self, params):
        return {"angle_offset_rad": params.offset_rad}

    def torque_balance_term(self, exp, td, joint, params):
        # tau_inv(q + offset) - tau_inv(q) = dtau_dq offset, on the tau_inv side: minus in the error
        return -td.dtau_dq[:, :, joint] * params.offset_rad

    def draw(self, rng):
        return Additive(rng.choice([-1, 1]) * rng.uniform(0.03, 0.06))
