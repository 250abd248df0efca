"""Servovalve hysteresis: Jiles-Atherton major loop, minor loops by a scaling factor.

Paper 001 §2.1 (eqs. 2-3) models the hysteresis between the input current i and a virtual
current i_hys that positions the valve tip with the Jiles-Atherton (JA) theory of
ferromagnetic hysteresis (i plays the field H, i_hys the magnetisation M)::

    d i_hys / d i = lambda (L - i_hys) / (delta k0 - alpha0 (L - i_hys))         (2)
    L(i, i_hys) = coth(gamma0 (i + alpha0 i_hys)) - 1 / (gamma0 (i + alpha0 i_hys)) (3)
    delta = sign(di/dt)

(the OCR of eq. 2 is garbled; this is the JA irreversible law of Jiles & Atherton, J. Magn.
Magn. Mater. 61 (1986), in the paper's notation; everything is normalised by the
saturation current i_sat at which "the major loop saturates", 1 A).  gamma0, alpha0 and k0
set the inclination and width of the loop.  Where the slope would turn negative
(delta (L - i_hys) < 0, just after a reversal) it is set to zero, the usual JA fix.

The paper's scaling factor lambda "is less than unity for minor loop generation and depends
on the switching point and the major loop".  Here: lambda = 1 on the major loop; at each
switching point (i_r, h_r) the new branch is the major branch of the new direction, scaled
so that it runs through the previous switching point (Madelung's return-point memory)::

    h(i) = h_r + lambda (H_dir(i) - H_dir(i_r)),
    lambda = (h_target - h_r) / (H_dir(i_target) - H_dir(i_r))

with H_dir the JA major branch.  When the input passes the target the minor loop has closed
(exactly, by construction) and the branch it interrupted continues.  A stack of switching
points holds the nested loops.  The valve's "decaying sinusoid" (paper §4) is
:meth:`Hysteresis.demagnetize`.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..config import spec

GRID_POINTS = 4001  # major-branch table over [-i_sat, i_sat]


@dataclass(frozen=True)
class HysteresisCfg:
    """Jiles-Atherton parameters of the servovalve's current hysteresis (paper 001 eqs. 2-3)."""

    saturation_current_a: float = spec(1.0, "current at which the major loop saturates (the "
                                       "amplifier clips the current there)", "A", 1e-3, 100.0)
    gamma0_per_a: float = spec(5.0, "Langevin scale gamma0: inclination of the loop", "1/A", 0.1, 1e3)
    alpha0: float = spec(0.05, "interdomain coupling alpha0 (feedback of i_hys on the effective "
                         "current)", "-", 0.0, 0.5)
    k0_a: float = spec(0.03, "pinning constant k0: sets the half-width (coercive current) of the "
                       "major loop", "A", 1e-4, 1.0)


def langevin(z):
    """L(z) = coth z - 1/z, with its series near 0."""
    z = np.asarray(z, float)
    small = np.abs(z) < 1e-4
    zs = np.where(small, 1.0, z)
    return np.where(small, z / 3.0 - z ** 3 / 45.0, 1.0 / np.tanh(zs) - 1.0 / zs)


def _langevin_scalar(z: float) -> float:
    return z / 3.0 - z ** 3 / 45.0 if abs(z) < 1e-4 else 1.0 / math.tanh(z) - 1.0 / z


def ja_slope(x, m, direction, gamma, alpha, k):
    """Eq. 2 in normalised units (x = i/i_sat, m = i_hys/i_sat, k = k0/i_sat, lambda = 1)."""
    diff = _langevin_scalar(gamma * (x + alpha * m)) - m
    if direction * diff <= 0.0:  # JA slope would be negative after a reversal: no change
        return 0.0
    return diff / (direction * k - alpha * diff)


