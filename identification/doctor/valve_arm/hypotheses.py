"""The doctor's hypotheses: every effect of the vocabulary, at every place it could act.

A pneumatic hypothesis changes the chamber model (:class:`PneumaticMods`) through one or
two parameters and is tested by pressure replays; a mechanical one adds torque regressors to
the rigid-body equation error.  Parameters carry their unit in the name: the fields of the
family's form (pneumatics/effects/registry.py), whose own hooks put them into the chamber
model (Family.apply_to_mods) or give the torque they add (Family.torque_balance_term).  What
stays here is the doctor's search: which forms it tries, where it starts, its bounds and probes.
"""
from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from pneumatics.effects.end_stop import penetration
from pneumatics.effects.friction import coulomb_shape
from pneumatics.effects.registry import get_family

from .hypothesis import Hypothesis, torque_regressor
from .profiled import (DRIFT_START_S, DRIFT_TAU_GRID_S, drift_hypotheses, end_stop_hypotheses, rigid_body_residual,
                       velocity_power_hypotheses)

__all__ = ["Hypothesis", "end_stop_hypotheses", "mechanical_hypotheses", "penetration", "pneumatic_hypotheses",
           "smooth_torque_yardstick"]


def _apply(family: str, robot, place: str, form: str | None = None):
    """(mods, x) -> mods with ``family`` at ``place``: x holds the first fields of the family's
    ``form`` in order (the rest keep their defaults), put into the chamber model by the family's
    own hook (pneumatics.effects.<family>: Family.apply_to_mods)."""
    fam = get_family(family)
    cls = fam.form_class(form)
    names = [f.name for f in dataclasses.fields(cls)]

    def apply(mods, x):
        return fam.apply_to_mods(mods, robot, place, cls(**dict(zip(names, x))))
    return apply


#: gas-wall conductance h A [W/K] the heat_transfer hypothesis starts from and its upper bound:
#: arm2's chambers (walls of 20-50 cm^2, h = 10-100 W/(m^2 K) with the flow's forced convection,
#: Carneiro & de Almeida 2006) have 0.02-0.5 W/K; 2 W/K is close to isothermal at 1 ms.
HEAT_PROBE_W_K, HEAT_MAX_W_K = 0.1, 2.0
#: the laminar piston leak's and valve clearance's conductance G [kg/(s Pa)] (effects.external_leak.laminar_flow): the
#: probe step carries about what a 1e-8 m^2 orifice does at 5 bar (~1e-5 kg/s), the bound 10x
#: the orifice forms' 4e-7 m^2 in the same sense
LAMINAR_PROBE, LAMINAR_MAX = 1e-11, 4e-9


#: the lumped line's tube volume: its probe step [m^3] (a 4 mm bore, 4 cm; arm2's dead volumes are
#: 3-4 cm^3), its bound in the chamber's dead volumes; its resistance's time constant [s]: start
#: and bounds (a tube of 1-3 cm^3 behind a few cm of fitting: a few to a few tens of ms,
#: Richer & Hurmuzlu 2000 §3)
TUBE_PROBE_M3, TUBE_MAX_DEAD_VOLUMES = 5e-7, 3.0
TUBE_TAU_START_S, TUBE_TAU_MIN_S, TUBE_TAU_MAX_S = 0.008, 5e-4, 0.1


