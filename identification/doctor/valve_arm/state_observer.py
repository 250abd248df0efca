"""The robot's chamber pressures and joint velocities between the samples, estimated together
forward in time, for the rigid body's replays (angle_replay.pressure_driven_angles).

A replay window needs the cylinders' forces on the 1 ms grid and the joints' velocities where
it starts.  Each chamber alone (pressure_smoother.py) is driven by the volume its cylinder
sweeps, taken from the angles' light spline; under humanoid38's PIDF every joint limit-cycles
at 9-14 Hz with harmonics past the 100 Hz DAQ's Nyquist frequency, which the spline does not
carry: on a development recording (seed 7100, nominal humanoid38 with +-3 % errors, 60 s) the
smoothed pressures missed the simulator's 1 ms pressures by 1.7 kPa rms, and the spline's
velocities its velocities by 0.54 rad/s rms.

**Method.** The whole robot is simulated -- MuJoCo's rigid body pushed by the cylinders of the
chamber model (pneumatic.ChamberModel, the calibrated ``mods``) under the recorded valve
commands, the chambers' volumes following the simulated motion -- and corrected at every
sample by what the DAQ read over the interval just simulated (a Luenberger observer; the
corrections' form is the steady-state alpha-beta tracker, Kalata, "The tracking index",
IEEE Trans. AES 20(2), 1984, and for each chamber a scalar Kalman gain):

    q <- q + ANGLE_GAIN e_q,   v <- v + VELOCITY_GAIN e_q / T,   p <- p + PRESSURE_GAIN e_p

with e the DAQ mean (or the sample) less the simulated one over the interval and T the sample
interval.  The angle corrections keep the simulated motion on the recorded one, so the
chambers' volumes carry the motion's harmonics; the pressure corrections keep each chamber on
its sensor.  On seed 7100 against the simulator's own 1 ms states: pressures 0.89 kPa rms,
velocities 0.082 rad/s rms.  The replays' summed squared NRMSE of the nominal body (38 joints)
went from 0.062 (the smoothed pressures, the spline's velocity, the restart corrected over the
burn-in) to 0.039 (this module's pressures and velocities, the same burn-in; 0.035 with the
burn-in taking half the velocity's error, angle_replay.BURN_IN_VELOCITY_SHARE); with the
simulator's states at the windows' starts, 0.024 with this module's pressures and 0.020 with
the simulator's own.  Gains on that seed (angle, velocity, pressure; the whole burn-in):
0.5, 0.2, 0.5 -> 0.039; 0.5, 0.2, 0.9 -> 0.039; 0.5, 0.4, 0.7 -> 0.042; lower angle gains
follow the motion worse (0.3, 0.1, 0.5: 1.6 mrad rms against 1.4).

The observer runs the rigid body and the joint torques the replay judges (a replay's ``MechMods``:
its calibrated masses and the findings' or candidate's frictions and end stops), because the
pressures it hands the replays between the samples follow its own motion there.  Run with the
nominal body on a recording of humanoid38 with a true viscous friction of 0.0267 N m s/rad at
left_shoulder_pitch (nominal robot, 30 s, development), the observer's pressures differed from
the friction-following observer's by up to 2.1 kPa rms, and the replays driven by them were
worse with the true friction than without it (training angle error's mean square 1.20 times
the frictionless replay's; least at 0.01, 0.64): a fit from them found a third of the truth.
With the friction in the observer the true value replays 0.14 of the mean square of the
frictionless replay through it (its velocities alone, the start of each window, changed it by
0.001).  It reads its body through a replay's angle-sensor law: an observer that took a
true offset's readings as the true angles held its body off them against the cylinders, and on
a recording of arm2 whose elbow sensor read 0.03 rad high its pressures were 0.70-1.07 kPa rms
off the simulator's and its velocities 0.11-0.16 rad/s, against 0.27-0.28 kPa and 0.022-0.024
rad/s reading through the offset (tests/test_doctor_state_observer.py).  It runs on the
pressures as read (the sensor offsets' fields left out of the chamber model; the replays take
the offsets off the forces), and starts again at every join of pooled recordings.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, fields

import mujoco
import numpy as np

from pneumatics.chamber import actuator_force
from pneumatics.effects.angle_sensor_offset import reading_error, true_angle
from pneumatics.effects.backlash import addresses
from pneumatics.kernel import pack

from .data import FINE_DT, Experiment
from .observer_kernel import chamber_travel, fine_step, set_actuation
from .torque_kernel import pack_torque_law
from .pneumatic import ChamberModel, effective_commands
from .pneumatic_mods import PneumaticMods
from .replay import MechMods
from .thermal import gas_temperatures

#: the share of each sample's angle innovation [rad] added to the simulated angles
ANGLE_GAIN = 0.5
#: the share of each sample's angle innovation, per sample interval, added to the simulated
#: velocities [rad/s per rad of innovation x sample interval]
VELOCITY_GAIN = 0.2
#: the share of each sample's pressure innovation [Pa] added to the simulated pressures
PRESSURE_GAIN = 0.5
#: the sensor-offset fields of PneumaticMods: the observer runs on the pressures as read, and
#: the replays take the offsets off afterwards (first order: a few kPa change the flows little)
SENSOR_FIELDS = ("sensor_offset_pa", "sensor_drift_pa", "sensor_drift_tau_s")
#: observed recordings kept per recording (a doctor's run asks for the same ones hundreds of times)
CACHE_SIZE = 4


@dataclass(frozen=True)
class ObservedStates:
    """The observer's estimates on the recording's 1 ms grid (``exp.fine_t``)."""

    #: (F, C) every chamber's pressure as read [Pa] (sensor offsets not taken off)
    pressure_pa: np.ndarray
    #: (F, J) every joint's velocity [rad/s], in the angle sensors' units (as read)
    velocity_rad_s: np.ndarray


def observed_states(exp: Experiment, mods: PneumaticMods, mech: MechMods | None = None) -> ObservedStates:
    """The observer's pressures and velocities (module docstring) with the chamber model
    ``mods`` and the rigid body and joint torques of ``mech`` (None: the nominal body, no
    torques); kept on ``exp`` for the next call with the same recording and models."""
    mech_digest = mech_key(mech)
    cache, key = exp.observer_cache, mods_key(mods) + mech_digest
    for entry in cache:     # a copy of ``exp`` (dataclasses.replace) shares the list
        if entry[0] == key and entry[1] is exp.p and entry[2] is exp.u and entry[3] is exp.q:
            cache.remove(entry)     # the last used go last: a round's base outlives its candidates'
            cache.append(entry)
            return entry[4]
    out = observe(exp, mods.copy(**{name: None for name in SENSOR_FIELDS}), mech if mech_digest else None)
    cache.append((key, exp.p, exp.u, exp.q, out))
    del cache[:-CACHE_SIZE]
    return out


def mods_key(mods: PneumaticMods) -> str:
    """A digest of everything in ``mods`` the chamber model integrates (the sensor offsets not)."""
    h = hashlib.sha1()
    for f in fields(mods):
        if f.name in SENSOR_FIELDS:
            continue
        v = getattr(mods, f.name)
        items = sorted(v.items()) if isinstance(v, dict) else [(None, v)]
        for k, x in items:
            h.update(f"{f.name}:{k}:".encode())
            h.update(np.ascontiguousarray(x, float).tobytes() if x is not None else b"None")
    return h.hexdigest()


#: the MechMods fields of the angle sensors' law (effects.angle_sensor_offset)
SENSOR_LAW = ("angle_offset_rad", "angle_scale_error")
#: the MechMods fields the observer runs: the rigid body, the joint torques, and the angle
#: sensors' law, through which it compares its body's angles with the readings
OBSERVED_MECH = ("mass_scale", "damping_scale", "armature_scale", "coulomb_nm", "stiction_extra_nm",
                 "viscous_nm_s", "viscous_power_nm", "viscous_exponents", "end_stop_nm_per_rad",
                 "end_stop_nm_s_per_rad", "end_stops", *SENSOR_LAW)


def mech_key(mech: MechMods | None) -> str:
    """A digest of what the observer runs of ``mech`` ('' for none: the nominal body without
    torques, whatever object says so); a yardstick's torque functions by identity."""
    if mech is None:
        return ""
    h, any_set = hashlib.sha1(), False
    for name in OBSERVED_MECH:
        v = getattr(mech, name)
        items = sorted(v.items()) if isinstance(v, dict) else [] if v is None else [(None, v)]
        for k, x in items:
            if np.any(np.asarray(x, float) != 0):
                any_set = True
            h.update(f"{name}:{k}:".encode())
            h.update(np.ascontiguousarray(x, float).tobytes())
    for j, f in sorted(mech.state_torques.items()):
        any_set = True
        h.update(f"state_torque:{j}:{id(f)}".encode())
    return h.hexdigest() if any_set else ""


