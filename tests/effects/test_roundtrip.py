"""One round trip per effect family: the simulator with the effect, then the doctor's replay of
it with the same parameters, taken from the same family definition (pneumatics/effects/registry.py).

A short noise-free recording of arm2 (PIDF tracking a hand-moved reference, sensors sampled
at 100 Hz without DAQ averaging) is made with one effect on; the doctor's replay of that
effect must reproduce it, and the replay without the effect must not:

* chamber, actuator and supply families (and backlash): the pressure replays
  (identification.doctor.valve_arm.pneumatic.replay, restarted every 0.3 s from the recorded pressures) with
  the chamber model the family fills (Family.apply_to_mods);
* joint families: the torque balance (identification.doctor.valve_arm.torque_balance.torque_data): the equation
  error tau_act - tau_inv must equal the torque the family says the effect adds
  (Family.torque_balance_term).

Not to round-off: the doctor sees the motion only through 100 Hz samples (angles splined,
velocities differentiated), where the simulator had it every 1 ms.  The nominal model replays
a nominal recording to about 10-20 Pa RMS; each tolerance below is stated with its reason.
"""
from __future__ import annotations

import numpy as np
import pytest

from controllers.pid import ARM2_PIDF
from controllers.reference import hand_moved
from identification.doctor.valve_arm.data import prepare
from identification.doctor.valve_arm.torque_balance import torque_data
from identification.doctor.valve_arm.pneumatic import Windows, replay
from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
from pneumatics.effects.effect_set import EffectSet
from pneumatics.effects.registry import FAMILIES, get_family
from pneumatics.runner import run
from pneumatics.sim import Simulation

SECONDS = 3.0
HORIZON = 30  # samples per pressure replay (0.3 s)
#: heat_transfer steps in Python (about 10x slower): a shorter recording keeps it at a few seconds
SECONDS_OF = {"heat_transfer": 2.0}


def record(robot, family=None, place=None, params=None, seconds=SECONDS, seed=3):
    effects = EffectSet()
    if family is not None:
        get_family(family).add_to(effects, place, params)
    ref = hand_moved(robot.joint_names, robot.joint_range(), seconds, seed=seed)
    sim = Simulation(robot, effects=effects)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=4.5e5)
    rec = run(sim, ARM2_PIDF.build(ref, robot.tables.valve[:, 0]), seconds, noise=False, average=False, seed=1)
    return prepare(robot, rec)


def pressure_error_pa(exp, mods) -> float:
    """RMS over every chamber and window of replayed minus recorded pressure [Pa]."""
    predicted, measured = replay(exp, Windows.tile(exp.t.size, HORIZON), mods)
    return float(np.sqrt(np.mean((predicted - measured) ** 2)))