def pneumatic_hypotheses(robot) -> list[Hypothesis]:
    out = []
    C = robot.tables.n_chambers
    for c, (a, ch) in enumerate(robot.chamber_names):
        where, place = {"actuator": a, "chamber": ch}, f"{a}.{ch}"
        out += [
            Hypothesis("valve_leak", where, "pneumatic", [("leak_area_m2", 0.0, 0.0, 4e-7, 2e-8)], [c],
                       apply=_apply("valve_leak", robot, place, "symmetric")),
            # the lands underlapped unequally: the pressure the leak pulls the chamber towards
            # moves (a laminar underlap balances near (p_s + p_room) / 2, the symmetric orifice
            # leak near 5.6 bar on arm2); the symmetric one is preferred unless this pays clearly
            # (the leak is there when either land leaks: a laminar underlap fitted by orifices
            # puts most of it on the exhaust land, the supply land's area 3.7 standard errors
            # from zero on fresh run 19's seed 251294628, where an external leak was named)
            Hypothesis("valve_leak", where, "pneumatic", [("supply_leak_area_m2", 0.0, 0.0, 4e-7, 2e-8),
                                                          ("exhaust_leak_area_m2", 0.0, 0.0, 4e-7, 2e-8)], [c],
                       apply=_apply("valve_leak", robot, place, "asymmetric"), any_tested=True),
            # an underlapped spool (Merritt 1967 §3.6): open at null, and the land that opens stays
            # open by the underlap, so the leak shows at every opening, not only near null; the
            # underlap width is assumed (UNDERLAP_WIDTH_V), the area fitted
            Hypothesis("valve_leak", where, "pneumatic", [("underlap_area_m2", 0.0, 0.0, 4e-7, 2e-8)], [c],
                       apply=_apply("valve_leak", robot, place, "underlap")),
            # an overlapped spool whose lands seal by a radial clearance (Merritt 1967 ch. 5): a
            # laminar flow through each land, inversely as the length it still covers, so the
            # land that stays shut leaks at every opening and the flow grows as the pressures
            # squared; the overlap is assumed (CLEARANCE_WIDTH_V), the conductance fitted
            Hypothesis("valve_leak", where, "pneumatic",
                       [("clearance_conductance_kg_s_pa", 0.0, 0.0, LAMINAR_MAX, LAMINAR_PROBE)], [c],
                       apply=_apply("valve_leak", robot, place, "clearance")),
            Hypothesis("external_leak", where, "pneumatic", [("leak_area_m2", 0.0, 0.0, 4e-7, 1e-8)], [c],
                       apply=_apply("external_leak", robot, place, "orifice")),
            # no laminar form of the external leak here (the simulator has one): the orifice
            # form names capillary external leaks (3 / 3 in the variant benchmark without the
            # laminar form), while the laminar one, growing as p^2, took 26 % of the
            # residual of a supply area that shrinks with pressure (published sample
            # case_2e6a35dc, outside the vocabulary) and named it an external leak
            Hypothesis("valve_hysteresis", where, "pneumatic", [("half_width_v", 0.0, 0.0, 2.0, 0.1)], [c],
                       apply=_apply("valve_hysteresis", robot, place)),
            Hypothesis("valve_lag", where, "pneumatic", [("time_constant_s", 0.0, 0.0, 0.15, 0.004)], [c],
                       apply=_apply("valve_lag", robot, place)),
            # a slew limit: large command steps take the spool a fixed time, small ones none
            Hypothesis("valve_lag", where, "pneumatic", [("full_stroke_time_s", 0.0, 0.0, 0.5, 0.02)], [c],
                       apply=_apply("valve_lag", robot, place, "slew_limit")),
            Hypothesis("line_dynamics", where, "pneumatic", [("delay_s", 0.0, 0.0, 0.15, 0.004)], [c],
                       adds_volume=float(robot.tables.dead_volume[c]),
                       apply=_apply("line_dynamics", robot, place)),
            # the tube at its own pressure behind a laminar resistance (line_dynamics, lumped_rc):
            # the valve fills the tube, the tube the chamber with a time constant; its volume is
            # tested, the time constant a shape that starts at TUBE_TAU_START_S
            Hypothesis("line_dynamics", where, "pneumatic",
                       [("tube_volume_m3", 0.0, 0.0, TUBE_MAX_DEAD_VOLUMES * float(robot.tables.dead_volume[c]),
                         TUBE_PROBE_M3),
                        ("time_constant_s", TUBE_TAU_START_S, TUBE_TAU_MIN_S, TUBE_TAU_MAX_S, 0.002)], [c],
                       apply=_apply("line_dynamics", robot, place, "lumped_rc"), tested=(0,)),
            Hypothesis("pressure_sensor_offset", where, "pneumatic", [("offset_pa", 0.0, -5e4, 5e4, 2000.0)], [c],
                       apply=_apply("pressure_sensor_offset", robot, place)),
            # a sensor warming up: its zero settles by drift_pa over time_constant_s from the
            # recording's start (the time constant starts at 20 s; it matters once drift is not 0)
            Hypothesis("pressure_sensor_offset", where, "pneumatic",
                       [("offset_pa", 0.0, -5e4, 5e4, 2000.0), ("drift_pa", 0.0, -5e4, 5e4, 2000.0),
                        ("time_constant_s", DRIFT_START_S, DRIFT_TAU_GRID_S[0], DRIFT_TAU_GRID_S[-1], 10.0)], [c],
                       apply=_apply("pressure_sensor_offset", robot, place, "warm_up_drift"), tested=(1,)),
            Hypothesis("heat_transfer", where, "pneumatic",
                       [("conductance_w_k", 0.0, 0.0, HEAT_MAX_W_K, HEAT_PROBE_W_K)], [c],
                       apply=_apply("heat_transfer", robot, place), null_value=np.nan),
        ]
    for j, a in enumerate(robot.actuator_names):
        out.append(Hypothesis("piston_leak", {"actuator": a}, "pneumatic", [("leak_area_m2", 0.0, 0.0, 4e-7, 1e-8)],
                              [2 * j, 2 * j + 1], apply=_apply("piston_leak", robot, a, "orifice")))
        out.append(Hypothesis("piston_leak", {"actuator": a}, "pneumatic",
                              [("conductance_kg_s_pa", 0.0, 0.0, LAMINAR_MAX, LAMINAR_PROBE)],
                              [2 * j, 2 * j + 1], apply=_apply("piston_leak", robot, a, "laminar")))
    joint_driven = robot.model.actuator_trntype[robot.actuator_ids] == int(mujoco.mjtTrn.mjTRN_JOINT)
    for j, a in enumerate(robot.actuator_names):
        if joint_driven[j]:  # the play shifts the piston by gear x gap / 2 (pneumatic.drive_side_lengths)
            joint = robot.model.joint(int(robot.model.actuator_trnid[robot.actuator_ids[j], 0])).name
            out.append(Hypothesis("backlash", {"joint": joint}, "pneumatic", [("gap_rad", 0.0, 0.0, 0.1, 0.005)],
                                  [2 * j, 2 * j + 1], joint=robot.joint_names.index(joint),
                                  apply=_apply("backlash", robot, joint)))
    out.append(Hypothesis("supply_droop", {"supply": "all"}, "pneumatic",
                          [("droop_pa_per_kg_s", 0.0, 0.0, 5e8, 5e6)], list(range(C)),
                          apply=_apply("supply_droop", robot, "all")))
    # behind a receiver the droop follows the flow low-passed (a few ms to a few 100 ms: 20-50
    # cm^3 behind a regulator of 1e7-1e8 Pa s/kg); the time constant is a shape, tested only
    # through the droop, and parsimony keeps the linear form unless this pays clearly
    out.append(Hypothesis("supply_droop", {"supply": "all"}, "pneumatic",
                          [("droop_pa_per_kg_s", 0.0, 0.0, 5e8, 5e6), ("time_constant_s", 0.02, 0.0, 1.0, 0.01)],
                          list(range(C)), apply=_apply("supply_droop", robot, "all", "reservoir"), tested=(0,)))
    # a regulator whose seat is an orifice near its set pressure droops with the flow squared
    # (effects.supply_droop, regulator_orifice): 1e10-1e12 Pa/(kg/s)^2 for seats of 1.5-0.3 mm^2
    # at arm2's draws of a few 1e-4 kg/s (tens of kPa), behind the same receiver
    out.append(Hypothesis("supply_droop", {"supply": "all"}, "pneumatic",
                          [("droop_pa_per_kg2_s2", 0.0, 0.0, 5e12, 1e10), ("time_constant_s", 0.02, 0.0, 1.0, 0.01)],
                          list(range(C)), apply=_apply("supply_droop", robot, "all", "regulator_orifice"),
                          tested=(0,)))
    # a receiver a switched compressor refills: its switch makes the replays jump with the
    # parameters, so it is searched in the flow errors (supply_receiver), not by the score test
    out.append(Hypothesis("supply_droop", {"supply": "all"}, "pneumatic",
                          [("receiver_volume_m3", 1e-3, 1e-4, 0.1, 0.0), ("compressor_kg_s", 3e-4, 1e-5, 1e-2, 0.0),
                           ("band_pa", 3e4, 0.0, 1.5e5, 0.0), ("cut_out_pa", robot.tables.supply_pa, 1e5, 2e6, 0.0),
                           ("leak_kg_s_pa", 0.0, 0.0, 1e-9, 0.0)], list(range(C)),
                          apply=_apply("supply_droop", robot, "all", "compressor_cycling"), tested=(2,),
                          screened=False))
    return out


