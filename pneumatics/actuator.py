"""Double-acting actuators: geometry of the two chambers and the force they make.

A *linear* cylinder (bore, rod, stroke) acts through a MuJoCo joint transmission with a
constant moment arm (``gear`` = r, so actuator length = r q) or through a tendon/site
transmission whose length, and so moment arm, MuJoCo computes from the joint angles.
A *rotary* vane actuator (displacement D [m^3/rad]) acts through a joint transmission with
gear 1.  Either way the piston (vane) position is ``x = L - L_zero`` along the actuator's
length L, chamber ``a`` grows with x and pushes L (and so the joint) positive::

    V_a = V_dead,a + A_a x,          V_b = V_dead,b + A_b (stroke - x)
    F   = A_a p_a - A_b p_b - (A_a - A_b) p_room          (DESIGN.md step 3; rod side vented)

(A in m^2 and F in N for a cylinder; D in m^3/rad and F in N m for a vane.)
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .config import spec
from .errors import ConfigError
from .valve import ValveCfg

KINDS = ("linear", "rotary")


@dataclass(frozen=True, kw_only=True)
class ActuatorCfg:
    """One double-acting cylinder or vane actuator, named after the joint it drives."""

    name: str = spec(doc="actuator name; must match a <general>/<motor> actuator in the MJCF")
    kind: str = spec("linear", "'linear' (cylinder) or 'rotary' (vane)")
    bore_m: float = spec(None, "piston diameter (linear)", "m", 1e-3, 0.5)
    rod_m: float = spec(0.0, "rod diameter on the b side (linear)", "m", 0.0, 0.5)
    stroke_m: float = spec(None, "full piston travel (linear)", "m", 1e-3, 2.0)
    displacement_m3_per_rad: float = spec(None, "vane displacement D (rotary)", "m^3/rad", 1e-9, 1e-2)
    travel_rad: float = spec(None, "full vane travel (rotary)", "rad", 1e-2, 2 * math.pi)
    dead_volume_a_m3: float = spec(doc="chamber a volume at x = 0 (ports, lines)", unit="m^3", lo=1e-8, hi=1e-2)
    dead_volume_b_m3: float = spec(doc="chamber b volume at x = stroke", unit="m^3", lo=1e-8, hi=1e-2)
    position_at_zero: float = spec(None, "piston (m) or vane (rad) position at the model's qpos0; default mid-stroke", "m or rad", 0.0, 2 * math.pi)
    valve_a: ValveCfg = spec(None, "valve of chamber a (fields default to the [valve] table)")
    valve_b: ValveCfg = spec(None, "valve of chamber b (fields default to the [valve] table)")

    def __post_init__(self):
        where = f"actuator {self.name!r}"
        if self.kind not in KINDS:
            raise ConfigError(f"{where}.kind: expected one of {KINDS}, got {self.kind!r}")
        if self.kind == "linear":
            for key in ("bore_m", "stroke_m"):
                if getattr(self, key) is None:
                    raise ConfigError(f"{where}: missing field {key!r} (m) for a linear cylinder")
            if self.rod_m >= self.bore_m:
                raise ConfigError(f"{where}.rod_m = {self.rod_m:g} m must be smaller than bore_m = {self.bore_m:g} m")
        else:
            for key in ("displacement_m3_per_rad", "travel_rad"):
                if getattr(self, key) is None:
                    raise ConfigError(f"{where}: missing field {key!r} for a rotary actuator")
        if self.position_at_zero is not None and not 0.0 <= self.position_at_zero <= self.stroke:
            raise ConfigError(f"{where}.position_at_zero = {self.position_at_zero:g} is outside the stroke [0, {self.stroke:g}]")

    @property
    def area_a(self) -> float:
        """Effective area of chamber a [m^2] (or displacement [m^3/rad] for a vane)."""
        if self.kind == "rotary":
            return self.displacement_m3_per_rad
        return math.pi * self.bore_m ** 2 / 4.0

    @property
    def area_b(self) -> float:
        """Effective area of chamber b (annulus: bore minus rod) [m^2] or [m^3/rad]."""
        if self.kind == "rotary":
            return self.displacement_m3_per_rad
        return math.pi * (self.bore_m ** 2 - self.rod_m ** 2) / 4.0

    @property
    def stroke(self) -> float:
        """Full travel [m] (or [rad])."""
        return self.travel_rad if self.kind == "rotary" else self.stroke_m

    @property
    def zero_position(self) -> float:
        return self.stroke / 2.0 if self.position_at_zero is None else self.position_at_zero

    def volumes(self, x):
        """(V_a, V_b) [m^3] at piston position x [m or rad] (clipped to the stroke)."""
        x = min(max(x, 0.0), self.stroke)
        return (self.dead_volume_a_m3 + self.area_a * x,
                self.dead_volume_b_m3 + self.area_b * (self.stroke - x))

    def force(self, p_a, p_b, room_pa):
        """Actuator force [N] (or torque [N m]) from chamber pressures [Pa abs]."""
        return self.area_a * p_a - self.area_b * p_b - (self.area_a - self.area_b) * room_pa