#: (family, form, place, parameters, tolerance [Pa RMS], least ratio without / with):
#: magnitudes from the case makers' ranges.  Most families replay to the nominal model's own
#: 10-40 Pa; the wider tolerances are differences between the two sides that these tests found
#: and that remain (docs/effects.md):
PRESSURE_CASES = [
    ("valve_leak", "symmetric", "elbow.a", {"leak_area_m2": 4e-8}, 100.0, 10.0),
    ("valve_leak", "asymmetric", "elbow.a", {"supply_leak_area_m2": 5e-8, "exhaust_leak_area_m2": 1e-8}, 100.0, 10.0),
    ("valve_leak", "underlap", "elbow.a", {"underlap_area_m2": 4e-8, "underlap_width_v": 0.4}, 100.0, 10.0),
    # the generator's clearances (1-3e-11 at null); at 4e-11 over a 0.4 V overlap the land about
    # to open passes 4e-10, a second valve whose gain near null sets the elbow's loop chattering
    # faster than 100 Hz samples of its motion resolve (replays then miss by ~9 kPa)
    ("valve_leak", "clearance", "elbow.a", {"clearance_conductance_kg_s_pa": 2e-11, "overlap_width_v": 0.6}, 100.0,
     10.0),
    ("external_leak", "orifice", "shoulder.b", {"leak_area_m2": 2e-8}, 100.0, 10.0),
    ("external_leak", "laminar", "shoulder.b", {"conductance_kg_s_pa": 2e-11}, 100.0, 10.0),
    ("piston_leak", "orifice", "elbow", {"leak_area_m2": 2e-8}, 100.0, 10.0),
    ("piston_leak", "laminar", "elbow", {"conductance_kg_s_pa": 2e-11}, 100.0, 10.0),
    ("valve_hysteresis", "play", "shoulder.a", {"half_width_v": 0.3}, 100.0, 10.0),
    # the doctor takes the lagged spool at the end of each 1 ms step, the simulator at its middle
    # (a 0.5 ms lead: ~340 of the ~550 Pa on elbow.b), and the lag makes the elbow's loop ring
    # faster than 100 Hz samples of its motion resolve (~130 Pa on elbow.a, which has no lag)
    ("valve_lag", "first_order", "elbow.b", {"time_constant_s": 0.03}, 400.0, 10.0),
    # a dead time runs on the line's delay mechanism, without its volume (and rings the loop
    # like the line's delay)
    ("valve_lag", "dead_time", "elbow.a", {"dead_time_s": 0.02}, 200.0, 10.0),
    # the slewing spool leads by the same half step as the lag's (the generator's 50-150 V/s
    # rate limits are full-stroke times of 0.07-0.2 s)
    ("valve_lag", "slew_limit", "elbow.b", {"full_stroke_time_s": 0.4}, 400.0, 8.0),
    # the delayed spool rings the loop likewise (~130 Pa on both elbow chambers)
    ("line_dynamics", "delay_volume", "elbow.a", {"delay_s": 0.02, "volume_m3": 2e-6}, 200.0, 10.0),
    # the tube's pressure starts at the chamber's in every replay window (its true one differs
    # by the flow through the resistance); the generator's tubes of 1-3 cm^3 and 5-15 ms
    ("line_dynamics", "lumped_rc", "elbow.a", {"tube_volume_m3": 2e-6, "time_constant_s": 0.01}, 200.0, 10.0),
    ("heat_transfer", "newton", "shoulder.a", {"conductance_w_k": 0.1}, 100.0, 10.0),
    ("pressure_sensor_offset", "additive", "elbow.b", {"offset_pa": 1.5e4}, 100.0, 10.0),
    # a sensor warming up: the reading's offset settles from 3 to 18 kPa within the recording
    ("pressure_sensor_offset", "warm_up_drift", "elbow.b", {"offset_pa": 3e3, "drift_pa": 1.5e4, "time_constant_s": 1.0},
     100.0, 10.0),
    # the simulator draws the droop from the flows at the nominal supply pressure and the
    # end-of-step chamber pressures, the doctor from the drooped supply and the start-of-step
    # ones: 0.1-0.9 kPa where the valves draw hard (supply_droop.py)
    ("supply_droop", "linear", "all", {"droop_pa_per_kg_s": 8e7}, 400.0, 5.0),
    ("supply_droop", "reservoir", "all", {"droop_pa_per_kg_s": 8e7, "time_constant_s": 0.05}, 400.0, 5.0),
    # a regulator's orifice: 25 kPa at a draw of 5e-4 kg/s, 100 kPa at 1e-3
    ("supply_droop", "regulator_orifice", "all", {"droop_pa_per_kg2_s2": 1e11, "time_constant_s": 0.05}, 400.0, 5.0),
    # the receiver integrated along the recording from the simulator's start (cut-out, off) at
    # the measured pressures' flows: a 0.2 L receiver, 0.2 bar band, cycling every ~0.5 s
    ("supply_droop", "compressor_cycling", "all", {"receiver_volume_m3": 2e-4, "compressor_kg_s": 1.5e-3,
                                                   "band_pa": 2e4, "cut_out_pa": 7e5, "leak_kg_s_pa": 1e-11},
     400.0, 5.0),
    # the doctor's backlash is quasi-static (the piston leads the link by gap/2 tanh(F / 1 % of
    # its largest force)); in the simulator the piston crosses the play in a few ms, bouncing
    ("backlash", "dead_zone", "elbow", {"gap_rad": 0.012}, 800.0, 2.0),
]