#: the angle profile's bin [rad]: four bins to the period of the finest position-periodic
#: torque worth naming (detents, cogging of a 5 deg pitch: 0.087 rad), far wider than the
#: angle noise (~1e-4 rad) and the filter's lag at the joints' speeds
ANGLE_PROFILE_BIN_RAD = 0.02
#: a bin the training data visit less than this [samples] joins its neighbour: its mean would be noise
ANGLE_PROFILE_MIN_SAMPLES = 20


def angle_profile_yardstick(robot, j: int, exp) -> Hypothesis:
    """Not an effect: a torque of joint j's angle alone, one constant per ANGLE_PROFILE_BIN_RAD
    bin of the angles the training data ``exp`` visit (a histogram regression).

    The smooth yardstick's functions of the angle are a constant, q and q^2; a detent, cogging
    or a cam's torque changes sign many times over the range and none of them follows it.  This
    one follows any torque of the angle that varies more slowly than its bins; the angles the
    training data did not visit take their nearest bin's value."""
    q = exp.q_s[:, j]
    edges = np.arange(q.min(), q.max(), ANGLE_PROFILE_BIN_RAD)[1:]
    counts = np.bincount(np.digitize(q, edges), minlength=edges.size + 1)
    while edges.size and counts.min() < ANGLE_PROFILE_MIN_SAMPLES:  # merge the emptiest bin into a neighbour
        k = int(np.argmin(counts))
        drop = min(k, edges.size - 1)
        edges = np.delete(edges, drop)
        counts = np.bincount(np.digitize(q, edges), minlength=edges.size + 1)

    def reg(e, td, edges=edges):
        n, J = e.qd.shape
        out = np.zeros((n, J, edges.size + 1))
        out[np.arange(n), j, np.digitize(e.q_s[:, j], edges)] = 1.0
        return out

    def torque(values, q, qd, edges=edges):  # the equation error's +theta is a torque -theta on the link
        return -np.asarray(values)[np.digitize(q, edges)]
    names = [f"bin_{k}_nm" for k in range(edges.size + 1)]
    return Hypothesis("angle_profile", {"joint": robot.joint_names[j]}, "mechanical",
                      [(n, 0.0, -np.inf, np.inf, 0.0) for n in names], joint=j, regressor=reg, state_torque=torque)


