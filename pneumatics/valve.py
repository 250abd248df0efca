"""The proportional valve of the Kokoro robots (paper 002 §III, Fig. 2A).

One valve per chamber; a command ``u`` in volts (0-10 V, ``null_v`` = 5 V closed) opens the
chamber towards the supply above null and towards the room below.  Near null the spool is
slightly open both ways, so a chamber settles at an intermediate pressure, slowly (Fig. 2A).
The map, from ``reference/arm2.md``, with s = clip((u - null_v) / half_range_v, -1, 1)::

    leak(s)      = f exp(-(s / w)^2),                  w = null_leak_width_v / half_range_v
    ramp(s)      = max(0, (s - d) / (1 - d))^gamma,    d = deadband_v / half_range_v
    a_supply(u)  = A_s,max (leak(s) + (1 - f) ramp(s))
    a_exhaust(u) = A_e,max (leak(s) + (1 - f) ramp(-s))
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .config import spec

#: column order of a valve row in the compiled kernel's chamber table
VALVE_COLUMNS = ("null_v", "half_range_v", "null_leak_fraction", "null_leak_width_v",
                 "deadband_v", "opening_exponent", "supply_area_max_m2", "exhaust_area_max_m2")


@dataclass(frozen=True)
class ValveCfg:
    """One chamber's proportional valve (effective areas are Cd*A)."""

    supply_area_max_m2: float = spec(8.0e-7, "effective area to supply at full opening", "m^2", 1e-9, 1e-3)
    exhaust_area_max_m2: float = spec(9.0e-7, "effective area to room at full opening", "m^2", 1e-9, 1e-3)
    null_v: float = spec(5.0, "command at which the valve is (nearly) closed", "V", 0.0, 10.0)
    half_range_v: float = spec(5.0, "command span from null to full opening", "V", 0.1, 10.0)
    null_leak_fraction: float = spec(0.02, "fraction f of full area open both ways at null", "-", 0.0, 0.5)
    null_leak_width_v: float = spec(0.6, "width w of the Gaussian null leak", "V", 1e-3, 5.0)
    deadband_v: float = spec(0.15, "command beyond null before the main port opens", "V", 0.0, 4.0)
    opening_exponent: float = spec(1.3, "gamma: shape of the area-vs-command ramp", "-", 0.2, 5.0)

    def as_row(self) -> np.ndarray:
        return np.array([getattr(self, name) for name in VALVE_COLUMNS])

    def areas(self, command_v):
        """(supply, exhaust) effective areas [m^2] for commands ``command_v`` [V] (any shape)."""
        return valve_areas(np.asarray(command_v, float), self.as_row()[:, None].T)


def valve_areas(command_v: np.ndarray, rows: np.ndarray):
    """Vectorised valve map.

    Args:
      command_v: (n,) commands [V].
      rows: (n, 8) valve parameters in :data:`VALVE_COLUMNS` order (or (1, 8), broadcast).
    Returns:
      (supply_area_m2, exhaust_area_m2), each (n,).
    """
    null, half, f, width, dead, gamma, a_s, a_e = (rows[..., i] for i in range(8))
    s = np.clip((command_v - null) / half, -1.0, 1.0)
    w = width / half
    d = dead / half
    leak = f * np.exp(-(s / w) ** 2)
    ramp_s = np.maximum(0.0, (s - d) / (1.0 - d)) ** gamma
    ramp_e = np.maximum(0.0, (-s - d) / (1.0 - d)) ** gamma
    return a_s * (leak + (1.0 - f) * ramp_s), a_e * (leak + (1.0 - f) * ramp_e)


assert tuple(f.name for f in fields(ValveCfg)) == tuple(
    ["supply_area_max_m2", "exhaust_area_max_m2", *VALVE_COLUMNS[:6]])
