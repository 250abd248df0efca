"""The coupled simulation: the fluid layer writes cylinder forces into MuJoCo every step.

One physics step (DESIGN.md "The simulation step"), the state (q, qd, p) at t::

    mj_step1            positions, velocities and actuator lengths L(t)
    [fluid update]      pressures over the previous step, from L(t - dt) to L(t)
    forces              F(p(t)) -> data.ctrl
    mj_step2            accelerations and integration of q, qd to t + dt

so the chambers see exactly the volume change MuJoCo made (see chamber.chamber_geometry).
At the end of every ``step(n)`` the lengths at the new state are computed (mj_kinematics,
mj_comPos, mj_tendon, mj_transmission) and the last step's pressures integrated, so q, qd
and p are synchronous whenever control returns to Python.  After changing ``data.qpos`` by
hand, call :meth:`Simulation.sync` (or :meth:`reset` with ``qpos=``).
"""
from __future__ import annotations

import copy
import dataclasses
import warnings
from dataclasses import dataclass

import mujoco
import numpy as np

from .chamber import (
    actuator_force,
    chamber_geometry,
    fluid_step_areas,
    leak_flows,
    receiver_after,
    supply_pressure_after,
)
from .effects.backlash import addresses, backlash_model, drive_pairs
from .effects.effect_set import EffectSet
from .effects.pressure_sensor_offset import offset_at
from .effects.friction import friction_torque
from .effects.heat_transfer import thermal_step
from .effects.line_dynamics import rc_line_step, valve_into_tube
from . import arguments
from .errors import ArgumentError, ConfigError, PneumasimError
from .command_kernel import CLIPPED, OK
from .kernel import MUJOCO_FUNCTIONS, RUNNING, fluid_step_fast, pack
from .tube_kernel import rc_line_step_compiled
from .robot import Robot
from .valve_bank import ValveBank

COMMAND_RANGE_V = (0.0, 10.0)
#: commands further than this outside COMMAND_RANGE_V are not a saturated controller but a unit
#: slip (mV, a pressure, a percentage): they raise instead of being clipped
COMMAND_SLIP_V = 10.0


class CommandClippedWarning(UserWarning):
    """Valve commands outside 0-10 V were clipped (as a real valve driver would)."""


@dataclass
class Observation:
    """What the sensors report at ``time``; shapes in brackets.

    q, qd: (n_joint,) joint positions [rad or m] and velocities; p: (n_ch,) chamber
    pressures [Pa abs], chambers ordered a0, b0, a1, b1, ...
    """

    time: float
    q: np.ndarray
    qd: np.ndarray
    p: np.ndarray

    @property
    def p_a(self) -> np.ndarray:
        return self.p[0::2]

    @property
    def p_b(self) -> np.ndarray:
        return self.p[1::2]


