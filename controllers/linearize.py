"""Per-valve linearising transform: every valve made to look like one canonical sigmoid
(paper 002 §VI: "a non-linear transformation which compensates for the unique characteristics
of every valve, resulting in a canonical sigmoid relationship between command signals and
(inferred) orifice areas ... transparent to the rest of the control system").

Each valve i has, from its orifice calibration (:mod:`identification.orifice`), a charging
area a_c,i(v) and a discharging area a_r,i(v).  Its *net opening*

    h_i(v) = a_c,i(v) / a_c,i(v_max) - a_r,i(v) / a_r,i(v_min)          in [-1, 1]

is -1 fully open to the room, +1 fully open to the supply and 0 where both ports leak equally
(the valve's own null); it has the valve's own null offset, dead band and opening curve.
The canonical valve has, for a command u (0-10 V, 5 V closed), the net opening

    sigma(u) = tanh(G s) / tanh(G),      s = (u - 5 V) / 5 V,   G = CANONICAL_GAIN

a smooth odd sigmoid with no dead band and no offset.  The transform sends a canonical command
u to the real command v_i = h_i^-1(sigma(u)) (monotone interpolation of the calibrated table),
so that h_i(v_i) = sigma(u) for every valve.  The scale of each valve (its full area) is kept:
valves are sized to their chambers (see models/humanoid38/README.md), which sets the speed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pneumatics.errors import PneumasimError
from pneumatics.valve import valve_areas

#: steepness G of the canonical sigmoid (slope at the null: G / tanh G = 2.07 x linear)
CANONICAL_GAIN = 2.0
CANONICAL_NULL_V = 5.0
HALF_RANGE_V = 5.0


def canonical_opening(u_v):
    """sigma(u): net opening [-1, 1] of the canonical valve at command u [V] (any shape)."""
    s = np.clip((np.asarray(u_v, float) - CANONICAL_NULL_V) / HALF_RANGE_V, -1.0, 1.0)
    return np.tanh(CANONICAL_GAIN * s) / np.tanh(CANONICAL_GAIN)


def canonical_command(opening):
    """sigma^-1: the canonical command [V] of a net opening in [-1, 1]."""
    y = np.clip(np.asarray(opening, float), -1.0, 1.0) * np.tanh(CANONICAL_GAIN)
    return CANONICAL_NULL_V + HALF_RANGE_V * np.arctanh(y) / CANONICAL_GAIN


def net_opening(a_charge, a_discharge) -> np.ndarray:
    """h(v) of each valve from its area tables (n_ch, n_cmd) on an increasing command grid:
    the areas normalised by their values at the highest (charge) and lowest (discharge)
    command.  Only ratios matter, so a_c/V and a_r/V tables work as well."""
    a_c = np.asarray(a_charge, float)
    a_r = np.asarray(a_discharge, float)
    if np.any(a_c[:, -1] <= 0) or np.any(a_r[:, 0] <= 0):
        raise PneumasimError("linearising transform: a valve has no charging area at its highest command "
                             "or no discharging area at its lowest; is the command grid 0-10 V?")
    return a_c / a_c[:, -1:] - a_r / a_r[:, :1]


@dataclass
class ValveLinearizer:
    """The transform of every chamber's valve.

    Attributes:
      commands_v: (n_cmd,) increasing command grid [V] of the calibration.
      opening: (n_ch, n_cmd) net opening h_i(v), made non-decreasing.
    """

    commands_v: np.ndarray
    opening: np.ndarray

    def __post_init__(self):
        self.commands_v = np.asarray(self.commands_v, float)
        h = np.maximum.accumulate(np.asarray(self.opening, float), axis=1)  # noise can break monotony
        # a tiny ramp makes the table strictly increasing, so its inverse is a function: inside a
        # flat stretch (the dead band, where h = 0) the inverse jumps across it -- which is what
        # dead-band compensation should do.
        self.opening = h + 1e-9 * np.arange(h.shape[1])
        if np.any(np.diff(self.commands_v) <= 0):
            raise PneumasimError("linearising transform: the command grid must increase")

    @classmethod
    def from_calibration(cls, cal) -> ValveLinearizer:
        """From an :class:`identification.orifice.OrificeCalibration` (needs no volumes)."""
        return cls(cal.commands_v, net_opening(cal.charge_per_volume, cal.discharge_per_volume))

    @classmethod
    def from_valve_rows(cls, valve_rows, commands_v=None) -> ValveLinearizer:
        """From known valve maps (``pneumatics.valve`` rows, (n_ch, 8)): the ideal transform."""
        cmd = np.linspace(0.0, 10.0, 1001) if commands_v is None else np.asarray(commands_v, float)
        rows = np.asarray(valve_rows, float)
        a_s, a_e = valve_areas(np.broadcast_to(cmd, (rows.shape[0], cmd.size)), rows[:, None, :])
        return cls(cmd, net_opening(a_s, a_e))

    @property
    def n_chambers(self) -> int:
        return self.opening.shape[0]

    @property
    def null_v(self) -> np.ndarray:
        """(n_ch,) each valve's calibrated null: the command where its net opening crosses 0
        (the middle of its dead band)."""
        return self.command_for_opening(np.zeros(self.n_chambers))

    def command_for_opening(self, opening) -> np.ndarray:
        """(n_ch,) real commands [V] giving net openings ``opening`` (n_ch,).

        Inside a flat stretch of the table (the dead band) the middle of the stretch is
        returned: the mean of the inverse just below and just above the wanted opening."""
        y = np.asarray(opening, float)
        d = 1e-6
        return 0.5 * (self._inverse(y - d) + self._inverse(y + d))

    def _inverse(self, y: np.ndarray) -> np.ndarray:
        """Row-wise linear interpolation of the inverse table, all chambers at once (n_ch,)."""
        h, v = self.opening, self.commands_v
        k = np.clip((h < y[:, None]).sum(axis=1), 1, v.size - 1)  # h[k-1] < y <= h[k]
        rows = np.arange(h.shape[0])
        h0, h1 = h[rows, k - 1], h[rows, k]
        w = np.clip((y - h0) / (h1 - h0), 0.0, 1.0)
        return v[k - 1] + w * (v[k] - v[k - 1])

    def opening_at(self, command_v) -> np.ndarray:
        """(n_ch,) net opening h_i(v_i) of each valve at real commands ``command_v`` (n_ch,)."""
        v = np.asarray(command_v, float)
        return np.array([np.interp(v[i], self.commands_v, self.opening[i]) for i in range(self.n_chambers)])

    def __call__(self, canonical_v) -> np.ndarray:
        """Real valve commands (n_ch,) [V] for canonical commands (n_ch,) [V]."""
        u = np.asarray(canonical_v, float)
        if u.shape != (self.n_chambers,):
            raise PneumasimError(f"linearising transform: expected {self.n_chambers} canonical commands, got shape {u.shape}")
        return self.command_for_opening(canonical_opening(u))


class Linearized:
    """A controller whose commands go through a :class:`ValveLinearizer` (a device driver:
    the inner controller sees canonical valves with their null at 5 V)."""

    def __init__(self, inner, linearizer: ValveLinearizer):
        self.inner = inner
        self.linearizer = linearizer
        if hasattr(inner, "reference"):
            self.reference = inner.reference

    def reset(self):
        self.inner.reset()

    def __call__(self, time_s: float, observation) -> np.ndarray:
        return self.linearizer(self.inner(time_s, observation))
