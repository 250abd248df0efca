"""medium.orifice_flow over large arrays, compiled.

The doctor's equation error (identification/doctor/valve_arm/flow_error.py) evaluates the
orifice law (paper 002 eqs. 6-8) at every chamber and 1 ms step of a recording, a dozen times
per check: 4.6 million flows on 60 s of humanoid38, 1.2 s each time in numpy, which evaluates
every branch (choked, subsonic, linear) and its powers at every element.  Here each element
takes its own branch through the simulator's compiled law (kernel.orifice_flow_compiled: the
flow function as flow_polynomial's Chebyshev interpolant, within a few 1e-14 of the power
formula).  medium.orifice_flow is the reference (tests/test_orifice_arrays.py).
"""
from __future__ import annotations

from functools import lru_cache

import numba
import numpy as np

from .kernel import orifice_flow_compiled, pack_glob


@lru_cache(maxsize=8)
def _glob(gas) -> np.ndarray:
    """The compiled law's gas constants (kernel.pack_glob; the plant's entries unused here)."""
    return pack_glob(gas, 0.0, 0.0, 1e-3, 0.0)


@numba.njit(cache=True, error_model="numpy")
def _flows(area, p_from, p_to, glob, derivatives, m, d_from, d_to):
    for i in range(m.shape[0]):
        for j in range(m.shape[1]):
            f, df, dt = orifice_flow_compiled(area[i, j], p_from[i, j], p_to[i, j], glob)
            m[i, j] = f
            if derivatives:
                d_from[i, j] = df
                d_to[i, j] = dt


def orifice_flows(area_m2, p_from, p_to, gas, derivatives: bool = True):
    """medium.orifice_flow, compiled: signed mass flow [kg/s] through an orifice of effective
    area ``area_m2`` [m^2] from ``p_from`` to ``p_to`` [Pa abs], and its derivatives by each
    pressure (None unless ``derivatives``); arrays of up to two dimensions broadcast."""
    arrays = [np.asarray(x, float) for x in (area_m2, p_from, p_to)]
    shape = np.broadcast_shapes(*(a.shape for a in arrays))
    if len(shape) > 2:
        raise ValueError(f"orifice_flows: arrays of at most 2 dimensions, got shape {shape}")
    shape2 = (1,) * (2 - len(shape)) + shape
    two_d = [np.broadcast_to(a, shape2) for a in arrays]     # read-only views, no copies
    m = np.empty(shape2)
    d_from, d_to = (np.empty(m.shape), np.empty(m.shape)) if derivatives else (np.empty((0, 0)), np.empty((0, 0)))
    _flows(*two_d, _glob(gas), bool(derivatives), m, d_from, d_to)
    if not derivatives:
        return m.reshape(shape), None, None
    return m.reshape(shape), d_from.reshape(shape), d_to.reshape(shape)
