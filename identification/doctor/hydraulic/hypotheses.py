"""The hydraulic doctor's hypotheses and rules: the calibrated nominal parameters, the effect
families of pneumatics/hydraulics/effects.py at their places, and the keep thresholds."""
from __future__ import annotations

import dataclasses

from pneumatics.errors import UnknownNameError

KEEP = 0.05
"""Held-out reduction of J an effect must bring to be named.  Set from null recordings: on 20
simulated null cases of the benchmark's plan (base seeds 3000 and 503751560, extra nulls 9100-9111)
the best hypothesis of the first round cut J by at most 1.0 %; the earlier 20 % left silent
effects that cut it by 17 % (a vane leak of 5e-14 m^3/(Pa s), an 18 kPa transducer offset).
Those nulls had free recordings only; on 15 nulls with braced recordings beside the free ones
(the benchmark's plan since braced recordings) no hypothesis bought more than 0.1 %."""
MIN_DJ = 0.25        # ... and this many noise variances (J: noise variances summed over channels; nulls <= 0.07)
UNEXPLAINED_SHARE = 0.20  # a flexible model (13-15 regressors) must cut this share of J to report `unexplained`
UNEXPLAINED_DJ = 1.0      # ... and at least this many noise variances
MIN_T = 4.0          # |value| / stderr an effect's parameter must reach
ALIKE = 0.90         # an alternative buying this share of the best one's improvement: not separable
CAL_BOUND = 0.5      # calibration: relative deviation allowed
DIFF_STEP = 1e-3     # finite-difference step in the scaled parameters
FIT_SECONDS = 6.0    # fits use at most this much of the fitted part (its start): the doctor's time
BRACED_FIT_SECONDS = 3.0  # ... and this much of the braced recordings among them
ROUNDS = 3           # greedy rounds at most

#: calibrated nominal parameters: (name, side) -- each a relative deviation, 0 = nominal.
#: oil side: the valve's flow gain (port width, paper 001 §3.2.1 "measured directly") and the
#: oil's effective bulk modulus; mechanical side: the load's inertia and weight moment m g r
#: (whatever the forearm carries).  The leak coefficients, friction and shaft stiffness are not
#: calibrated: each is exactly the parameter a family tests.  The bulk modulus is an *effective*
#: one for replays from a noisy angle: the oil spring beta D_v / V multiplies the smoothed
#: angle's error (errors in variables attenuate the fitted gain), and it came out at -47 % on a
#: simulated recording with no hidden effect and the model's 0.3 mrad encoder noise (the
#: held-out J falling from 5.26 to 4.43 with it).  Calibrating it keeps that
#: attenuation out of the families that soften one chamber's spring (line_dynamics).
CALIBRATION = [("valve_flow_gain", "oil"), ("bulk_modulus", "oil"), ("load_inertia", "mech"), ("load_weight", "mech")]
OIL_CAL = [k for k, (_, side) in enumerate(CALIBRATION) if side == "oil"]
MECH_CAL = [k for k, (_, side) in enumerate(CALIBRATION) if side == "mech"]


@dataclasses.dataclass(frozen=True)
class Hypothesis:
    effect: str
    where: dict
    field: str          # HydraulicEffects field
    unit: float         # one scaled parameter unit in SI
    lower: float        # bounds in SI
    upper: float
    side: str           # "oil" (needs the replay), "mech" (equation errors only) or "both"
    regime: str         # where the physics says it should show
    needs_torque: bool = False
    braced_side: str | None = None  # the side when braced recordings are given, if another

    @property
    def name(self) -> str:
        return self.effect + "".join(f"[{v}]" for v in self.where.values())


ACT = {"actuator": "elbow"}
JOINT = {"joint": "elbow"}
HYPOTHESES = [
    Hypothesis("pressure_sensor_offset", {"actuator": "elbow", "chamber": "a"}, "pressure_sensor_offset_a_pa",
               1e4, -2e6, 2e6, "oil", "all the time (constant)"),
    Hypothesis("pressure_sensor_offset", {"actuator": "elbow", "chamber": "b"}, "pressure_sensor_offset_b_pa",
               1e4, -2e6, 2e6, "oil", "all the time (constant)"),
    Hypothesis("valve_hysteresis", ACT, "hysteresis_extra_k0_a", 1e-2, -0.025, 0.2, "oil", "current reversals"),
    Hypothesis("valve_null_shift", ACT, "null_shift_a", 1e-2, -0.3, 0.3, "oil", "valve near null"),
    Hypothesis("valve_leak", ACT, "valve_leak_m3_per_pa_s", 1e-13, 0.0, 2e-11, "oil", "valve near null"),
    Hypothesis("piston_leak", ACT, "vane_leak_m3_per_pa_s", 1e-13, 0.0, 2e-11, "oil", "large load pressure"),
    Hypothesis("line_dynamics", {"actuator": "elbow", "chamber": "a"}, "line_volume_extra_a_m3", 1e-7, 0.0, 5e-5,
               "oil", "fast vane motion (the oil spring)"),
    Hypothesis("line_dynamics", {"actuator": "elbow", "chamber": "b"}, "line_volume_extra_b_m3", 1e-7, 0.0, 5e-5,
               "oil", "fast vane motion (the oil spring)"),
    Hypothesis("supply_droop", {"supply": "all"}, "pump_droop_pa_s_per_m3", 1e10, 0.0, 2e13, "oil",
               "large valve flow"),
    Hypothesis("coulomb_friction", JOINT, "coulomb_extra_nm", 0.1, -1.4, 10.0, "mech", "velocity reversals"),
    Hypothesis("viscous_friction", JOINT, "viscous_extra_nm_s_per_rad", 0.01, -0.05, 10.0, "mech", "high speed"),
    Hypothesis("angle_sensor_offset", JOINT, "angle_sensor_offset_rad", 0.01, -0.5, 0.5, "both",
               "all the time (constant)"),
    Hypothesis("force_sensor_offset", JOINT, "torque_sensor_offset_nm", 0.1, -20.0, 20.0, "mech",
               "all the time (constant)", needs_torque=True),
    # braced, the shaft's twist drives the vane and so the oil replay (replay.vane_speed)
    Hypothesis("shaft_compliance", {"joint": "shaft"}, "shaft_compliance_extra_rad_per_nm", 1e-5, -9e-5, 1e-3,
               "mech", "shaft oscillations after stick-slip; the braced load's twist", needs_torque=True,
               braced_side="both"),
]


def select_hypotheses(names=None, torque: bool = True) -> list[Hypothesis]:
    """The hypotheses to test: all (those the sensors can test), or those whose family or full
    name (``effect[place]``) is in ``names``."""
    usable = [h for h in HYPOTHESES if torque or not h.needs_torque]
    if names is None:
        return usable
    valid = {h.effect for h in HYPOTHESES} | {h.name for h in HYPOTHESES}
    for n in names:
        if n not in valid:
            raise UnknownNameError("hydraulic doctor hypothesis", n, valid)
    return [h for h in usable if h.effect in names or h.name in names]


def calibrated(cfg0, mech0, dev):
    """(fluid cfg, Mechanics) with the CALIBRATION deviations ``dev`` applied."""
    sv, oil = cfg0.servovalve, cfg0.oil
    cfg = dataclasses.replace(cfg0, servovalve=dataclasses.replace(sv, port_width_m=sv.port_width_m * (1.0 + dev[0])),
                              oil=dataclasses.replace(oil, bulk_modulus_pa=oil.bulk_modulus_pa * (1.0 + dev[1])))
    return cfg, mech0.scaled(dev[2], dev[3])
