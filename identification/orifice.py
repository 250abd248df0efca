"""Orifice-area calibration from static-volume pressure transients (paper 002 §IV-B.3, eqs. 10-12).

With a chamber's volume held constant (joint braced), its pressure obeys (002 eq. 10, our
eq. 9 with dV/dt = 0 and the polytropic exponent n of the chamber model)::

    dp/dt = n R T / V * (a_c(v) f(P_c, p) - a_r(v) f(p, P_r))

where f(p_up, p_down) is the isentropic mass flow per unit area (002 eqs. 7-8;
:func:`pneumatics.medium.unit_flow`).  For each valve command v the unknowns a_c(v)/V and
a_r(v)/V enter linearly, so one linear least-squares fit per chamber and command, on the
pressure and its smoothing-spline derivative, recovers them with standard errors
(:func:`identification.base.lsq.linear`).  Every command is applied twice, from room pressure and
from supply pressure, so that both the charging and the discharging branch are excited; near
the null, where both ports leak, the pair also fixes the ratio through the asymptote.

Absolute areas then follow either from the chamber volume V (geometry:
dead volume + piston area x travel at the braced pose) or, as the paper does, from two areas
known from the valve's data sheet (eqs. 11-12)::

    a_c(v) = a_c(10) (a_c(v)/V) / (a_c(10)/V),      a_r(v) = a_r(0) (a_r(v)/V) / (a_r(0)/V)

:func:`static_volume_transients` runs the experiment on a simulated robot: every joint is
locked by a stiff joint equality (MuJoCo ``mjEQ_JOINT``, added with ``MjSpec``, the kind of
arm2's ``brace_shoulder``) and all chambers of the robot are excited at once, so the
humanoid's 76 valves cost no more runs than arm2's four.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import mujoco
import numpy as np

from pneumatics.chamber import chamber_geometry
from pneumatics.errors import PneumasimError
from pneumatics.medium import orifice_flow
from pneumatics.robot import Robot
from pneumatics.sim import Simulation
from pneumatics.valve import valve_areas

from identification.base.lsq import linear
from identification.base.smoothing import discrepancy_lambda, smoothing_spline

#: default command grid [V]: coarse where the valve is open, 0.1 V steps around the null
#: (null offsets of +-0.15 V and dead bands of 0.1-0.25 V must be resolved)
DEFAULT_COMMANDS_V = np.array([0.0, 1.0, 2.0, 3.0, 3.5, 4.0, 4.25, 4.5, 4.6, 4.7, 4.8, 4.9, 5.0, 5.1,
                               5.2, 5.3, 5.4, 5.5, 5.75, 6.0, 6.5, 7.0, 8.0, 9.0, 10.0])
#: commands this close to 5 V give slow transients (null leak, dead band): longer, slower records
SLOW_BAND_V = 0.8
MID_BAND_V = 2.0
#: (duration [s], rate [Hz]) of a transient record: near the null / partly open / open
SCHEDULE = {"slow": (3.0, 200.0), "mid": (1.0, 500.0), "open": (0.4, 1000.0)}
#: recorded samples dropped after the command step (DAQ averaging straddles the step)
SKIP_SAMPLES = 2


@dataclass
class Transient:
    """One static-volume record: every chamber at ``command_v`` from initial pressure ``p0_pa``.

    time: (T,) s, mid-points of the DAQ averaging periods; pressure: (T, n_ch) Pa abs;
    command_v: (n_ch,) V."""

    time: np.ndarray
    pressure: np.ndarray
    command_v: np.ndarray
    p0_pa: float


@dataclass
class OrificeCalibration:
    """Recovered orifice areas per chamber (rows, chambers a0, b0, a1, ...) and command (columns).

    Attributes:
      commands_v: (n_cmd,) command grid [V].
      charge_per_volume, discharge_per_volume: (n_ch, n_cmd) a_c(v)/V, a_r(v)/V [1/m].
      charge_se, discharge_se: (n_ch, n_cmd) their standard errors [1/m].
      volume_m3: (n_ch,) chamber volumes at the braced pose, if known.
      chamber_names: (n_ch,) ``(actuator, 'a'|'b')``.
    """

    commands_v: np.ndarray
    charge_per_volume: np.ndarray
    discharge_per_volume: np.ndarray
    charge_se: np.ndarray
    discharge_se: np.ndarray
    volume_m3: np.ndarray | None = None
    chamber_names: list | None = None

    def areas(self, volume_m3=None):
        """(a_c, a_r), each (n_ch, n_cmd) [m^2], scaled by the chamber volumes."""
        v = self.volume_m3 if volume_m3 is None else np.asarray(volume_m3, float)
        if v is None:
            raise PneumasimError("orifice calibration: chamber volumes unknown; pass volume_m3 or use anchored()")
        return self.charge_per_volume * v[:, None], self.discharge_per_volume * v[:, None]

    def area_stderr(self, volume_m3=None):
        """Standard errors of :meth:`areas`, each (n_ch, n_cmd) [m^2]."""
        v = self.volume_m3 if volume_m3 is None else np.asarray(volume_m3, float)
        return self.charge_se * v[:, None], self.discharge_se * v[:, None]

    def anchored(self, charge_full_m2, discharge_full_m2):
        """Paper 002 eqs. 11-12: areas from the known a_c at the highest command and a_r at the
        lowest (each (n_ch,), e.g. from the valve's data sheet); volumes not needed."""
        c = np.asarray(charge_full_m2, float)[:, None] * self.charge_per_volume / self.charge_per_volume[:, -1:]
        r = np.asarray(discharge_full_m2, float)[:, None] * self.discharge_per_volume / self.discharge_per_volume[:, :1]
        return c, r


# -- the experiment --------------------------------------------------------------------------

def locked_robot(robot: Robot, qpos=None, solref=(0.002, 1.0)) -> Robot:
    """The robot with every joint braced at ``qpos`` (default: the ``home`` keyframe, else 0)
    by a stiff joint equality, so that every chamber keeps its volume."""
    if robot.mjcf_path is None:
        raise PneumasimError(f"{robot.name}: locking joints needs the MJCF file")
    spec = mujoco.MjSpec.from_file(str(robot.mjcf_path))
    m0 = robot.model
    if qpos is None:
        qpos = m0.key("home").qpos[robot.qpos_index] if m0.nkey else np.zeros(len(robot.joint_names))
    for name, q, adr in zip(robot.joint_names, qpos, robot.qpos_index):
        eq = spec.add_equality()
        eq.type = mujoco.mjtEq.mjEQ_JOINT
        eq.name = f"lock_{name}"
        eq.name1 = name
        eq.data[0] = q - m0.qpos0[adr]  # joint equality: q - qpos0 = polycoef[0]
        eq.solref = list(solref)
    model = spec.compile()
    return dataclasses.replace(robot, model=model)


def chamber_volumes(sim: Simulation) -> np.ndarray:
    """(n_ch,) chamber volumes [m^3] at the simulation's current pose."""
    length = sim.data.actuator_length[sim.robot.actuator_ids]
    return chamber_geometry(sim.tables, length, length, sim.dt)[0]


def record_schedule(command_v: float) -> tuple[float, float]:
    """(duration [s], rate [Hz]) of the records at command ``command_v``."""
    off = abs(command_v - 5.0)
    return SCHEDULE["slow" if off <= SLOW_BAND_V else "mid" if off <= MID_BAND_V else "open"]


def static_volume_transients(robot: Robot, commands_v=DEFAULT_COMMANDS_V, *, noise: bool = True,
                             seed: int = 0, duration_scale: float = 1.0, effects=None, kernel: str = "fast"):
    """Run the calibration experiment of paper 002 §IV-B.3 on a simulated robot.

    Every joint is braced (:func:`locked_robot`); for each command v, all chambers start at
    room pressure, then at supply pressure, with every valve at v, and the DAQ records the
    pressures (averaged over each period, plus the model's sensor noise scaled to the record
    rate: sigma_100Hz * sqrt(rate / 100 Hz)).

    Returns:
      (transients, volume_m3 (n_ch,)): a list of :class:`Transient`, two per command.
    """
    locked = locked_robot(robot)
    sim = Simulation(locked, kernel=kernel, effects=effects)
    sim.reset()
    volume = chamber_volumes(sim)
    rng = np.random.default_rng(seed)
    tab = sim.tables
    sd100 = locked.fluid.sensors.pressure_noise_pa if noise else 0.0
    out = []
    for v in np.asarray(commands_v, float):
        duration, rate = record_schedule(v)
        duration *= duration_scale
        n_sub = round(1.0 / (rate * sim.dt))
        n_rows = round(duration * rate)
        for p0 in (tab.room_pa, tab.supply_pa):
            sim.reset(pressure_pa=p0)
            sim.set_command(np.full(tab.n_chambers, v))
            sim.take_mean()
            p = np.empty((n_rows, tab.n_chambers))
            for k in range(n_rows):
                sim.step(n_sub)
                p[k] = sim.take_mean().p
            p += rng.normal(0.0, sd100 * np.sqrt(rate / 100.0), p.shape)
            t = (np.arange(n_rows) + 0.5) / rate  # each mean belongs to its period's middle
            out.append(Transient(t[SKIP_SAMPLES:], p[SKIP_SAMPLES:], sim.command.copy(), float(p0)))
    return out, volume


# -- the regression --------------------------------------------------------------------------

def smoothing_lambdas(transients) -> list[float]:
    """Smoothing-spline lambda of each transient, by the discrepancy principle
    (:mod:`identification.base.smoothing`).  Records of one rate share one lambda, found on the
    chamber with the fastest transient among them, so that no chamber is over-smoothed
    (and the bisection runs once per rate, not once per record)."""
    by_rate: dict[float, list[int]] = {}
    for i, tr in enumerate(transients):
        by_rate.setdefault(round(1.0 / np.median(np.diff(tr.time)), 3), []).append(i)
    lam = [0.0] * len(transients)
    for idx in by_rate.values():
        speed = [np.abs(np.diff(transients[i].pressure, axis=0)).max(axis=0) for i in idx]
        best = int(np.argmax([s.max() for s in speed]))
        tr = transients[idx[best]]
        value = discrepancy_lambda(tr.time, tr.pressure[:, int(np.argmax(speed[best]))], block=600)
        for i in idx:
            lam[i] = value
    return lam


def smoothed_rate(tr: Transient, lam: float):
    """(p_smooth, dp/dt), each (T, n_ch), from one smoothing spline over all chambers."""
    s = smoothing_spline(tr.time, tr.pressure, lam=lam)
    return s(tr.time), s.derivative(1)(tr.time)


def fit_orifice_areas(transients, gas, supply_pa: float, room_pa: float, *, volume_m3=None,
                      chamber_names=None) -> OrificeCalibration:
    """Least-squares a_c(v)/V and a_r(v)/V of every chamber at every command (002 eq. 10).

    Args:
      transients: :class:`Transient` records; those with the same command are pooled.
      gas: :class:`pneumatics.medium.GasCfg` (R, T and the chamber's polytropic exponent n).
      supply_pa, room_pa: P_c and P_r [Pa abs].
    Returns:
      :class:`OrificeCalibration` over the sorted distinct commands.
    """
    if not transients:
        raise PneumasimError("orifice calibration: no transients given")
    n_ch = transients[0].pressure.shape[1]
    rt_n = gas.polytropic_exponent * gas.gas_constant_j_per_kg_k * gas.temperature_k
    groups: dict[float, list] = {}
    for tr in transients:
        cmd = np.round(tr.command_v, 6)
        if np.ptp(cmd) > 1e-9:
            raise PneumasimError("orifice calibration: each transient must hold one command on all chambers")
        groups.setdefault(float(cmd[0]), []).append(tr)
    commands = np.array(sorted(groups))
    shape = (n_ch, commands.size)
    c_v, r_v, c_se, r_se = (np.zeros(shape) for _ in range(4))
    lams = dict(zip(map(id, transients), smoothing_lambdas(transients)))
    for k, v in enumerate(commands):
        rows = []
        for tr in groups[v]:
            p, pdot = smoothed_rate(tr, lams[id(tr)])
            f_c = orifice_flow(1.0, supply_pa, p, gas)[0]  # into the chamber, per m^2
            f_r = orifice_flow(1.0, p, room_pa, gas)[0]    # out to the room, per m^2
            rows.append((f_c * rt_n, -f_r * rt_n, pdot))
        fc, fr, pd = (np.concatenate([r[i] for r in rows]) for i in range(3))
        for i in range(n_ch):
            fit = linear(np.column_stack([fc[:, i], fr[:, i]]), pd[:, i], ["a_c_per_v", "a_r_per_v"])
            c_v[i, k], r_v[i, k] = fit.values
            c_se[i, k], r_se[i, k] = fit.stderr
    return OrificeCalibration(commands, c_v, r_v, c_se, r_se,
                              None if volume_m3 is None else np.asarray(volume_m3, float), chamber_names)


def calibrate_robot(robot: Robot, commands_v=DEFAULT_COMMANDS_V, *, noise: bool = True, seed: int = 0,
                    duration_scale: float = 1.0, effects=None, kernel: str = "fast") -> OrificeCalibration:
    """The whole procedure on a simulated robot: experiment, then regression."""
    transients, volume = static_volume_transients(robot, commands_v, noise=noise, seed=seed,
                                                  duration_scale=duration_scale, effects=effects, kernel=kernel)
    tab = robot.tables
    return fit_orifice_areas(transients, tab.gas, tab.supply_pa, tab.room_pa, volume_m3=volume,
                             chamber_names=robot.chamber_names)


# -- comparison with the model ---------------------------------------------------------------

def true_areas(valve_rows: np.ndarray, commands_v: np.ndarray):
    """The model's maps (``pneumatics.valve``): (a_c, a_r), each (n_ch, n_cmd) [m^2]."""
    rows = np.asarray(valve_rows, float)
    cmd = np.asarray(commands_v, float)
    a_s, a_e = valve_areas(np.broadcast_to(cmd, (rows.shape[0], cmd.size)), rows[:, None, :])
    return a_s, a_e


def relative_errors(estimate, truth, open_fraction: float = 0.1) -> np.ndarray:
    """|estimate - truth| / truth where the true area is at least ``open_fraction`` of that
    valve's largest (relative errors of a closed port mean nothing); flat array."""
    truth = np.asarray(truth, float)
    mask = truth >= open_fraction * truth.max(axis=1, keepdims=True)
    return np.abs(np.asarray(estimate)[mask] - truth[mask]) / truth[mask]


def calibration_errors(cal: OrificeCalibration, valve_rows: np.ndarray, open_fraction: float = 0.1) -> dict:
    """Relative errors of both branches against the model's true maps (flat arrays):
    ``{"volume": ..., "anchored": ..., "closed_abs_frac": ...}`` -- areas scaled by the chamber
    volumes; scaled by eqs. 11-12 with the true full-open areas; and, where the port is nearly
    closed, the absolute error as a fraction of the valve's full area."""
    t_c, t_r = true_areas(valve_rows, cal.commands_v)
    e_c, e_r = cal.areas()
    a_c, a_r = cal.anchored(t_c[:, -1], t_r[:, 0])
    closed = []
    for est, tr in ((e_c, t_c), (e_r, t_r)):
        full = tr.max(axis=1, keepdims=True)
        m = tr < open_fraction * full
        closed.append((np.abs(est - tr) / full)[m])
    return {"volume": np.concatenate([relative_errors(e_c, t_c, open_fraction), relative_errors(e_r, t_r, open_fraction)]),
            "anchored": np.concatenate([relative_errors(a_c, t_c, open_fraction), relative_errors(a_r, t_r, open_fraction)]),
            "closed_abs_frac": np.concatenate(closed)}