def observe(exp: Experiment, mods: PneumaticMods, mech: MechMods | None = None) -> ObservedStates:
    """Run the observer over the recording, from each pooled part's start (its light spline's
    angles and velocity, its pressures' spline at the first sample), with ``mech``'s rigid body,
    joint torques and angle sensors (None: the nominal body, sensors reading true): its body's
    angles are compared with the readings through the sensors' law
    (effects.angle_sensor_offset), so a sensor's offset does not hold the body off its true
    angle against the cylinders' forces.

    The chambers' step, forces and joint torques are compiled (observer_kernel) between
    MuJoCo's two half steps; :func:`observe_reference` is the same loop in Python, and runs the
    state torques (a yardstick's Python functions) and the RK4 integrator this path cannot."""
    robot = exp.robot
    if (mech is not None and mech.state_torques) or robot.model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        return observe_reference(exp, mods, mech)
    model = robot.model if mech is None else mech.model(robot.model)
    data = mujoco.MjData(model)
    qadr, dadr = addresses(model, robot.joint_names)
    qadr, dadr = np.asarray(qadr, np.int64), np.asarray(dadr, np.int64)
    ids, tab, S = np.asarray(robot.actuator_ids, np.int64), robot.tables, exp.n_sub
    geometry = (ids, np.asarray(tab.actuator_of_chamber, np.int64), np.asarray(tab.length_zero, float),
                np.asarray(tab.stroke, float), np.asarray(tab.is_a, np.bool_))
    forces = pack(tab, ids, FINE_DT)[::2]     # (act, glob): the simulator's force writer's tables
    law, active = pack_torque_law(mech, len(qadr))
    chambers = ChamberModel(robot, mods, 1)
    kargs = chambers.kernel_args()
    u = np.ascontiguousarray(effective_commands(exp, mods))
    F, C, J = exp.fine_t.size, tab.n_chambers, len(qadr)
    pressure, velocity = np.empty((F, C)), np.empty((F, J))
    offset, gain = sensor_law(mech, J)
    rate_hz = exp.rate_hz
    travel0, travel1, p_next = np.empty((1, C)), np.empty((1, C)), np.empty((1, C))
    acc_q, acc_p = np.zeros(J), np.zeros(C)
    bounds = (0, *exp.breaks, exp.t.size)
    for first, end in zip(bounds[:-1], bounds[1:]):
        f0, f1 = first * S, (end - 1) * S
        p, receiver = restart(exp, model, data, chambers, u, first, qadr, dadr, offset, gain)
        path = np.zeros(0) if receiver is None else np.ascontiguousarray(receiver, float)
        p = np.ascontiguousarray(p, float)
        pressure[f0], velocity[f0] = p[0], data.qvel[dadr]
        chamber_travel(data.actuator_length, *geometry, travel0)
        set_actuation(p, data.qpos, data.qvel, qadr, dadr, *forces, law, active, data.ctrl, data.qfrc_applied)
        acc_q[:], acc_p[:] = 0.0, 0.0
        for f in range(f0, f1):
            mujoco.mj_step2(model, data)
            mujoco.mj_step1(model, data)
            fine_step(f, p, u[f:f + 1], travel0, travel1, data.actuator_length, *geometry, path, float(tab.supply_pa),
                      kargs, chambers.T, chambers.p_tube, chambers.supply_shift, acc_p, data.qpos, qadr, acc_q, p_next)
            p, p_next = p_next, p
            if (f + 1 - f0) % S == 0:
                dq, dqd, dp = corrections(exp, (f + 1) // S, acc_q / S if exp.averaged else data.qpos[qadr],
                                          acc_p / S if exp.averaged else p[0], offset, gain, rate_hz)
                data.qpos[qadr] += dq
                data.qvel[dadr] += dqd
                p += dp[None]
                acc_q[:], acc_p[:] = 0.0, 0.0
                mujoco.mj_step1(model, data)    # the next step starts from the corrected state
                chamber_travel(data.actuator_length, *geometry, travel0)
            set_actuation(p, data.qpos, data.qvel, qadr, dadr, *forces, law, active, data.ctrl, data.qfrc_applied)
            pressure[f + 1], velocity[f + 1] = p[0], data.qvel[dadr]
        if end < exp.t.size:        # the fine rows padding a join hold the part's last state
            for arr in (pressure, velocity):
                arr[f1 + 1:end * S] = arr[f1]
    if np.any(gain != 1.0):
        velocity *= gain        # as read
    return ObservedStates(pressure, velocity)