@pytest.mark.parametrize("family, form, place, values, tol_pa, ratio", PRESSURE_CASES,
                         ids=[f"{c[0]}-{c[1]}" for c in PRESSURE_CASES])
def test_the_pressure_replay_of_a_family_reproduces_the_simulator(arm2, family, form, place, values, tol_pa, ratio):
    fam = get_family(family)
    params = fam.params(values, form)
    exp = record(arm2, family, place, params, seconds=SECONDS_OF.get(family, SECONDS))
    nominal = PneumaticMods.nominal(arm2.tables.n_chambers)
    with_effect = pressure_error_pa(exp, fam.apply_to_mods(nominal, arm2, place, params))
    without = pressure_error_pa(exp, nominal)
    print(f"{family} ({form}): {with_effect:.1f} Pa with, {without:.1f} Pa without")
    assert with_effect < tol_pa
    assert without > ratio * with_effect


def torque_error_nm(td, joint: int, term=None) -> float:
    """RMS over the valid samples of joint ``joint``'s equation error tau_act - tau_inv minus
    the effect's torque ``term`` (N, J) [N m]."""
    res = td.residual if term is None else td.residual - term
    return float(np.sqrt(np.mean(res[td.valid, joint] ** 2)))


#: (family, form, joint, parameters, tolerance [N m RMS], least ratio without / with); a nominal
#: recording leaves 0.0015-0.002 N m RMS in the equation error (splined 100 Hz angles)
TORQUE_CASES = [
    ("coulomb_friction", "coulomb", "elbow", {"coulomb_nm": 0.08}, 0.01, 5.0),
    # stick-slip: the joint stops and breaks away within a few ms, which 100 Hz samples and
    # their splined accelerations do not resolve (0.01-0.03 N m left where |qd| < 0.05 rad/s)
    ("stiction", "stribeck", "shoulder", {"coulomb_nm": 0.03, "breakaway_extra_nm": 0.1, "stribeck_rad_s": 0.1},
     0.025, 2.0),
    ("viscous_friction", "linear", "elbow", {"viscous_nm_s_per_rad": 0.1}, 0.01, 5.0),
    ("viscous_friction", "velocity_power", "elbow", {"power_coefficient_nm": 0.07, "exponent": 0.5}, 0.01, 5.0),
    ("angle_sensor_offset", "additive", "shoulder", {"offset_rad": 0.05}, 0.01, 5.0),
    ("angle_sensor_offset", "offset_and_scale", "shoulder", {"offset_rad": 0.02, "scale_error": 0.04}, 0.01, 5.0),
]


@pytest.mark.parametrize("family, form, joint, values, tol_nm, ratio", TORQUE_CASES,
                         ids=[f"{c[0]}-{c[1]}" for c in TORQUE_CASES])
def test_the_torque_balance_of_a_family_reproduces_the_simulator(arm2, family, form, joint, values, tol_nm, ratio):
    fam = get_family(family)
    params = fam.params(values, form)
    exp = record(arm2, family, joint, params)
    td = torque_data(exp)
    j = arm2.joint_names.index(joint)
    with_effect = torque_error_nm(td, j, fam.torque_balance_term(exp, td, j, params))
    without = torque_error_nm(td, j)
    print(f"{family} ({form}): {with_effect:.4f} N m with, {without:.4f} without")
    assert with_effect < tol_nm
    assert without > ratio * with_effect


