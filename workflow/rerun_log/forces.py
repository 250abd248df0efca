"""Cylinder forces for a whole batch of frames: they are affine in the chamber pressures."""
from __future__ import annotations

import numpy as np


def affine_forces(sim):
    """(M, c) with ``sim.forces() == M @ sim.pressure + c`` for every pressure, or ``None``.

    The cylinder force of :meth:`Simulation.forces` is affine in the chamber pressures (and
    depends on nothing else), so a logger can compute it for a whole batch at flush time
    instead of calling ``sim.forces()`` every frame.  Only for that very method (a subclass
    that overrides it may depend on more than the pressures), probed and checked on random
    pressures (restored afterwards); ``None`` (per-frame calls) otherwise.
    """
    from pneumatics.sim import Simulation

    if getattr(type(sim), "forces", None) is not Simulation.forces:
        return None
    p0 = sim.pressure.copy()
    try:
        n = p0.size
        sim.pressure[:] = 0.0
        c = np.array(sim.forces(), float)
        mat = np.empty((c.size, n))
        for j in range(n):
            sim.pressure[:] = 0.0
            sim.pressure[j] = 1e5
            mat[:, j] = (np.asarray(sim.forces(), float) - c) / 1e5
        rng = np.random.default_rng(0)
        for _ in range(2):
            sim.pressure[:] = rng.uniform(0.5e5, 2e7, n)
            expect = mat @ sim.pressure + c
            if not np.allclose(sim.forces(), expect, rtol=1e-9,
                               atol=1e-9 * max(1.0, np.abs(expect).max(initial=0.0))):
                return None
        return mat, c
    except Exception:
        return None
    finally:
        sim.pressure[:] = p0
