"""Static force/current characteristic of the jet-pipe actuator (paper 000 Fig. 9a, eq. 14's f).

Without hysteresis the steady jet position is x_abs = f3(k_m i) + x_offset (eqs. 1-4, the
jet dynamics have unit DC gain) and the steady force follows from the chamber mass balances
(chambers.static_force).  This curve is the paper's midpoint line f of the force/current loop:
the controller's feedforward uses its inverse f^-1 (eq. 14) and its slope k [N/A] (Sec. V-A).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .chambers import static_force
from .params import JetpipeCfg
from .valve import static_position


def midline_force(current_a, cfg: JetpipeCfg) -> np.ndarray:
    """Steady force [N] (N,) at currents ``current_a`` (N,) [A], hysteresis excluded."""
    i = np.atleast_1d(np.asarray(current_a, float))
    i = np.clip(i, -cfg.driver.current_limit_a, cfg.driver.current_limit_a)
    x_abs = static_position(cfg.driver.force_constant_n_per_a * i, cfg.jet) + cfg.jet.offset_m
    return static_force(x_abs, cfg)


@dataclass
class StaticCurve:
    """The midpoint line sampled on a current grid, with its inverse and slope."""

    current_a: np.ndarray  # (N,)
    force_n: np.ndarray    # (N,)

    def inverse(self, force_n: float) -> float:
        """f^-1: current [A] on the midpoint line for force ``force_n`` [N] (clamped to the range)."""
        f, i = self.force_n, self.current_a
        ok = np.concatenate([[True], np.diff(f) > 1e-9])  # strictly increasing part for interp
        return float(np.interp(force_n, f[ok], i[ok]))

    def slope_n_per_a(self, force_n: float) -> float:
        """k = dF/di [N/A] at ``force_n``."""
        i0 = self.inverse(force_n)
        return float(np.interp(i0, self.current_a, np.gradient(self.force_n, self.current_a)))

    @property
    def max_force_n(self) -> float:
        return float(self.force_n.max())


def static_curve(cfg: JetpipeCfg, n: int = 161) -> StaticCurve:
    """Sample the midpoint line from the current where the force leaves zero to the limit."""
    i = np.linspace(-0.05, min(0.25, cfg.driver.current_limit_a), n)
    return StaticCurve(i, midline_force(i, cfg))
