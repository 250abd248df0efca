"""Each chamber's valve between its command and its open areas: what the spool does with a
command (a play of +-h, a first-order lag, a slew limit, a line's transport delay) and the
areas and leaks at the spool's position.

The valve effects (pneumatics.effects): valve_hysteresis (play_step), valve_lag (lag_decay,
slew_step_v), line_dynamics (the transport delay, modelled on the valve side as in Richer &
Hurmuzlu 2000's line model), valve_leak (a Gaussian leak near null, an underlap, or the lands'
laminar clearance).  The Simulation validates a command and clips it; the bank moves the spool.
"""
from __future__ import annotations

import numpy as np

from .effects.effect_set import EffectSet
from .effects.valve_hysteresis import play_step
from .effects.valve_lag import lag_decay, slew_step_v
from .effects.valve_leak import clearance_conductances, leak_areas, underlap_areas
from .robot import Robot
from .tables import FluidTables, valve_areas_table


class ValveBank:
    """The valves of a robot's chambers, with their effects.

    Args:
      robot: the robot (chamber names and order).
      effects: the effects switched on.
      tables: the simulation's tables (valve curves and nulls).
      timestep_s: the physics step [s].
      line_delay_s: (n_ch,) each chamber's line transport delay [s] (0: none).
      clearance: (n_ch, 2) where the lands' laminar conductances [kg/(s Pa)] are written: a
        view of the compiled kernel's chamber table, which reads them there.

    State (n_ch,) arrays, each one object for the bank's life (compiled steps hold views):
    ``command`` [V] as clipped, ``spool`` the command after the play, ``spool_position`` the
    spool after lag and delay; ``areas`` (n_ch, 2) the (supply, exhaust) areas [m^2].
    """

    def __init__(self, robot: Robot, effects: EffectSet, tables: FluidTables, timestep_s: float,
                 line_delay_s: np.ndarray, clearance: np.ndarray):
        self.tables, self.effects = tables, effects
        self.line_delay = line_delay_s
        self.lag = effects.chamber_array(robot, "valve_lag_s")
        # valve_lag (slew_limit): the most the spool moves in one physics step [V] (inf: no limit)
        self.slew_step = slew_step_v(effects.chamber_array(robot, "valve_slew_s"), timestep_s)
        self.slewing = bool(np.isfinite(self.slew_step).any())
        #: valve_lag / line_dynamics move the spool between commands: one physics step at a time
        self.dynamic = bool(np.any(self.lag > 0) or np.any(line_delay_s > 0) or self.slewing)
        # exact first-order decay over half a physics step (0 where the valve has no lag)
        self.lag_decay_half = lag_decay(self.lag, 0.5 * timestep_s)
        self.leak = effects.chamber_array(robot, "valve_leak_m2")
        exhaust = effects.chamber_array(robot, "valve_leak_exhaust_m2")
        given = np.array([f"{a}.{c}" in effects.valve_leak_exhaust_m2 for a, c in robot.chamber_names])
        self.leak_exhaust = np.where(given, exhaust, self.leak)  # symmetric unless given
        self.underlap_m2, self.underlap_v = effects.underlap_arrays(robot)
        # an underlapped valve's areas are set by the numpy path (update_areas); the compiled
        # command step knows the Gaussian leak alone.  valve_leak (clearance): the lands'
        # laminar conductances follow the spool, set there too
        self.clearance_g, self.clearance_v = effects.clearance_arrays(robot)
        #: whether the numpy path must set the areas (an underlap or clearance seal)
        self.numpy_only = bool(self.underlap_m2.any() or self.clearance_g.any())
        self.hysteresis = effects.chamber_array(robot, "valve_hysteresis_v")
        n_ch = tables.n_chambers
        self.command = np.array(tables.valve[:, 0])  # each valve's null
        self.spool = np.zeros(n_ch)
        self.spool_position = np.zeros(n_ch)
        self.areas = np.zeros((n_ch, 2))
        self.clearance = clearance
        self.history = [(-np.inf, self.spool.copy())]  # (time set, spool target) for line delays

    def reset(self) -> None:
        """Every command, spool and position at its valve's null; the areas there."""
        self.command[:] = self.tables.valve[:, 0]
        self.spool[:] = self.command
        self.spool_position[:] = self.command
        self.history = [(-np.inf, self.spool.copy())]
        self.update_areas()

    def set(self, command_v: np.ndarray, time_s: float) -> None:
        """Take (n_ch,) commands [V] already validated and clipped: the spool follows them
        through the play of +-h (valve_hysteresis); with valve dynamics the target is kept for
        :meth:`advance`, else the areas follow at once."""
        self.command[:] = command_v
        self.spool[:] = play_step(self.spool, self.command, self.hysteresis)
        if self.dynamic:
            self.history.append((time_s, self.spool.copy()))
            return
        self.spool_position[:] = self.spool
        self.update_areas()

    def advance(self, time_s: float, dt_s: float) -> None:
        """valve_lag and line_dynamics over the physics step from ``time_s``: the spool target
        delayed by each chamber's line delay, then the exact first-order lag, evaluated at
        mid-step, its step bounded by the slew limit."""
        t, dt, hist = time_s, dt_s, self.history
        while len(hist) > 1 and hist[1][0] + self.line_delay.max() <= t - dt:
            hist.pop(0)  # entries every chamber has passed
        target = hist[0][1].copy()
        for t_set, u in hist[1:]:
            due = t_set + self.line_delay <= t + 1e-9
            target[due] = u[due]
        x, decay = self.spool_position, self.lag_decay_half
        if self.slewing:  # the slew limit bounds the step the lag asks for (a solenoid's force bounds the speed)
            step = np.clip(target + (x - target) * decay ** 2 - x, -self.slew_step, self.slew_step)
            mid = x + 0.5 * step
            x += step
        else:
            mid = target + (x - target) * decay
            x[:] = target + (x - target) * decay ** 2
        self.update_areas(mid)

    def update_areas(self, spool: np.ndarray | None = None) -> None:
        """The (supply, exhaust) areas [m^2] and clearance conductances at ``spool`` [V]
        (default: the spool's position)."""
        spool = self.spool_position if spool is None else spool
        a_s, a_e = valve_areas_table(self.tables, spool)
        null = self.tables.valve[:, 0]
        if self.leak.any() or self.leak_exhaust.any():  # valve_leak: the spool does not shut near null
            leak_s, leak_e = leak_areas(spool, null, self.leak, self.leak_exhaust, self.effects.valve_leak_width_v)
            a_s, a_e = a_s + leak_s, a_e + leak_e
        if self.numpy_only:  # valve_leak (underlap): the opening land stays open by the underlap
            lap_s, lap_e = underlap_areas(spool, null, self.underlap_m2, self.underlap_v)
            a_s, a_e = a_s + lap_s, a_e + lap_e
            # valve_leak (clearance): each land's laminar conductance over its covered length
            self.clearance[:, 0], self.clearance[:, 1] = clearance_conductances(spool, null, self.clearance_g,
                                                                                self.clearance_v)
        self.areas[:, 0], self.areas[:, 1] = a_s, a_e

    def command_step_args(self, low_v: float, high_v: float, slip_v: float) -> tuple:
        """The arguments of :func:`pneumatics.command_kernel.command_step` after the commands
        (only meaningful where neither ``dynamic`` nor ``numpy_only``)."""
        return (low_v, high_v, slip_v, self.command, self.spool, self.spool_position, self.hysteresis,
                self.tables.valve, self.leak, self.leak_exhaust, self.effects.valve_leak_width_v, self.areas)
