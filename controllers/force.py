"""Feedforward + proportional force control of the jet-pipe actuator (paper 000 Sec. IV, eq. 14).

    proportional (Fig. 12):   i = (k_p / k) (F_d - F_a)
    feedforward  (Fig. 13):   i = (k_p / k) (F_d - F_a) + f^-1(F_d)                  (eq. 14)

k_p is dimensionless (the loop gain at DC), k [N/A] the static force/current ratio of the
actuator (paper: k ~ 550 N/A from Fig. 9a), f^-1 the inverse of the midpoint line of the static
force/current loop.  The controller is digital: it samples the measured force and updates its
output at ``rate_hz`` (the paper's servo rate; Sec. IV-B) and holds it in between (zero-order
hold), however often it is called; by default a sample's output reaches the D/A one tick later
(the computation delay of a digital servo loop).  Its output saturates at the rated current.
Interface as controllers/pid.py: ``reset()``, ``__call__(time_s, observation) -> (1,) A``, and
``reference(time_s)`` (the desired force) for recording.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from pneumatics.config import spec
from pneumatics.errors import ConfigError


@dataclass(frozen=True, kw_only=True)
class ForceCfg:
    """Gains and timing of the force controller."""

    kp: float = spec(20.0, "dimensionless proportional gain k_p (eq. 14)", "-", 0.0, 1e4)
    static_gain_n_per_a: float = spec(550.0, "k: static force/current ratio of the actuator (Sec. V-A)", "N/A", 1e-3, 1e6)
    feedforward: bool = spec(True, "add f^-1(F_d), the inverse static midpoint line (Fig. 13); False: Fig. 12")
    rate_hz: float = spec(1000.0, "servo (sampling) rate; output held in between", "Hz", 1.0, 1e6)
    current_limit_a: float = spec(0.4, "output saturation, the rated coil current", "A", 1e-4, 100.0)
    delay_samples: int = spec(1, "computation delay: a sample's output is applied at the next servo tick (0: at once)", "-", 0, 10)

    def build(self, reference: Callable[[float], float],
              inverse_static: Callable[[float], float] | None = None) -> ForceController:
        """A controller tracking ``reference(time_s) -> F_d [N]``; ``inverse_static(F) -> i [A]`` is
        f^-1, required when ``feedforward``."""
        if self.feedforward and inverse_static is None:
            raise ConfigError("ForceCfg.feedforward = True needs inverse_static (f^-1: force N -> current A)")
        return ForceController(self, reference, inverse_static)


@dataclass
class ForceController:
    """The control law with its zero-order hold; see module docstring."""

    cfg: ForceCfg
    desired: Callable[[float], float]
    inverse_static: Callable[[float], float] | None = None
    _next_sample: float = field(default=-math.inf, init=False)
    _held: float = field(default=0.0, init=False)
    _queue: list = field(default_factory=list, init=False)
    samples: int = field(default=0, init=False)
    saturated_samples: int = field(default=0, init=False)

    def reset(self):
        self._next_sample = -math.inf
        self._held = 0.0
        self._queue = []
        self.samples = 0
        self.saturated_samples = 0

    def reference(self, time_s: float) -> float:
        return float(self.desired(time_s))

    def law(self, desired_n: float, measured_n: float) -> tuple[float, bool]:
        """(current [A], saturated?) of eq. 14 for one sample."""
        c = self.cfg
        i = c.kp / c.static_gain_n_per_a * (desired_n - measured_n)
        if c.feedforward:
            i += float(self.inverse_static(desired_n))
        clipped = min(max(i, -c.current_limit_a), c.current_limit_a)
        return clipped, clipped != i

    def __call__(self, time_s: float, observation) -> np.ndarray:
        if time_s >= self._next_sample - 1e-12:
            period = 1.0 / self.cfg.rate_hz
            # next sampling instant on the servo grid k / rate (no drift when called off-grid)
            self._next_sample = (math.floor(time_s * self.cfg.rate_hz + 1e-9) + 1) * period
            measured = float(np.asarray(observation.force_n).reshape(-1)[0])
            value, sat = self.law(self.reference(time_s), measured)
            if not self._queue:  # first sample: as if the loop had been running at this output
                self._queue = [value] * self.cfg.delay_samples
            self._queue.append(value)
            # a real servo loop computes during the period and writes at the next tick
            self._held = self._queue.pop(0)
            self.samples += 1
            self.saturated_samples += int(sat)
        return np.array([self._held])

    @property
    def saturation_fraction(self) -> float:
        """Share of samples whose output hit the current limit."""
        return self.saturated_samples / max(self.samples, 1)