#: the largest gain error an angle sensor may have [-]: a potentiometer's or a two-point
#: calibration's few per cent (the random-form generator draws 1-3 %), an eccentric disc's e cos(phi)
#: <= 0.015.  A fit that wants more is a spring standing in (a hose pulling the elbow with
#: 0.08 N m/rad, development seed 197913926, fitted 8.2 %; its least squares at the bound give no
#: error bar, which the keep rule rejects)
ANGLE_GAIN_MAX = 0.05


def mechanical_hypotheses(robot, exp=None, td=None) -> list[Hypothesis]:
    """Friction, angle-sensor offsets and pressure-sensor offsets at every joint/chamber; end
    stops, warming-up pressure sensors and velocity-power friction too when the training data
    (``exp``, ``td``) are given to place them and choose their time constant or exponent
    (profiled.py)."""
    out = []
    if exp is not None:
        residual = rigid_body_residual(td)
        out = (end_stop_hypotheses(robot, exp, td) + drift_hypotheses(robot, exp, td, residual)
               + velocity_power_hypotheses(robot, exp, td, residual))
    for j, name in enumerate(robot.joint_names):
        w = {"joint": name}
        out += [
            Hypothesis("coulomb_friction", w, "mechanical", [("coulomb_nm", 0.0, 0.0, np.inf, 0.0)], joint=j,
                       regressor=torque_regressor("coulomb_friction", j, [{"coulomb_nm": 1.0}])),
            # stiction is Stribeck friction: a Coulomb level plus a breakaway excess at low speed
            Hypothesis("stiction", w, "mechanical", [("coulomb_nm", 0.0, 0.0, np.inf, 0.0),
                                                     ("breakaway_extra_nm", 0.0, 0.0, np.inf, 0.0)], joint=j,
                       regressor=torque_regressor("stiction", j, [{"coulomb_nm": 1.0}, {"breakaway_extra_nm": 1.0}])),
            Hypothesis("viscous_friction", w, "mechanical", [("viscous_nm_s_per_rad", 0.0, 0.0, np.inf, 0.0)],
                       joint=j, regressor=torque_regressor("viscous_friction", j, [{"viscous_nm_s_per_rad": 1.0}])),
            Hypothesis("angle_sensor_offset", w, "mechanical", [("offset_rad", 0.0, -0.2, 0.2, 0.0)], joint=j,
                       regressor=torque_regressor("angle_sensor_offset", j, [{"offset_rad": 1.0}])),
            # ... and its gain too: a two-point calibration's two errors, or over the joint's
            # travel an eccentric disc's once-per-turn error (angle_sensor_offset's docstring),
            # within ANGLE_GAIN_MAX
            Hypothesis("angle_sensor_offset", w, "mechanical", [("offset_rad", 0.0, -0.2, 0.2, 0.0),
                                                                ("scale_error", 0.0, -ANGLE_GAIN_MAX, ANGLE_GAIN_MAX, 0.0)],
                       joint=j,
                       regressor=torque_regressor("angle_sensor_offset", j, [{"offset_rad": 1.0},
                                                                             {"offset_rad": 0.0, "scale_error": 1.0}],
                                                   "offset_and_scale"), form="offset_and_scale"),
        ]
    # a pressure-sensor offset seen by the torque balance: a constant actuator force error.
    # Chambers a and b of one actuator give (nearly) collinear regressors here; the doctor
    # picks the chamber by the pressure replays (see doctor._pick_offset_chamber).
    for c, (a, ch) in enumerate(robot.chamber_names):
        j = robot.joint_names.index(a) if a in robot.joint_names else 0
        out.append(Hypothesis("pressure_sensor_offset", {"actuator": a, "chamber": ch}, "mechanical",
                              [("offset_pa", 0.0, -5e4, 5e4, 0.0)], chambers=[c], joint=j,
                              regressor=lambda e, td, c=c: td.dtau_dp[:, :, c:c + 1]))
    return out


