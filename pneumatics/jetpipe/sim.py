"""The jet-pipe actuator as a simulation: MuJoCo (piston, spring, stopper, force sensor) and the
valve/chamber ODE stepped together.

One physics step (MuJoCo timestep 0.5 ms, from models/jetpipe/jetpipe.xml)::

    q, qd                 piston position (chamber-1 length) and speed from MuJoCo
    valve + chambers      n_sub RK4 substeps of at most 0.1 ms with the current command held
                          (kernel "fast": numba; "reference": plant.rk4_step in numpy)
    data.ctrl             A_p (P1 - P2) -> the force actuator on the piston joint (eq. 13)
    mj_step               piston dynamics, contact with the stopper, spring

The force sensor reads what the stopper (and so the rod and tendon) carries: the piston's
contact force plus the spring's.  A controller is called every physics step with an
observation and holds its own output at its servo rate (controllers/force.py).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

import models

from .. import arguments
from ..errors import PneumasimError
from ..recording import Recording
from ..sim import Observation
from . import kernel as compiled
from .hysteresis import PlayHysteresis
from .linear import operating_point
from .params import JetpipeCfg, load_jetpipe_cfg
from .plant import I_CURRENT, I_P1, I_P2, I_X, rk4_step

MODEL = "jetpipe"
ACTUATOR = "piston"
MAX_FLUID_STEP_S = 1e-4
#: a current command beyond this many times the driver's limit is a unit slip (mA given as A),
#: not a saturated controller: it raises; inside it the driver saturates (kernel.rhs)
CURRENT_SLIP_FACTOR = 10.0
"""Largest RK4 substep [s] of the valve and chambers: h |lambda| <= 0.71 for the driver pole."""
_STOPPER_FACE_OFFSET_M = 0.004  # piston half-thickness + stopper half-thickness (jetpipe.xml)


@dataclass
class JetpipeObservation(Observation):
    """What the jet-pipe bench measures: q, qd (1,) piston [m, m/s], p (2,) chamber pressures
    [Pa abs] (chamber 1 = 'a', chamber 2 = 'b'), force_n (1,) force sensor [N], current_a (1,)
    coil current [A]."""

    force_n: np.ndarray = None
    current_a: np.ndarray = None


@dataclass
class JetpipeModel:
    """A compiled MJCF with its fluid parameters; ``cfg.cylinder.stopper_position_m`` placed."""

    name: str
    cfg: JetpipeCfg
    model: mujoco.MjModel


def build(cfg: JetpipeCfg | None = None, name: str = MODEL) -> JetpipeModel:
    """Load ``models/<name>/`` (jetpipe.xml and fluid.toml, or ``cfg`` if given) and place the
    rod stopper at x_s."""
    folder = models.folder(name)
    cfg = cfg or load_jetpipe_cfg(folder / "fluid.toml")
    path = Path(folder / f"{name}.xml")
    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as e:
        raise PneumasimError(f"{path}: {e}") from None
    stopper = model.body("stopper").id
    model.body_pos[stopper, 0] = cfg.cylinder.chamber1_length_m + _STOPPER_FACE_OFFSET_M
    return JetpipeModel(name, cfg, model)


class JetpipeSim:
    """The actuator's state (MuJoCo + valve/chamber states), stepped together.

    Args:
      jm: from :func:`build` (default: the shipped model).
      kernel: ``"fast"`` (numba) or ``"reference"`` (numpy plant.rk4_step, readable, slow).
      substeps: fluid RK4 substeps per MuJoCo step (default: steps of at most
        ``MAX_FLUID_STEP_S``).
    """

    def __init__(self, jm: JetpipeModel | None = None, kernel: str = "fast", substeps: int | None = None,
                 effects=None):
        if kernel not in ("fast", "reference"):
            raise PneumasimError(f"unknown kernel {kernel!r}; valid: fast, reference")
        self.jm = jm or build()
        self.cfg = self.jm.cfg
        self.model = self.jm.model
        self.data = mujoco.MjData(self.model)
        self.dt = float(self.model.opt.timestep)
        if substeps is None:
            substeps = int(np.ceil(self.dt / MAX_FLUID_STEP_S - 1e-9))
        if int(substeps) < 1:
            raise PneumasimError(f"substeps must be >= 1, got {substeps}")
        self.kernel, self.substeps = kernel, int(substeps)
        self.prm = compiled.pack(self.cfg)
        self.hyst = PlayHysteresis(self.cfg.hysteresis_half_width_n, self.cfg.hysteresis.n_operators)
        self._y7 = np.zeros(7)  # plant state + the lagged current of effects.py (valve_lag)
        self.y = self._y7[:6]
        self.effects, self._fx = None, None
        self.command_a = 0.0
        self._steady: dict[float, np.ndarray] = {}  # force -> steady state (operating_point is slow)
        self._sensor_adr = self.model.sensor("stopper_force").adr[0]
        if effects is not None:
            self.set_effects(effects)
        self.reset()

    def set_effects(self, effects):
        """Switch on a :class:`pneumatics.jetpipe.effects.JetpipeEffects` (None: off); call
        :meth:`reset` afterwards."""
        self.effects = effects
        self._fx = None if effects is None else effects.pack()
        half = self.cfg.hysteresis_half_width_n if effects is None else effects.half_width_n(self.cfg)
        self.hyst = PlayHysteresis(half, self.cfg.hysteresis.n_operators)

    # -- state ---------------------------------------------------------------------------
    def reset(self, force_n: float | None = None, hysteresis: bool = True):
        """Piston on the stopper; valve and chambers steady at ``force_n`` [N] (the paper's
        model, no hysteresis, gives the state) or at rest with room pressure (None).  The
        hysteresis starts demagnetised at the current's tip force.  ``force_n`` must be finite and
        within the largest steady pull or push, A_p (supply - room) (eq. 13)."""
        if force_n is not None:
            s = self.cfg.supply
            f_max = self.cfg.cylinder.piston_area_m2 * (s.supply_pa - s.room_pa)
            force_n = arguments.command_in_range(force_n, -f_max, f_max, "JetpipeSim.reset(force_n)", "N",
                                                 "the largest steady force, piston area x (supply - room)")
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[0] = self.cfg.cylinder.chamber1_length_m
        if force_n is None:
            self.y[:] = 0.0
            self.y[I_P1] = self.y[I_P2] = self.cfg.supply.room_pa
        else:
            key = float(force_n)
            if key not in self._steady:
                self._steady[key] = operating_point(key, self.cfg).state
            self.y[:] = self._steady[key]
        self.command_a = float(self.y[I_CURRENT])
        self.hyst.reset(self.cfg.driver.force_constant_n_per_a * self.y[I_CURRENT])
        self._y7[6] = self.y[I_CURRENT]  # the lagged current (effects.valve_lag) starts settled
        self._write_force()
        mujoco.mj_forward(self.model, self.data)
        # settle the contact (and sensor) on the initial force
        for _ in range(100):
            mujoco.mj_step(self.model, self.data)
        self.data.time = 0.0

    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def pressure(self) -> np.ndarray:
        """(2,) chamber pressures P1, P2 [Pa abs]."""
        return self.y[I_P1:I_P2 + 1].copy()

    @property
    def current_a(self) -> float:
        return float(self.y[I_CURRENT])

    @property
    def jet_abs_m(self) -> float:
        """x_jp,abs [m] (eq. 4)."""
        return float(self.y[I_X] + self.cfg.jet.offset_m)

    def pressure_force_n(self) -> float:
        """A_p (P1 - P2) [N] on the piston (eq. 13)."""
        return self.cfg.cylinder.piston_area_m2 * float(self.y[I_P1] - self.y[I_P2])

    def force_n(self) -> float:
        """The force sensor between piston and stopper [N] (pull positive)."""
        return -float(self.data.sensordata[self._sensor_adr])

    def observe(self) -> JetpipeObservation:
        d = self.data
        p, f = self.y[I_P1:I_P2 + 1].copy(), np.full(1, -d.sensordata[self._sensor_adr])
        if self.effects is not None:  # sensor offsets: what is observed only
            p, f = self.effects.observe(p, f)
        return JetpipeObservation(d.time, d.qpos[:1].copy(), d.qvel[:1].copy(), p, f,
                                  self.y[I_CURRENT:I_CURRENT + 1].copy())

    # -- stepping ------------------------------------------------------------------------
    def _write_force(self):
        self.data.ctrl[0] = self.pressure_force_n()

    def step(self, command_a: float | None = None, n: int = 1):
        """Advance n physics steps with the current command [A] held (None: keep the last).

        ``n`` >= 1 whole; ``command_a`` finite, saturated by the driver at +-current_limit_a and
        refused beyond CURRENT_SLIP_FACTOR times that (:class:`~pneumatics.errors.ArgumentError`)."""
        n = arguments.step_count(n, "JetpipeSim.step")
        if command_a is not None:
            slip = CURRENT_SLIP_FACTOR * self.cfg.driver.current_limit_a
            why = (f"the driver saturates at ±{self.cfg.driver.current_limit_a:g} A; beyond {CURRENT_SLIP_FACTOR:g} x "
                   "that is a unit slip, mA given as A?")
            self.command_a = arguments.command_in_range(command_a, -slip, slip, "JetpipeSim.step(command_a)", "A", why)
        h = self.dt / self.substeps
        for _ in range(n):
            q, qd = float(self.data.qpos[0]), float(self.data.qvel[0])
            if self._fx is not None:  # effects.py: the same step with the effects (7 states)
                from . import effects as fx_mod
                if self.kernel == "fast":
                    fx_mod.step(self._y7, self.hyst.state, self.hyst.radii, self.command_a, q, qd, h,
                                self.substeps, self.prm, self._fx)
                else:
                    fx_mod.reference_step(self._y7, self.hyst, self.command_a, q, qd, h, self.substeps,
                                          self.cfg, self._fx)
            elif self.kernel == "fast":
                compiled.step(self.y, self.hyst.state, self.hyst.radii, self.command_a, q, qd, h,
                              self.substeps, self.prm)
            else:
                for _ in range(self.substeps):
                    f_h = self.hyst(self.cfg.driver.force_constant_n_per_a * self.y[I_CURRENT])
                    self.y[:] = rk4_step(self.y, h, self.command_a, f_h, q, qd, self.cfg)
            self._write_force()
            mujoco.mj_step(self.model, self.data)

    def run(self, controller, duration_s: float, record_hz: float = 1000.0, reference=None) -> Recording:
        """Call ``controller(time, observation) -> (1,) current [A]`` every physics step for
        ``duration_s`` and record at ``record_hz``.  ``reference(t) -> desired force`` (or the
        controller's own ``reference``) adds a ``force_ref.piston`` column."""
        every = max(1, round(1.0 / (record_hz * self.dt)))
        n_steps = round(duration_s / self.dt)
        n_rows = n_steps // every + 1
        ref = reference or getattr(controller, "reference", None)
        cols = {k: np.empty(n_rows) for k in ("q.piston", "p_a.piston", "p_b.piston", "i.piston",
                                              "force.piston", "x_jet.piston", "i_cmd.piston")}
        if ref is not None:
            cols["force_ref.piston"] = np.empty(n_rows)
        t = np.empty(n_rows)
        controller.reset()
        t0 = self.time
        row = 0
        for k in range(n_steps + 1):
            obs = self.observe()
            obs.time = obs.time - t0
            cmd = float(np.asarray(controller(obs.time, obs)).reshape(-1)[0])
            if k % every == 0 and row < n_rows:
                t[row] = obs.time
                cols["q.piston"][row] = obs.q[0]
                cols["p_a.piston"][row], cols["p_b.piston"][row] = obs.p
                cols["i.piston"][row] = obs.current_a[0]
                cols["force.piston"][row] = obs.force_n[0]
                cols["x_jet.piston"][row] = self.y[I_X]  # what the PSD sees: no offset
                cols["i_cmd.piston"][row] = cmd
                if ref is not None:
                    cols["force_ref.piston"][row] = float(np.asarray(ref(obs.time)).reshape(-1)[0])
                row += 1
            if k < n_steps:
                self.step(cmd)
        meta = {"model": self.jm.name, "physics_dt_s": self.dt, "fluid_substeps": self.substeps,
                "kernel": self.kernel, "record_hz": record_hz, "generator": "pneumasim",
                "stopper_position_m": self.cfg.cylinder.stopper_position_m}
        return Recording(t[:row], {k: v[:row] for k, v in cols.items()}, meta, f"<{self.jm.name} run>")

    def rerun_robot(self):
        """What :class:`workflow.rerun_log.RerunLogger` reads of a robot, for this actuator
        (log runs with ``logger.log_recording(rec, prefix="", bodies=True)``)."""
        from ..robot_view import RobotView

        return RobotView(self.jm.name, self.model, ["piston"],
                          np.array([self.model.jnt_qposadr[self.model.joint("piston").id]]),
                          ["piston"], [("piston", "a"), ("piston", "b")])

    def with_cfg(self, **sections) -> JetpipeSim:
        """A new simulation with config sections replaced, e.g. ``cylinder={"stopper_position_m": .07}``."""
        cfg = self.cfg
        for sec, changes in sections.items():
            cfg = dataclasses.replace(cfg, **{sec: dataclasses.replace(getattr(cfg, sec), **changes)})
        return JetpipeSim(build(cfg, self.jm.name), self.kernel, self.substeps, self.effects)

    def with_stopper(self, stopper_position_m: float) -> JetpipeSim:
        """A new simulation with the rod stopper at x_s = ``stopper_position_m``."""
        return self.with_cfg(cylinder={"stopper_position_m": stopper_position_m})


class OpenLoopCurrent:
    """A current command as a function of time: ``fn(time_s) -> A`` (controller interface)."""

    def __init__(self, fn):
        self.fn = fn

    def reset(self):
        pass

    def __call__(self, time_s: float, observation) -> np.ndarray:
        return np.array([self.fn(time_s)])