class Simulation:
    """A robot's rigid-body (MuJoCo) and fluid-power state, stepped together.

    Args:
      robot: from :func:`pneumatics.robot.load_robot`.
      kernel: ``"fast"`` (compiled, default) or ``"reference"`` (numpy, readable, slow).
      effects: effects to switch on; default: the robot's own (``robot.effects``, a fitted
        model's) or none.
    """

    def __init__(self, robot: Robot, kernel: str = "fast", effects: EffectSet | None = None):
        if kernel not in ("fast", "reference"):
            raise PneumasimError(f"unknown kernel {kernel!r}; valid: fast, reference")
        self.robot = robot
        # a fitted robot carries its effects (load_robot(fitted=...)); given ones replace them
        self.effects = effects if effects is not None else (robot.effects or EffectSet())
        self.model = robot.model
        if self.effects.backlash:  # a drive hinge per joint with play: a model of its own
            self.model = backlash_model(robot, self.effects.backlash)
        if self.effects.end_stop:  # end stops narrow the joint limits of this simulation's own copy
            self.model = copy.copy(self.model)
            self.effects.apply_end_stops(robot, self.model)
        self.data = mujoco.MjData(self.model)
        self.kernel = kernel
        self._line_delay, line_volume = self.effects.line_arrays(robot)
        self.tables = dataclasses.replace(
            robot.tables, external_leak_m2=self.effects.chamber_array(robot, "external_leak_m2"),
            piston_leak_m2=self.effects.actuator_array(robot, "piston_leak_m2"),
            external_leak_g=self.effects.chamber_array(robot, "external_leak_laminar_kg_s_pa"),
            piston_leak_g=self.effects.actuator_array(robot, "piston_leak_laminar_kg_s_pa"),
            supply_droop_pa_per_kg_s=self.effects.supply_droop_pa_per_kg_s,
            supply_droop_pa_per_kg2_s2=self.effects.supply_droop_pa_per_kg2_s2,
            supply_droop_tau_s=self.effects.supply_droop_tau_s,
            supply_compressor=self.effects.compressor_array(),
            dead_volume=robot.tables.dead_volume + line_volume)
        self._p_offset = self.effects.chamber_array(robot, "pressure_offset_pa")
        self._p_drift, self._p_drift_tau = self.effects.drift_arrays(robot)
        self._drifting = bool(self._p_drift.any())  # decided once: observe() is on the control loop
        self._q_offset = self.effects.joint_array(robot, "angle_offset_rad")
        self._q_gain = 1.0 + self.effects.joint_array(robot, "angle_scale_error")  # effects.angle_sensor_offset
        self._gained = bool((self._q_gain != 1.0).any())  # decided once, as _drifting
        self._fric = self.effects.friction_table(robot, self.model)
        # heat_transfer: those chambers carry a gas temperature [K] and step in Python
        self._thermal, self._conductance = self.effects.heat_arrays(robot)
        self._thermal_any = bool(self._thermal.any())
        # line_dynamics (lumped_rc): those chambers' valves fill a tube at its own pressure, a
        # state stepped in Python after the chambers' step (_tube_update)
        tube_v, self._tube_tau = self.effects.tube_arrays(robot)
        self._tubes = np.nonzero(tube_v > 0)[0]
        self._tube_v = tube_v
        both = [f"{a}.{c}" for i, (a, c) in enumerate(robot.chamber_names) if tube_v[i] > 0 and self._thermal[i]]
        if both:
            raise ConfigError(f"chamber(s) {', '.join(both)}: a lumped line (line_dynamics, lumped_rc) and "
                              "heat_transfer at one chamber are not simulated together")
        self._compiled_args = None  # physics_steps' arguments, built at the first step
        self._step_call = None  # step_call.StepCall of them
        self._command_caller = None  # step_call.CommandCall of command_step_args
        #: physics steps run in one compiled loop (:func:`pneumatics.kernel.physics_steps`)
        self.compiled_steps = (kernel == "fast" and MUJOCO_FUNCTIONS is not None and not self._thermal_any
                               and self._tubes.size == 0)
        self.gas_temperature = np.full(robot.tables.n_chambers, robot.tables.gas.temperature_k)
        self._ids = robot.actuator_ids
        self._packed = pack(self.tables, self._ids, self.model.opt.timestep)
        #: the valves between the commands and the areas (valve_lag, valve_hysteresis, valve_leak,
        #: line delays); the clearance conductances go to the kernel's chamber table
        self.valves = ValveBank(robot, self.effects, self.tables, self.model.opt.timestep, self._line_delay,
                                self._packed[1][:, 14:16])
        self.spool = self.valves.spool  # command the spool follows (hysteresis)
        self.spool_position = self.valves.spool_position  # the spool after lag and line delay
        n_ch = self.tables.n_chambers
        self.pressure = np.full(n_ch, self.tables.room_pa)
        #: the lumped lines' tube pressures [Pa abs] (line_dynamics, lumped_rc; the chamber's elsewhere)
        self.tube_pressure = self.pressure.copy()
        self.command = self.valves.command  # as clipped [V]; each valve's null at first
        self.areas = self.valves.areas  # valve (supply, exhaust) areas [m^2] at self.command
        self._prev_length = np.zeros(self._ids.size)
        #: the valves' (supply, exhaust) land clearance conductances [kg/(s Pa)] at the spool
        #: (valve_leak, clearance form; zero without): a view of the kernel's chamber table
        self.clearance = self.valves.clearance
        # the link joints' addresses in this simulation's model (backlash adds drive joints)
        self._qadr, self._dadr = addresses(self.model, robot.joint_names)
        self._drive = drive_pairs(self.model, robot.joint_names)  # (k, gap, qpos adr, dof adr)
        self._clip_warned = False
        self.sums = np.zeros(n_ch + self.model.nq + self.model.nv)
        #: physics steps added into ``sums`` since the last :meth:`take_mean`
        self.steps_summed = 0
        self.reset()

    # -- state ---------------------------------------------------------------------------
    def reset(self, keyframe: str | None = "home", pressure_pa=None, qpos=None):
        """Reset MuJoCo to ``keyframe`` (None: the model's qpos0) and every chamber to
        ``pressure_pa`` [Pa abs] (scalar or (n_ch,); default: room pressure), the joints to
        ``qpos`` ((n_joint,) [rad or m]) if given.  Commands go to each valve's null.

        Raises :class:`~pneumatics.errors.ArgumentError` (or UnknownNameError for a keyframe
        the model lacks) before changing anything: pressures must be finite and within
        1 kPa .. 2 x the supply, joint positions finite and inside the joint ranges."""
        names = [f"{a}.{c}" for a, c in self.robot.chamber_names]
        key = None if keyframe is None else arguments.keyframe_id(self.model, keyframe)
        pressure = (None if pressure_pa is None else
                    arguments.chamber_pressures(pressure_pa, self.tables.n_chambers, self.tables.supply_pa, names))
        if qpos is not None:
            m = self.robot.model
            limited = [bool(m.jnt_limited[m.joint(n).id]) for n in self.robot.joint_names]
            qpos = arguments.joint_positions(qpos, self.robot.joint_names, self.robot.joint_range(), limited)
        mujoco.mj_resetData(self.model, self.data)
        if key is not None:
            mujoco.mj_resetDataKeyframe(self.model, self.data, key)
        if qpos is not None:
            self.data.qpos[self._qadr] = qpos
            k, _, drive_qadr, _ = self._drive
            self.data.qpos[drive_qadr] = self.data.qpos[self._qadr[k]]  # backlash: drive at the link
        self.pressure[:] = self.tables.room_pa if pressure is None else pressure
        self.tube_pressure[:] = self.pressure
        self.gas_temperature[:] = self.tables.gas.temperature_k
        self.valves.reset()
        glob = self._packed[2]  # supply pressure in effect (supply_droop): nominal, or the receiver's cut-out
        glob[13] = self.tables.supply_pa if self.tables.supply_compressor is None else self.tables.supply_compressor[3]
        glob[RUNNING] = 0.0
        self._clip_warned = False
        self.sums[:] = 0.0
        self.steps_summed = 0
        mujoco.mj_forward(self.model, self.data)
        self._prev_length[:] = self.data.actuator_length[self._ids]
        self.data.ctrl[self._ids] = actuator_force(self.tables, self.pressure)

    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def dt(self) -> float:
        return float(self.model.opt.timestep)

    def pressure_offset_now(self) -> np.ndarray:
        """(n_ch,) what the pressure sensors add to the true pressures now [Pa]: the offsets,
        with a warming-up sensor's drift at the simulation's time (pressure_sensor_offset)."""
        if not self._drifting:
            return self._p_offset
        return offset_at(self.time, self._p_offset, self._p_drift, self._p_drift_tau)

    def observe(self) -> Observation:
        """Noise-free, instantaneous sensor values now (with any sensor-offset effects)."""
        q, qd = self._angle_readings(self.data.qpos[self._qadr], self.data.qvel[self._dadr])
        return Observation(self.time, q, qd, self.pressure + self.pressure_offset_now())

    def _angle_readings(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What the angle sensors report for true angles ``q`` [rad] and rates ``qd`` [rad/s]
        (effects.angle_sensor_offset: gain, then offset; the rates take the gain alone)."""
        if self._gained:
            q, qd = self._q_gain * q, self._q_gain * qd
        return q + self._q_offset, qd

    def forces(self) -> np.ndarray:
        """(n_act,) actuator forces [N] (torques [N m] for vanes) from the current pressures."""
        return actuator_force(self.tables, self.pressure)

    # -- commands ------------------------------------------------------------------------
    def set_command(self, command_v):
        """Set all (n_ch,) valve commands [V], held until changed.

        NaN or inf raise; values outside 0-10 V are clipped like a real valve driver, with a
        :class:`CommandClippedWarning` once per run; values more than COMMAND_SLIP_V outside
        it (a unit slip) raise :class:`~pneumatics.errors.ArgumentError`."""
        try:
            u = np.array(command_v, dtype=float)
        except (TypeError, ValueError):
            raise ArgumentError(f"set_command(command_v): expected {self.command.size} numbers [V], "
                                f"got {command_v!r}") from None
        if u.shape != self.command.shape:
            raise ArgumentError(f"set_command(command_v): expected shape {self.command.shape} "
                                f"(one per chamber), got {u.shape}")
        if self.kernel == "fast" and self.valve_dynamics_free:
            status = self._command_call()(u)
            if status == CLIPPED:
                self.warn_clipped(u)
            if status in (OK, CLIPPED):
                return
            # NOT_FINITE, UNIT_SLIP: nothing was changed; the numpy path below names the fault
        if not np.all(np.isfinite(u)):
            bad = [f"{a}.{c}" for (a, c), ok in zip(self.robot.chamber_names, np.isfinite(u)) if not ok]
            raise ArgumentError(f"set_command(command_v): valve commands are NaN or inf for chamber(s) "
                                f"{', '.join(bad)} at t = {self.time:.3f} s")
        lo, hi = COMMAND_RANGE_V
        slip = (u < lo - COMMAND_SLIP_V) | (u > hi + COMMAND_SLIP_V)
        if slip.any():
            i = int(np.argmax(slip))
            a, c = self.robot.chamber_names[i]
            raise ArgumentError(f"set_command(command_v): {u[i]:.6g} V for chamber {a}.{c} is far outside the "
                                f"valve's {lo:g}-{hi:g} V (clipped within {COMMAND_SLIP_V:g} V of it): wrong unit?")
        if u.min() < lo or u.max() > hi:
            self.warn_clipped(u)
        self.valves.set(np.clip(u, lo, hi), self.time)  # with valve dynamics the areas follow step by step

    def warn_clipped(self, u):
        """A CommandClippedWarning for commands ``u`` outside COMMAND_RANGE_V, once per run."""
        if self._clip_warned:
            return
        self._clip_warned = True
        lo, hi = COMMAND_RANGE_V
        warnings.warn(f"valve commands outside {lo:g}-{hi:g} V (min {u.min():.3g}, max {u.max():.3g}) "
                      f"at t = {self.time:.3f} s are clipped; warned once per run",
                      CommandClippedWarning, stacklevel=3)

    # -- stepping ------------------------------------------------------------------------
    def play(self, commands, steps: int):
        """Play ``commands`` (P, n_ch) [V], each row held for ``steps`` physics steps, as
        ``set_command`` + ``step`` would, in one compiled call where the fast kernel allows
        (:mod:`pneumatics.playback`).  Returns a :class:`~pneumatics.playback.Playback` of the
        state at each row's end; a row of bad commands raises ArgumentError naming the row,
        with the rows before it played."""
        from .playback import play

        return play(self, commands, steps)

    def step(self, n: int = 1):
        """Advance ``n`` physics steps with the current commands.

        The pressures, qpos and qvel at each new instant are added into ``self.sums``
        (see :meth:`take_mean`), for DAQ-style sensor averaging.  ``n`` must be a whole
        number >= 1 (:class:`~pneumatics.errors.ArgumentError` otherwise)."""
        n = arguments.step_count(n, "Simulation.step")
        if self.valves.dynamic:
            for _ in range(n):
                self.valves.advance(self.time, self.dt)
                self._physics_steps(1)
            return
        self._physics_steps(n)

    def _physics_steps(self, n: int):
        m, d = self.model, self.data
        self.steps_summed += n
        if self.compiled_steps:
            args = self.physics_step_args()
            call = self._step_call
            if call is None or call.args is not args:
                from .step_call import StepCall  # compiles (or loads) the C entry point at the first step

                call = self._step_call = StepCall(args)
            call(n)
            return
        for k in range(n):
            mujoco.mj_step1(m, d)
            if k > 0:
                self._fluid_update()
                self._accumulate()
            d.ctrl[self._ids] = actuator_force(self.tables, self.pressure)
            self._apply_friction()
            mujoco.mj_step2(m, d)
        self.sync()
        self._accumulate()

    def physics_step_args(self) -> tuple:
        """The arguments of :func:`pneumatics.kernel.physics_steps` after ``n`` for this simulation,
        made once: MjData's array views stay valid for its life, and building them (and MjData's
        address lookups) every call cost a few us a period."""
        args = self._compiled_args
        if args is None or args[3] is not self.pressure or args[4] is not self.areas or args[13] is not self.sums:
            m, d = self.model, self.data
            act, ch, glob = self._packed
            args = self._compiled_args = (
                MUJOCO_FUNCTIONS, np.uint64(m._address), np.uint64(d._address), self.pressure, self.areas,
                self._prev_length, d.actuator_length, d.ctrl, act, ch, glob, d.qpos, d.qvel, self.sums,
                d.qfrc_applied, self._fric)
        return args

    def _command_call(self):
        """step_call.CommandCall of :meth:`command_step_args`, made once (the arrays it points
        at live as long as the simulation)."""
        call = self._command_caller
        if call is None or call.args[3] is not self.command or call.args[11] is not self.areas:
            from .step_call import CommandCall  # compiles (or loads) the C entry point at the first command

            call = self._command_caller = CommandCall(self.command_step_args())
        return call

    def command_step_args(self) -> tuple:
        """The arguments of :func:`pneumatics.command_kernel.command_step` after the commands, for
        this simulation's state arrays (only meaningful where ``valve_dynamics_free``)."""
        lo, hi = COMMAND_RANGE_V
        return self.valves.command_step_args(lo, hi, COMMAND_SLIP_V)

    @property
    def valve_dynamics_free(self) -> bool:
        """Whether a command sets the valve areas at once (no valve lag or line delay moving the
        spool between commands, no underlapped or clearance-sealed valve), so that command_step is the whole of
        set_command."""
        return not (self.valves.dynamic or self.valves.numpy_only)

    def sensor_maps(self) -> tuple:
        """(qpos addresses (n_joint,), qvel addresses (n_joint,), angle offsets (n_joint,) [rad],
        pressure offsets (n_ch,) [Pa], their warm-up drifts (n_ch,) [Pa] and time constants
        (n_ch,) [s], 0 without; the angle sensors' gains 1 + scale_error (n_joint,)): how
        :meth:`observe` and :meth:`take_mean` read the state."""
        return self._qadr, self._dadr, self._q_offset, self._p_offset, self._p_drift, self._p_drift_tau, self._q_gain

    def sync(self):
        """Actuator lengths at the current MuJoCo state; integrate the pressures up to it."""
        m, d = self.model, self.data
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_tendon(m, d)
        mujoco.mj_transmission(m, d)
        self._fluid_update()
        d.ctrl[self._ids] = actuator_force(self.tables, self.pressure)

    def _apply_friction(self):
        for dof, *coefficients in self._fric:
            v = self.data.qvel[int(dof)]
            self.data.qfrc_applied[int(dof)] = friction_torque(v, *coefficients)

    def _fluid_update(self):
        length = self.data.actuator_length[self._ids]
        if self._tubes.size:  # the lumped lines' chambers, again from the same start (_tube_update)
            start = (self.pressure.copy(), self._prev_length.copy(), float(self._packed[2][13]))
        if self._thermal.any():
            self._thermal_update(length)
        elif self.kernel == "fast":
            act, ch, glob = self._packed
            fluid_step_fast(self.pressure, self.areas, self._prev_length, self.data.actuator_length,
                            self.data.ctrl, act, ch, glob)
        else:
            self.pressure[:] = fluid_step_areas(self.tables, self.pressure, self.areas[:, 0], self.areas[:, 1],
                                                self._prev_length, length, self.dt, self._packed[2][13],
                                                self.clearance)
            self._supply_after(self.pressure)
            self._prev_length[:] = length
        if self._tubes.size:
            self._tube_update(*start, length)

    def _tube_update(self, p_old, prev_length, supply_pa: float, length):
        """The lumped lines' chambers over the step just taken, from its start: each valve fills
        its tube, the tube its chamber (effects.line_dynamics.rc_line_step), the chamber's leaks
        held at their start-of-step flows.  The supply droop's draw is the one the step above
        took, at the chamber pressures (the tube's differ from them by a few kPa)."""
        tab, gas = self.tables, self.tables.gas
        rt, n, room = gas.gas_constant_j_per_kg_k * gas.temperature_k, gas.polytropic_exponent, tab.room_pa
        volume, volume_rate = chamber_geometry(tab, prev_length, length, self.dt)
        other = leak_flows(tab, p_old)  # the clearance's flows enter the tube (valve_flow)
        for c in self._tubes:
            a_s, a_e = self.areas[c]
            g_s, g_e = self.clearance[c]
            if self.kernel == "fast":  # the compiled twin (pneumatics.tube_kernel)
                self.tube_pressure[c], self.pressure[c] = rc_line_step_compiled(
                    float(self.tube_pressure[c]), float(p_old[c]), float(volume[c]), float(volume_rate[c]),
                    float(self._tube_v[c]), float(self._tube_tau[c]), float(a_s), float(a_e), float(g_s), float(g_e),
                    supply_pa, float(other[c]), self._packed[2], self.dt)
                continue
            self.tube_pressure[c], self.pressure[c] = rc_line_step(
                float(self.tube_pressure[c]), float(p_old[c]), float(volume[c]), float(volume_rate[c]),
                float(self._tube_v[c]), float(self._tube_tau[c]), valve_into_tube(a_s, a_e, g_s, g_e, supply_pa, room, gas),
                float(other[c]), n, rt, self.dt)
        self.data.ctrl[self._ids] = actuator_force(tab, self.pressure)

    def _supply_after(self, p):
        """The reference path's supply pressure in effect for the next step (glob[13]; the
        compressor's switch in glob[RUNNING]), the valves drawing at chamber pressures p."""
        glob = self._packed[2]
        if self.tables.supply_compressor is None:
            glob[13] = supply_pressure_after(self.tables, p, self.areas[:, 0], glob[13], self.dt)
        else:
            glob[13], running = receiver_after(self.tables, p, self.areas[:, 0], glob[13], glob[RUNNING] > 0, self.dt)
            glob[RUNNING] = float(running)

    def _thermal_update(self, length):
        """The fluid step (eq. 9, compiled or numpy by ``kernel``) for every chamber, then the
        energy equation with the gas temperature (effects.heat_transfer.thermal_step) for the
        heat_transfer chambers, from the same start, over the same step."""
        tab, th = self.tables, self._thermal
        supply = self._packed[2][13]
        p_old, prev = self.pressure.copy(), self._prev_length.copy()
        if self.kernel == "fast":  # eq. 9 for all chambers, supply droop, lengths (compiled)
            act, ch, glob = self._packed
            fluid_step_fast(self.pressure, self.areas, self._prev_length, self.data.actuator_length,
                            self.data.ctrl, act, ch, glob)
        else:
            self.pressure[:] = fluid_step_areas(tab, p_old, self.areas[:, 0], self.areas[:, 1], prev, length,
                                                self.dt, supply, self.clearance)
            self._supply_after(self.pressure)  # at the step's end, as the compiled step and _fluid_update
            self._prev_length[:] = length
        volume, volume_rate = chamber_geometry(tab, prev, length, self.dt)
        extra = leak_flows(tab, p_old, self.clearance, supply)
        p_th, t_th = thermal_step(p_old[th], self.gas_temperature[th], volume[th], volume_rate[th],
                                  self.areas[th, 0], self.areas[th, 1], tab.gas, supply, tab.room_pa,
                                  self._conductance[th], tab.gas.temperature_k, self.dt, extra[th])
        self.pressure[th], self.gas_temperature[th] = p_th, t_th
        self.data.ctrl[self._ids] = actuator_force(tab, self.pressure)

    def _accumulate(self):
        n_ch, nq = self.pressure.size, self.model.nq
        self.sums[:n_ch] += self.pressure
        self.sums[n_ch:n_ch + nq] += self.data.qpos
        self.sums[n_ch + nq:] += self.data.qvel

    def take_mean(self) -> Observation:
        """Mean of the sensors over the steps since the last call (DAQ averaging), then restart.

        With no step since the last call, the instantaneous values."""
        if self.steps_summed == 0:
            return self.observe()
        n_ch, nq = self.pressure.size, self.model.nq
        mean = self.sums / self.steps_summed
        self.sums[:] = 0.0
        self.steps_summed = 0
        q, qd = self._angle_readings(mean[n_ch:n_ch + nq][self._qadr], mean[n_ch + nq:][self._dadr])
        return Observation(self.time, q, qd, mean[:n_ch] + self.pressure_offset_now())