def smooth_torque_yardstick(robot, j: int) -> Hypothesis:
    """Not an effect: a smooth torque of joint j's own state — a constant, the angle and its
    square, the Coulomb shape and the velocity — fitted by the same linear least squares.

    It measures how much of the joint's torque residual *any* simple function of its state
    would remove.  The library's mechanical effects are (near) special cases of it (a constant
    force error, friction, an angle offset's gravity torque), so a true one removes about as
    much as the yardstick; a torque the library does not hold (a spring, a hose pulling on the
    link) is taken up by the yardstick and only projected, in part, onto a library effect."""
    names = ["constant_nm", "per_rad_nm", "per_rad2_nm", "coulomb_nm", "viscous_nm_s_per_rad"]

    def reg(e, td):
        out = np.zeros(e.qd.shape + (len(names),))
        out[:, j] = _smooth_basis(e.q[:, j], e.qd[:, j])
        return out

    def torque(values, q, qd):  # as friction_torque: the equation error's +theta f is a torque -theta f on the link
        return -_smooth_basis(q, qd) @ np.asarray(values, float)
    return Hypothesis("smooth_torque", {"joint": robot.joint_names[j]}, "mechanical",
                      [(n, 0.0, -np.inf, np.inf, 0.0) for n in names], joint=j, regressor=reg, state_torque=torque)


def _smooth_basis(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """(n, 5) the smooth yardstick's functions of a joint's angle q and velocity qd (n,): its
    regressor in the torque balance and its torque in the angle replay are both made of these."""
    return np.stack([np.ones_like(q), q, q ** 2, coulomb_shape(qd), qd], axis=1)
