"""The linearised actuator as a simulation (paper 000 Sec. V-C, Fig. 22).

The sixth-order model of :func:`.linear.linearize` about an operating point (force F0, current
i0, state y0), in absolute input and output::

    d(dy)/dt = A dy + B (i_cmd - i0),      F = F0 + C dy,     dy = y - y0

discretised exactly for a command held over each step (zero-order hold: the matrix exponential
of [[A, B], [0, 0]] dt, Franklin, Powell & Workman, *Digital Control of Dynamic Systems*, 3rd
ed., Sec. 4.3.3).  The piston stays on the stopper, as in the linearisation; the force is the
pressure force A_p (P1 - P2).  A controller is called every step with an observation carrying
``force_n``, as :meth:`.sim.JetpipeSim.run` does, so the same controller object runs on both.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ..recording import Recording
from .linear import OperatingPoint, linearize
from .params import JetpipeCfg


@dataclass
class LinearObservation:
    """What a force controller reads: time [s] and the force sensor (1,) [N]."""

    time: float
    force_n: np.ndarray


class LinearJetpipe:
    """The linearised actuator about ``op``, stepped at ``dt_s`` (default the MuJoCo step, 0.5 ms)."""

    def __init__(self, op: OperatingPoint, cfg: JetpipeCfg, dt_s: float = 5e-4):
        a, b, c, _ = linearize(op, cfg)
        n = a.shape[0]
        aug = np.zeros((n + 1, n + 1))
        aug[:n, :n], aug[:n, n:] = a, b
        phi = expm(aug * dt_s)
        self.ad, self.bd = phi[:n, :n], phi[:n, n]
        self.c = c[0]
        self.op, self.dt = op, dt_s
        self.dy = np.zeros(n)

    def reset(self):
        """Back to the operating point."""
        self.dy[:] = 0.0

    def force_n(self) -> float:
        return self.op.force_n + float(self.c @ self.dy)

    def run(self, controller, duration_s: float, record_hz: float = 2000.0) -> Recording:
        """Call ``controller(time, observation) -> (1,) A`` every step for ``duration_s``; records
        ``force.piston``, ``i_cmd.piston`` and ``force_ref.piston`` (if the controller has a
        ``reference``)."""
        every = max(1, round(1.0 / (record_hz * self.dt)))
        n_steps = round(duration_s / self.dt)
        controller.reset()
        t, force, cmd, ref = [], [], [], []
        has_ref = hasattr(controller, "reference")
        for k in range(n_steps + 1):
            time = k * self.dt
            f = self.force_n()
            i = float(np.asarray(controller(time, LinearObservation(time, np.array([f])))).reshape(-1)[0])
            if k % every == 0:
                t.append(time)
                force.append(f)
                cmd.append(i)
                ref.append(controller.reference(time) if has_ref else np.nan)
            if k < n_steps:
                self.dy = self.ad @ self.dy + self.bd * (i - self.op.current_a)
        cols = {"force.piston": np.array(force), "i_cmd.piston": np.array(cmd)}
        if has_ref:
            cols["force_ref.piston"] = np.array(ref)
        meta = {"model": "jetpipe (linearised)", "operating_force_n": self.op.force_n, "physics_dt_s": self.dt,
                "generator": "pneumasim"}
        return Recording(np.array(t), cols, meta, "<jetpipe linearised run>")