def observe_reference(exp: Experiment, mods: PneumaticMods, mech: MechMods | None = None) -> ObservedStates:
    """:func:`observe` as a readable Python loop: every 1 ms step MuJoCo's whole step, the
    actuators' lengths, the chamber model's step (pneumatic.ChamberModel.step) and replay.MechMods.torque."""
    robot = exp.robot
    model = robot.model if mech is None else mech.model(robot.model)
    data = mujoco.MjData(model)
    qadr, dadr = addresses(model, robot.joint_names)
    ids, tab, S = robot.actuator_ids, robot.tables, exp.n_sub
    chambers = ChamberModel(robot, mods, 1)
    u = effective_commands(exp, mods)
    F = exp.fine_t.size
    pressure = np.empty((F, tab.n_chambers))
    velocity = np.empty((F, len(qadr)))
    offset, gain = sensor_law(mech, len(qadr))
    rate_hz = exp.rate_hz
    bounds = (0, *exp.breaks, exp.t.size)
    for first, end in zip(bounds[:-1], bounds[1:]):
        f0, f1 = first * S, (end - 1) * S
        p, receiver = restart(exp, model, data, chambers, u, first, qadr, dadr, offset, gain)
        pressure[f0], velocity[f0] = p[0], data.qvel[dadr]
        travel0 = chambers.travel(lengths(model, data, ids))
        acc_q, acc_p = np.zeros(len(qadr)), np.zeros(tab.n_chambers)
        for f in range(f0, f1):
            data.ctrl[ids] = actuator_force(tab, p)[0]
            if mech is not None:
                tau = mech.torque(data.qpos[qadr][None], data.qvel[dadr][None])
                if tau is not None:
                    data.qfrc_applied[dadr] = tau[0]
            mujoco.mj_step(model, data)
            travel1 = chambers.travel(lengths(model, data, ids))
            chambers.follow_supply(receiver, np.array([f]))
            p = chambers.step(p, u[f:f + 1], travel0, travel1)
            travel0 = travel1
            acc_q += data.qpos[qadr]
            acc_p += p[0]
            if (f + 1 - f0) % S == 0:
                dq, dqd, dp = corrections(exp, (f + 1) // S, acc_q / S if exp.averaged else data.qpos[qadr],
                                          acc_p / S if exp.averaged else p[0], offset, gain, rate_hz)
                data.qpos[qadr] += dq
                data.qvel[dadr] += dqd
                p = p + dp[None]
                acc_q[:], acc_p[:] = 0.0, 0.0
                travel0 = chambers.travel(lengths(model, data, ids))
            pressure[f + 1], velocity[f + 1] = p[0], data.qvel[dadr]
        if end < exp.t.size:        # the fine rows padding a join hold the part's last state
            for arr in (pressure, velocity):
                arr[f1 + 1:end * S] = arr[f1]
    if np.any(gain != 1.0):
        velocity *= gain        # as read
    return ObservedStates(pressure, velocity)


