"""Perturbations wrapped around a controller (paper 002 §IV-A and Fig. 6C).

* :class:`CommandPerturbation` — "self-generated control perturbations": a random,
  piecewise-constant offset added antagonistically to each joint's valve commands
  (u^+ += delta, u^- -= delta), new every ``hold_s``; it excites the dynamics beyond what
  the reference asks for, for identification.
* :class:`ExternalPush` — the experimenter pushing the arm: a Cartesian force on a body
  (MuJoCo ``data.xfrc_applied``) during given time windows.

Both keep the wrapped controller's ``reset``/``reference`` so the runner records ``ref.*``.
"""
from __future__ import annotations

import numpy as np

from pneumatics.errors import PneumasimError

from .pid import COMMAND_MAX_V, COMMAND_MIN_V


class _Wrapper:
    def __init__(self, inner):
        self.inner = inner
        if hasattr(inner, "reference"):
            self.reference = inner.reference

    def reset(self):
        self.inner.reset()


class CommandPerturbation(_Wrapper):
    """Random antagonistic command offsets, uniform in +-``amplitude_v``, held ``hold_s``."""

    def __init__(self, inner, amplitude_v: float = 1.5, hold_s: float = 0.15, seed: int = 0):
        super().__init__(inner)
        if amplitude_v < 0 or hold_s <= 0:
            raise PneumasimError("CommandPerturbation: amplitude_v must be >= 0 and hold_s > 0")
        self.amplitude_v, self.hold_s, self.seed = amplitude_v, hold_s, seed
        self.reset()

    def reset(self):
        super().reset()
        self._rng = np.random.default_rng(self.seed)
        self._next = -np.inf
        self._delta = None

    def __call__(self, t, obs):
        u = np.asarray(self.inner(t, obs), float).copy()
        if t >= self._next:
            self._delta = self._rng.uniform(-self.amplitude_v, self.amplitude_v, u.size // 2)
            self._next = t + self.hold_s
        u[0::2] += self._delta
        u[1::2] -= self._delta
        return np.clip(u, COMMAND_MIN_V, COMMAND_MAX_V)


class ExternalPush(_Wrapper):
    """Apply ``force_n`` (3,) world-frame force at body ``body``'s COM during ``windows``.

    Args:
      sim: the :class:`pneumatics.sim.Simulation` being run (the push is written into its
        ``data.xfrc_applied`` at each control instant and held, like the commands).
      windows: [(t0, t1, (fx, fy, fz)), ...] in seconds and newtons.
    """

    def __init__(self, inner, sim, body: str, windows):
        super().__init__(inner)
        try:
            self.body_id = sim.model.body(body).id
        except KeyError:
            names = [sim.model.body(i).name for i in range(sim.model.nbody)]
            raise PneumasimError(f"ExternalPush: no body {body!r}; bodies: {', '.join(names)}") from None
        self.sim = sim
        self.windows = [(float(a), float(b), np.asarray(f, float)) for a, b, f in windows]

    def reset(self):
        super().reset()
        self.sim.data.xfrc_applied[self.body_id] = 0.0

    def __call__(self, t, obs):
        force = np.zeros(3)
        for t0, t1, f in self.windows:
            if t0 <= t < t1:
                force += f
        self.sim.data.xfrc_applied[self.body_id, :3] = force
        return self.inner(t, obs)
