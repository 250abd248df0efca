"""A recorded valve-command sequence played through compiled code: :meth:`Simulation.play`.

A replay of a recording sets each control period's commands and steps the physics.  From
Python that is two calls into compiled code a period (``set_command``, ``step``), about 3 us,
some 8 % of an arm2 period of ten 1 ms steps.  :func:`play_rows` runs the whole sequence in
one call: per row, the command's path (:func:`pneumatics.command_kernel.command_step`: clip,
hysteresis, valve areas) and the period's physics steps (:func:`pneumatics.kernel.period_steps`),
the pressures of a period's last step waiting for the next row's ``mj_step1`` as in the
compiled closed loop (:func:`pneumatics.kernel.period_start`).  The states it returns are
those of ``set_command`` + ``step`` bit for bit (``tests/test_playback.py``).  Valve lag, line
delay, heat transfer and the reference kernel keep the Python loop, with the same results.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from . import arguments
from .command_kernel import CLIPPED, OK, command_step
from .errors import ArgumentError
from .kernel import period_start, period_steps


@dataclass(frozen=True)
class Playback:
    """The state at the end of every row of a played command sequence."""

    time_s: np.ndarray
    """(P,) simulation time [s]: the start time plus (row + 1) * steps * dt."""
    pressure_pa: np.ndarray
    """(P, n_ch) true chamber pressures [Pa] (absolute)."""
    qpos: np.ndarray
    """(P, nq) MuJoCo's qpos."""
    qvel: np.ndarray
    """(P, nv) MuJoCo's qvel."""


@numba.njit(cache=True, error_model="numpy")
def play_rows(commands, steps, out_p, out_q, out_v, command_args, step_args):
    """Rows of ``commands`` (P, n_ch) [V], each held for ``steps`` physics steps; the state at
    each row's end into ``out_*``.  ``command_args``: Simulation.command_step_args;
    ``step_args``: Simulation.physics_step_args.  Returns (rows played, status): P and OK or
    CLIPPED, or the row command_step refused (NOT_FINITE, UNIT_SLIP) with the simulation
    synchronous at the end of the rows before it."""
    pressure, qpos, qvel = step_args[3], step_args[11], step_args[12]
    n_rows = commands.shape[0]
    status = OK
    pending = False
    for k in range(n_rows + 1):
        if pending:  # the previous row's last step: its pressures, after this mj_step1
            period_start(*step_args)
        if k > 0:
            out_p[k - 1] = pressure
            out_q[k - 1] = qpos
            out_v[k - 1] = qvel
        if k == n_rows:
            break
        s = command_step(commands[k], *command_args)
        if s != OK and s != CLIPPED:
            return k, s
        if s == CLIPPED:
            status = CLIPPED
        catch_up = k == n_rows - 1  # synchronous at the end
        period_steps(steps, pending, catch_up, *step_args)
        pending = not catch_up
    return n_rows, status


def play(sim, commands, steps: int) -> Playback:
    """:meth:`Simulation.play`: ``commands`` (P, n_ch) [V], each row held ``steps`` steps."""
    u = _commands(sim, commands)
    steps = arguments.step_count(steps, "Simulation.play")
    n_rows = u.shape[0]
    times = sim.time + steps * sim.dt * np.arange(1, n_rows + 1)
    out = (np.empty((n_rows, sim.pressure.size)), np.empty((n_rows, sim.data.qpos.size)),
           np.empty((n_rows, sim.data.qvel.size)))
    if not (sim.kernel == "fast" and sim.compiled_steps and sim.valve_dynamics_free):
        for k, row in enumerate(u):
            _set_row(sim, row, k)
            sim.step(steps)
            out[0][k], out[1][k], out[2][k] = sim.pressure, sim.data.qpos, sim.data.qvel
        return Playback(times, *out)
    done, status = play_rows(u, steps, *out, sim.command_step_args(), sim.physics_step_args())
    sim.steps_summed += done * steps
    if status == CLIPPED:
        sim.warn_clipped(u[:done])
    if done < n_rows:
        _set_row(sim, u[done], done)  # the numpy path names the fault (and changes nothing)
        # the numpy path refuses what command_step refused; never return rows that were not played
        raise ArgumentError(f"play(commands): row {done}: refused by the compiled command path")
    return Playback(times, *out)


def _commands(sim, commands) -> np.ndarray:
    try:
        u = np.array(commands, dtype=float)
    except (TypeError, ValueError):
        raise ArgumentError(f"play(commands): expected numbers [V] of shape (rows, {sim.command.size})") from None
    if u.ndim != 2 or u.shape[1] != sim.command.size or u.shape[0] == 0:
        raise ArgumentError(f"play(commands): expected shape (rows >= 1, {sim.command.size}) "
                            f"(one column per chamber), got {u.shape}")
    return np.ascontiguousarray(u)


def _set_row(sim, row, k: int):
    try:
        sim.set_command(row)
    except ArgumentError as error:
        raise ArgumentError(f"play(commands): row {k}: {error}") from None