def corrections(exp: Experiment, k: int, q_sim: np.ndarray, p_sim: np.ndarray, offset: np.ndarray,
                gain: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(angles [rad], velocities [rad/s], pressures [Pa]) to add at sample k: the gains of the
    module docstring times the innovations, the DAQ's sample less the simulated one (``q_sim``
    true angles, read through the sensors' ``offset`` and ``gain``; ``p_sim`` pressures)."""
    e_q = (exp.q[k] - q_sim - reading_error(q_sim, offset, gain - 1.0)) / gain   # in true angle
    e_p = exp.p[k] - p_sim
    return ANGLE_GAIN * e_q, VELOCITY_GAIN * rate_hz * e_q, PRESSURE_GAIN * e_p


def sensor_law(mech: MechMods | None, J: int) -> tuple[np.ndarray, np.ndarray]:
    """((J,) offsets [rad], (J,) gains 1 + scale error) of ``mech``'s angle sensors."""
    offset = np.zeros(J) if mech is None or mech.angle_offset_rad is None else np.asarray(mech.angle_offset_rad, float)
    scale = np.zeros(J) if mech is None or mech.angle_scale_error is None else np.asarray(mech.angle_scale_error, float)
    return offset, 1.0 + scale


def restart(exp: Experiment, model, data, chambers: ChamberModel, u: np.ndarray, first: int, qadr, dadr,
            offset: np.ndarray, gain: np.ndarray):
    """Set the observer at sample ``first``, a pooled part's start: the light spline's angles
    and its slope over the next millisecond (read back through the sensors' ``offset`` and
    ``gain``, :func:`sensor_law`), the pressures' spline, the supply's and lines'
    states there; returns
    (pressures (1, C), the supply receiver's path or None)."""
    f0, fq = first * exp.n_sub, exp.fine_q
    mujoco.mj_resetData(model, data)
    data.qpos[qadr] = true_angle(fq[f0], offset, gain - 1.0)
    data.qvel[dadr] = (fq[f0 + 1] - fq[f0]) / FINE_DT / gain
    mujoco.mj_forward(model, data)
    start = np.array([f0])
    if chambers.thermal.size:
        chambers.T = np.ascontiguousarray(gas_temperatures(exp, chambers.mods, u)[start])
    receiver = chambers.start_supply(exp, u, start)
    chambers.start_tubes(exp, u, start)
    return exp.p_at_t[first:first + 1].copy(), receiver


def lengths(model, data, ids) -> np.ndarray:
    """(1, n_act) the actuators' lengths at the data's present positions (mj_step leaves the
    ones of the step's start)."""
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    mujoco.mj_tendon(model, data)
    mujoco.mj_transmission(model, data)
    return data.actuator_length[ids][None]

