"""The coupled simulation: the fluid layer writes cylinder forces into MuJoCo every step.

One physics step (DESIGN.md "The simulation step")::

    mj_step1            positions, velocities, actuator lengths and velocities at t
    fluid update        forces from p(t) -> data.ctrl;  p(t) -> p(t + dt)  (chamber.py / kernel.py)
    mj_step2            accelerations and integration to t + dt

Splitting ``mj_step`` this way makes the fluid layer see the actuator length of the current
state (after a plain ``mj_step`` ``data.actuator_length`` belongs to the previous one).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import mujoco
import numpy as np

from .chamber import actuator_force, fluid_step
from .tables import valve_areas_table
from .errors import PneumasimError
from .kernel import fluid_step_fast, pack, run_steps_compiled
from .robot import Robot

COMMAND_RANGE_V = (0.0, 10.0)


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
    """

    def __init__(self, robot: Robot, kernel: str = "fast"):
        if kernel not in ("fast", "reference"):
            raise PneumasimError(f"unknown kernel {kernel!r}; valid: fast, reference")
        self.robot = robot
        self.model = robot.model
        self.data = mujoco.MjData(self.model)
        self.kernel = kernel
        self.tables = robot.tables
        n_ch = self.tables.n_chambers
        self.pressure = np.full(n_ch, self.tables.room_pa)
        self.command = np.array(self.tables.valve[:, 0])  # each valve's null
        self.areas = np.zeros((n_ch, 2))  # valve (supply, exhaust) areas [m^2] at self.command
        self._ids = robot.actuator_ids
        self._packed = pack(self.tables, self._ids, self.model.opt.timestep)
        self._qadr = robot.qpos_index
        self._dadr = robot.dof_index
        self._clip_warned = False
        self.reset()

    # -- state ---------------------------------------------------------------------------
    def reset(self, keyframe: str | None = "home", pressure_pa=None, qpos=None):
        """Reset MuJoCo to ``keyframe`` (if the model has it) and every chamber to ``pressure_pa``
        (scalar or (n_ch,); default: room pressure).  Commands go to each valve's null."""
        mujoco.mj_resetData(self.model, self.data)
        if keyframe is not None and self.model.nkey:
            try:
                mujoco.mj_resetDataKeyframe(self.model, self.data, self.model.key(keyframe).id)
            except KeyError:
                pass
        if qpos is not None:
            self.data.qpos[self._qadr] = qpos
        self.pressure[:] = self.tables.room_pa if pressure_pa is None else pressure_pa
        self.command[:] = self.tables.valve[:, 0]
        self._update_areas()
        self._clip_warned = False
        mujoco.mj_forward(self.model, self.data)
        self.data.ctrl[self._ids] = actuator_force(self.tables, self.pressure)

    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def dt(self) -> float:
        return float(self.model.opt.timestep)

    def observe(self) -> Observation:
        """Exact (noise-free, instantaneous) sensor values now."""
        return Observation(self.time, self.data.qpos[self._qadr].copy(),
                           self.data.qvel[self._dadr].copy(), self.pressure.copy())

    def forces(self) -> np.ndarray:
        """(n_act,) actuator forces [N] (torques [N m] for vanes) from the current pressures."""
        return actuator_force(self.tables, self.pressure)

    # -- commands ------------------------------------------------------------------------
    def set_command(self, command_v):
        """Set all (n_ch,) valve commands [V], held until changed.

        NaN or inf raise; values outside 0-10 V are clipped like a real valve driver, with a
        :class:`CommandClippedWarning` once per run."""
        u = np.asarray(command_v, float)
        if u.shape != self.command.shape:
            raise PneumasimError(f"valve commands: expected shape {self.command.shape} "
                                 f"(one per chamber), got {u.shape}")
        if not np.all(np.isfinite(u)):
            bad = [f"{a}.{c}" for (a, c), ok in zip(self.robot.chamber_names, np.isfinite(u)) if not ok]
            raise PneumasimError(f"valve commands are NaN or inf for chamber(s) {', '.join(bad)} "
                                 f"at t = {self.time:.3f} s")
        lo, hi = COMMAND_RANGE_V
        if (u.min() < lo or u.max() > hi) and not self._clip_warned:
            self._clip_warned = True
            warnings.warn(f"valve commands outside {lo:g}-{hi:g} V (min {u.min():.3g}, max {u.max():.3g}) "
                          f"at t = {self.time:.3f} s are clipped; warned once per run",
                          CommandClippedWarning, stacklevel=2)
        np.clip(u, lo, hi, out=self.command)
        self._update_areas()

    def _update_areas(self):
        a_s, a_e = valve_areas_table(self.tables, self.command)
        self.areas[:, 0], self.areas[:, 1] = a_s, a_e

    # -- stepping ------------------------------------------------------------------------
    def step(self, n: int = 1):
        """Advance ``n`` physics steps with the current commands."""
        m, d = self.model, self.data
        step1, step2 = mujoco.mj_step1, mujoco.mj_step2
        if self.kernel == "fast":
            act, ch, glob = self._packed
            ids = self._ids
            contiguous = np.array_equal(ids, np.arange(ids.size))
            if contiguous and run_steps_compiled is not None:
                run_steps_compiled(n, m._address, d._address, self.pressure, self.areas,
                                   d.actuator_length, d.actuator_velocity, d.ctrl, act, ch, glob)
                return
            for _ in range(n):
                step1(m, d)
                length = d.actuator_length if contiguous else d.actuator_length[ids]
                velocity = d.actuator_velocity if contiguous else d.actuator_velocity[ids]
                fluid_step_fast(self.pressure, self.areas, length, velocity, d.ctrl, act, ch, glob)
                step2(m, d)
        else:
            for _ in range(n):
                step1(m, d)
                d.ctrl[self._ids] = actuator_force(self.tables, self.pressure)
                self.pressure[:] = fluid_step(self.tables, self.pressure, self.command,
                                              d.actuator_length[self._ids], d.actuator_velocity[self._ids],
                                              self.dt)
                step2(m, d)
