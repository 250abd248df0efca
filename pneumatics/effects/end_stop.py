"""end_stop: a bumper inside the model's joint range.

Past the stop the joint meets a stiff, damped pad: a one-sided spring-damper (Hunt & Crossley,
"Coefficient of restitution interpreted as damping in vibroimpact", ASME J. Appl. Mech. 42,
1975, without the power law)::

    tau_stop = -(k (q - q_stop) + b qd)   past q_stop (on its side), 0 before it

Two forms, one per side of the round trip:

* ``soft_limit`` — the simulator's: the stop ``intrusion_rad`` inside the model's joint limit
  on the ``upper`` or ``lower`` side, made MuJoCo's own soft joint limit with a time constant of
  END_STOP_TIMECONST_S (a spring-damper whose k and b MuJoCo sets from the joint's inertia);
* ``spring_damper`` — the doctor's: the stop angle, stiffness and damping of the law above,
  fitted by the torque balance (k and b linear, the angle on a grid).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .family import Family, NotOnThisSide, joint_column, param

END_STOP_TIMECONST_S = 0.005
"""MuJoCo solref time constant of an end-stop bumper [s]: a stiff rubber pad, critically damped
(about 0.01 rad of give under full pressure on arm2; MuJoCo asks for at least 2 timesteps)."""
#: the hand-moved references keep 5 deg inside the joint limits (controllers/reference.py): an
#: end stop scaled down moves out towards this margin, beyond which the arm never goes
REFERENCE_MARGIN_RAD = float(np.radians(5.0))
SIDES = ("upper", "lower")


def penetration(q, stop, side):
    """How far q is past an end stop at ``stop`` [rad] on ``side`` (+1 upper, -1 lower); 0 before it."""
    return np.maximum(q - stop, 0.0) if side > 0 else np.minimum(q - stop, 0.0)


def stop_torque(q, qd, stop_rad, side, stiffness_nm_per_rad, damping_nm_s_per_rad):
    """tau_stop [N m] of the bumper at angles q [rad] and velocities qd [rad/s]."""
    pen = penetration(q, stop_rad, side)
    return -np.where(pen != 0, stiffness_nm_per_rad * pen + damping_nm_s_per_rad * qd, 0.0)


@dataclass(frozen=True)
class SoftLimit:
    """The simulator's bumper: MuJoCo's soft joint limit moved inside the model's."""

    side: str = param("upper", "which limit the bumper sits at: 'upper' or 'lower'", "-", magnitude=False)
    intrusion_rad: float = param(0.0, "how far inside the model's joint limit the bumper stops the joint",
                                 "rad", 0.0, 3.2)

    def __post_init__(self):
        if self.side not in SIDES:
            raise ConfigError(f"effect end_stop (soft_limit).side: expected one of {', '.join(SIDES)}, got {self.side!r}")


@dataclass(frozen=True)
class SpringDamper:
    """The doctor's bumper: a one-sided spring-damper past a stop angle."""

    stop_rad: float = param(0.0, "joint angle where the bumper begins", "rad", -10.0, 10.0, magnitude=False)
    side_sign: float = param(1.0, "+1: the stop limits from above, -1: from below", "-", -1.0, 1.0, magnitude=False)
    stiffness_nm_per_rad: float = param(0.0, "bumper stiffness k", "N m/rad", 0.0, 1e7)
    damping_nm_s_per_rad: float = param(0.0, "bumper damping b while in contact", "N m s/rad", 0.0, 1e5)


class EndStop(Family):
    name = "end_stop"
    place_kind = "joint"
    forms = {"soft_limit": SoftLimit, "spring_damper": SpringDamper}
    physics = "one-sided spring-damper -(k (q - q_stop) + b qd) past a stop inside the joint range"
    sources = "Hunt & Crossley 1975; MuJoCo soft constraints (solref)"
    simulator = "MuJoCo soft joint limit narrowed by the intrusion (EffectSet.apply_end_stops)"
    doctor = "torque_balance"
    benchmark_ok = False  # a bumper the arm touches cannot be concealed (scenarios/_cases.py)

    def effect_set_entry(self, params):
        if not isinstance(params, SoftLimit):
            raise NotOnThisSide(f"{self.name}: the simulator takes the soft_limit form (side, intrusion_rad), "
                                f"got {type(params).__name__}")
        return {"end_stop": {f"{params.side}_intrusion_rad": params.intrusion_rad}}

    def stop_angle(self, robot, joint: str, params: SoftLimit) -> tuple[float, float]:
        """(stop angle [rad], side sign) of a soft_limit bumper on ``robot``'s joint."""
        lo, hi = robot.model.jnt_range[robot.model.joint(joint).id]
        if params.side == "upper":
            return float(hi - params.intrusion_rad), 1.0
        return float(lo + params.intrusion_rad), -1.0

    def torque_balance_term(self, exp, td, joint, params):
        if not isinstance(params, SpringDamper):
            raise NotOnThisSide(f"{self.name}: the torque balance takes the spring_damper form (stop_rad, side_sign, "
                                f"stiffness_nm_per_rad, damping_nm_s_per_rad), got {type(params).__name__}")
        units = self.torque_balance_units(exp, td, joint, np.array([params.stop_rad]), params.side_sign)[:, 0]
        tau = units @ np.array([params.stiffness_nm_per_rad, params.damping_nm_s_per_rad])
        return joint_column(tau.size, exp.qd.shape[1], joint, tau)

    def torque_balance_units(self, exp, td, joint, stops, side_sign) -> np.ndarray:
        """(N, S, 2) the equation-error terms per unit stiffness and per unit damping of
        bumpers at each of ``stops`` [rad] on side ``side_sign``, at ``joint``: the doctor
        places a stop on a grid of them, smoothed in one pass."""
        # the bumper's torque is sharp in the angle: evaluated on the barely smoothed angle and
        # smoothed as the equation error is (Experiment.like_q_s), not on the smoothed angle
        q, qd = exp.q_light[:, joint, None], exp.qd_light[:, joint, None]
        stops = np.asarray(stops, float)[None, :]
        tau = np.stack([stop_torque(q, qd, stops, side_sign, 1.0, 0.0), stop_torque(q, qd, stops, side_sign, 0.0, 1.0)],
                       axis=2)
        if td is not None and td.joint_ok is not None:
            # where the torque balance leaves the joint out (near the model's own limit, whose
            # force MuJoCo's inverse dynamics holds) a bumper cannot be judged: its torque
            # there, filtered, would fit the limit impact's spread into the samples kept
            tau = np.where(td.joint_ok[:, joint, None, None], tau, 0.0)
        return -exp.like_q_s(tau.reshape(q.size, -1), joint).reshape(tau.shape)

    def scaled(self, params, k):
        """The bumper moved out towards the reference margin by k (halving the intrusion itself
        would hide the stop altogether)."""
        if isinstance(params, SoftLimit):
            return SoftLimit(params.side, REFERENCE_MARGIN_RAD + (params.intrusion_rad - REFERENCE_MARGIN_RAD) * k)
        return super().scaled(params, k)

    def draw(self, rng):
        # a bumper 9-13 deg inside the model's joint limit, on one side
        side = "upper" if rng.random() < 0.5 else "lower"
        return SoftLimit(side, rng.uniform(0.15, 0.22))