@functools.lru_cache(maxsize=16)
def major_loop(cfg: HysteresisCfg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The JA major loop: ``(x, m_up, m_down)`` on a grid x in [-1, 1] (normalised current).

    Integrated with RK4 along the grid: up, down, up again (the loop settles in one cycle);
    m is normalised so that the loop tip is m(+-1) = +-1, i.e. i_hys = +-i_sat there.
    """
    gamma = cfg.gamma0_per_a * cfg.saturation_current_a
    alpha, k = cfg.alpha0, cfg.k0_a / cfg.saturation_current_a
    x = np.linspace(-1.0, 1.0, GRID_POINTS)
    m = -0.5
    for _ in range(50):  # start on the anhysteretic curve at x = -1: m = L(gamma (x + alpha m))
        m = _langevin_scalar(gamma * (-1.0 + alpha * m))

    def sweep(xs, m0, direction):
        xs = xs.tolist()
        out = [m0]
        for j in range(len(xs) - 1):
            h = xs[j + 1] - xs[j]
            xj, mj = xs[j], out[j]
            k1 = ja_slope(xj, mj, direction, gamma, alpha, k)
            k2 = ja_slope(xj + h / 2, mj + h / 2 * k1, direction, gamma, alpha, k)
            k3 = ja_slope(xj + h / 2, mj + h / 2 * k2, direction, gamma, alpha, k)
            k4 = ja_slope(xj + h, mj + h * k3, direction, gamma, alpha, k)
            out.append(mj + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4))
        return np.array(out)

    up = sweep(x, m, +1)
    down = sweep(x[::-1], up[-1], -1)[::-1]
    up = sweep(x, down[0], +1)
    down = sweep(x[::-1], up[-1], -1)[::-1]
    tip = up[-1]
    return x, up / tip, down / tip


@dataclass
class _Branch:
    direction: int      # +1 ascending, -1 descending
    x0: float           # where the branch starts (switching point), normalised current
    m0: float           # output there
    scale: float        # lambda
    major: bool         # True for the major loop itself (lambda = 1)


class Hysteresis:
    """Input current -> virtual current i_hys [A], with nested minor loops.

    Call :meth:`__call__` with each new input current (any sampling); the state is the stack
    of unclosed switching points.  Starts at the negative tip of the major loop (i = -i_sat);
    call :meth:`demagnetize` to start at the null.
    """

    def __init__(self, cfg: HysteresisCfg):
        self.cfg = cfg
        self.i_sat = cfg.saturation_current_a
        self._x, self._up, self._down = major_loop(cfg)
        self.reset()

    def reset(self):
        """At the negative tip of the major loop, ascending next."""
        self.stack = [_Branch(+1, -1.0, -1.0, 1.0, True)]
        self.x, self.m = -1.0, -1.0

    def major(self, x, direction: int):
        """Major branch value(s) at normalised current ``x``."""
        return np.interp(x, self._x, self._up if direction > 0 else self._down)

    def _value(self, b: _Branch, x: float) -> float:
        if b.major:
            return float(self.major(x, b.direction))
        return b.m0 + b.scale * float(self.major(x, b.direction) - self.major(b.x0, b.direction))

    def _target(self, level: int) -> tuple[float, float]:
        """Where branch ``level`` closes: the start of the branch below it, or the tip."""
        d = self.stack[level].direction
        if level == 1:
            return float(d), float(d)
        below = self.stack[level - 1]
        return below.x0, below.m0

    def __call__(self, current_a: float) -> float:
        """Feed the input current [A]; returns i_hys [A].  Inputs beyond +-i_sat are clipped."""
        x = min(max(current_a / self.i_sat, -1.0), 1.0)
        dx = x - self.x
        if dx != 0.0:
            d = 1 if dx > 0 else -1
            top = self.stack[-1]
            if d != top.direction:  # switching point: new branch heading for the last one
                self.stack.append(_Branch(d, self.x, self.m, 1.0, False))
                xt, mt = self._target(len(self.stack) - 1)
                den = float(self.major(xt, d) - self.major(self.x, d))
                self.stack[-1].scale = (mt - self.m) / den if abs(den) > 1e-12 else 1.0
            while len(self.stack) > 1:  # passed the target: that minor loop has closed
                xt, _ = self._target(len(self.stack) - 1)
                if d * (x - xt) < 0.0:
                    break
                if len(self.stack) == 2:  # reached the tip: back on the major loop
                    self.stack = [_Branch(d, xt, float(d), 1.0, True)]
                else:
                    del self.stack[-2:]
            self.x = x
            self.m = self._value(self.stack[-1], x)
        return self.m * self.i_sat

    @property
    def depth(self) -> int:
        """Number of unclosed switching points (nested minor loops)."""
        return len(self.stack) - 1

    def demagnetize(self, cycles: int = 40, points_per_cycle: int = 24, final_a: float = 1e-3):
        """Decaying sinusoid from i_sat to ``final_a`` then 0 (paper 001 §4): ends near the null."""
        decay = (final_a / self.i_sat) ** (1.0 / cycles)
        n = cycles * points_per_cycle
        k = np.arange(n + 1)
        amp = self.i_sat * decay ** (k / points_per_cycle)
        for i in amp * np.cos(2 * math.pi * k / points_per_cycle):
            self(float(i))
        self(0.0)
        return self.m * self.i_sat
