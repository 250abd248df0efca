"""A valve command's whole path, compiled: checks, clip, hysteresis, valve areas.

:meth:`pneumatics.sim.Simulation.set_command` runs once per control period; in numpy its dozen
small array operations cost about 30 µs on arm2, as much as ten compiled physics steps.  This
is the same arithmetic in one compiled call (about 1 µs), used by the fast kernel when no valve
lag or line delay moves the spool between periods.  The readable reference is the numpy path it
replaces (:func:`pneumatics.valve.valve_areas`, :func:`pneumatics.effects.valve_hysteresis.play_step`,
:func:`pneumatics.effects.valve_leak.leak_areas`); tests/test_command_kernel.py checks the two
against each other.  Bad input changes nothing and is left to the numpy path's error messages.
"""
from __future__ import annotations

import math

import numba
import numpy as np

OK, NOT_FINITE, UNIT_SLIP, CLIPPED = 0, 1, 2, 3


@numba.njit(cache=True)
def command_step(u, lo, hi, slip, command, spool, spool_position, hysteresis, rows, leak_s, leak_e,
                 leak_width, areas) -> int:
    """Set ``command`` (clipped to [lo, hi]), ``spool`` and ``spool_position`` (through the play of
    half-width ``hysteresis``) and ``areas`` (n, 2) (valve map of ``rows``, valve.VALVE_COLUMNS
    order, plus the valve leak's Gaussian) from commands ``u`` [V].  Returns OK, CLIPPED (done,
    some command was clipped), or NOT_FINITE / UNIT_SLIP (nothing changed)."""
    status = OK
    for i in range(u.size):
        x = u[i]
        if not np.isfinite(x):
            return NOT_FINITE
        if x < lo - slip or x > hi + slip:
            return UNIT_SLIP
        if x < lo or x > hi:
            status = CLIPPED
    for i in range(u.size):
        c = min(max(u[i], lo), hi)
        command[i] = c
        s = min(max(spool[i], c - hysteresis[i]), c + hysteresis[i])
        spool[i] = s
        spool_position[i] = s
        null, half, f, width, dead, gamma, a_s, a_e = rows[i, 0], rows[i, 1], rows[i, 2], rows[i, 3], \
            rows[i, 4], rows[i, 5], rows[i, 6], rows[i, 7]
        sn = min(max((s - null) / half, -1.0), 1.0)
        w = width / half
        d = dead / half
        leak = f * math.exp(-(sn / w) ** 2)
        ramp_s = max(0.0, (sn - d) / (1.0 - d)) ** gamma
        ramp_e = max(0.0, (-sn - d) / (1.0 - d)) ** gamma
        g = math.exp(-((s - null) / leak_width) ** 2)
        areas[i, 0] = a_s * (leak + (1.0 - f) * ramp_s) + leak_s[i] * g
        areas[i, 1] = a_e * (leak + (1.0 - f) * ramp_e) + leak_e[i] * g
    return status
