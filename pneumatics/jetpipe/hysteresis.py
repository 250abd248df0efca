"""Rate-independent hysteresis between coil current and jet position: a Prandtl-Ishlinskii model.

Paper 000 (Sec. III-A) measured a major loop of almost constant width between jet position and
current (0.08 mm between the midpoint line and each branch, ~8 % of the 1 mm range) and found that
the Preisach-type model of Frame et al. failed to predict its minor loops.  We use the simplest
model whose minor loops close by construction: a Prandtl-Ishlinskii operator, a weighted sum of
play (backlash) operators (Brokate & Sprekels, *Hysteresis and Phase Transitions*, 1996, §2.3;
Kuhnen, *Eur. J. Control* 9 (2003) 407), acting on the tip force F = k_m i before the static
nonlinearity f3::

    play_r(F)(t) = min(F + r, max(F - r, y_r(t-)))          y_r: the play's output
    H(F) = sum_k w_k play_{r_k}(F),   w_k = 1/n,  r_k = 2 h k / (n + 1), k = 1..n

After a reversal longer than 2 r_max, every play is dragged: the branches are H = F -+ h, so
the half-width of the major loop is h (the mean radius) everywhere, and a periodic input gives a
closed minor loop from its second cycle on (each play's output is periodic).  The distributed
radii make the branches curve smoothly after a reversal, as measured loops do.
"""
from __future__ import annotations

import numpy as np


def play_radii(half_width: float, n: int) -> np.ndarray:
    """(n,) radii r_k = 2 h k / (n + 1) whose mean is ``half_width`` (units of the input)."""
    return 2.0 * half_width * np.arange(1, n + 1) / (n + 1)


class PlayHysteresis:
    """Prandtl-Ishlinskii hysteresis with equal weights; ``state`` (n,) = the play outputs."""

    def __init__(self, half_width: float, n: int = 8):
        self.radii = play_radii(half_width, n)
        self.state = np.zeros(n)

    def reset(self, value: float = 0.0):
        """Demagnetised start: every play output at ``value``."""
        self.state[:] = value

    def __call__(self, value: float) -> float:
        """Advance with input ``value`` and return the output (same units)."""
        np.clip(self.state, value - self.radii, value + self.radii, out=self.state)
        return float(self.state.mean())

    def trace(self, values) -> np.ndarray:
        """Outputs (N,) for an input sequence (N,), continuing from the current state."""
        return np.array([self(v) for v in np.asarray(values, float)])