def test_an_end_stop_in_the_simulator_is_the_doctors_spring_damper_at_the_same_angle(arm2):
    """The simulator's bumper (soft_limit: MuJoCo's soft joint limit moved inside the model's)
    and the doctor's (spring_damper) share the stop angle; MuJoCo sets the soft limit's
    stiffness and damping from the joint's inertia, so those two are fitted here by the doctor's
    linear least squares on the torque balance, and must then explain the contact torque."""
    fam, joint = get_family("end_stop"), "elbow"
    j = arm2.joint_names.index(joint)
    lo, hi = arm2.model.jnt_range[arm2.model.joint(joint).id]
    reached = record(arm2).q[:, j].max()
    soft = fam.params({"side": "upper", "intrusion_rad": float(hi - (reached - 0.2))}, "soft_limit")
    exp = record(arm2, "end_stop", joint, soft)
    td = torque_data(exp)
    stop, side = fam.stop_angle(arm2, joint, soft)
    assert abs(stop - (reached - 0.2)) < 1e-12
    unit_k = fam.params({"stop_rad": stop, "side_sign": side, "stiffness_nm_per_rad": 1.0}, "spring_damper")
    unit_b = fam.params({"stop_rad": stop, "side_sign": side, "damping_nm_s_per_rad": 1.0}, "spring_damper")
    regressors = np.column_stack([fam.torque_balance_term(exp, td, j, u)[td.valid, j] for u in (unit_k, unit_b)])
    (k, b), *_ = np.linalg.lstsq(regressors, td.residual[td.valid, j], rcond=None)
    fitted = fam.params({"stop_rad": stop, "side_sign": side, "stiffness_nm_per_rad": k,
                         "damping_nm_s_per_rad": max(b, 0.0)}, "spring_damper")
    with_effect = torque_error_nm(td, j, fam.torque_balance_term(exp, td, j, fitted))
    without = torque_error_nm(td, j)
    print(f"end_stop: k {k:.1f} N m/rad, b {b:.3f} N m s/rad; {with_effect:.4f} N m with, {without:.4f} without")
    assert k > 20.0  # a stop, not a spring (the doctor's END_STOP_MIN_STIFFNESS_NM_PER_RAD)
    assert without > 3 * with_effect


def test_every_registered_family_has_a_round_trip_or_says_why_not():
    tested = {c[0] for c in PRESSURE_CASES} | {c[0] for c in TORQUE_CASES} | {"end_stop"}
    for name, fam in FAMILIES.items():
        assert (name in tested) != bool(fam.roundtrip_gap), name
        if name in tested:
            assert "valve_arm" in fam.plants and fam.doctor, name


def test_the_torque_balance_sees_a_warming_up_pressure_sensor_as_a_settling_force_error(arm2):
    """pressure_sensor_offset, warm_up_drift: the measured pressure carries offset + drift
    (1 - exp(-t / tau)), so the torque balance's equation error carries that times the
    chamber's d tau / d p, which the doctor's drift hypothesis regresses on
    (profiled.drift_regressors)."""
    from identification.doctor.valve_arm.profiled import drift_regressors

    fam = get_family("pressure_sensor_offset")
    params = fam.params({"offset_pa": 3e3, "drift_pa": 1.5e4, "time_constant_s": 1.0}, "warm_up_drift")
    exp = record(arm2, "pressure_sensor_offset", "elbow.b", params)
    td = torque_data(exp)
    c = [f"{a}.{ch}" for a, ch in arm2.chamber_names].index("elbow.b")
    term = drift_regressors(exp, td, c, 1.0) @ np.array([3e3, 1.5e4])
    j = arm2.joint_names.index("elbow")
    with_effect, without = torque_error_nm(td, j, term), torque_error_nm(td, j)
    print(f"warm-up drift: {with_effect:.4f} N m with, {without:.4f} without")
    assert with_effect < 0.01
    assert without > 5.0 * with_effect
