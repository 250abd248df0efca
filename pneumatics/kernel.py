"""Compiled fast path of the fluid update: the same equations as :mod:`pneumatics.chamber`
(the readable numpy reference), scalar loops compiled with numba, writing the cylinder forces
into MuJoCo's ``data.ctrl`` in place.  A numpy call costs ~20 us whatever the array size,
more than a 2-DOF ``mj_step``; this kernel costs ~1 us.  ``tests/test_kernel.py`` checks it
against the reference to round-off.

Table layouts (from :meth:`pneumatics.tables.FluidTables.packed`):
  act  (n_act, 5): area_a, area_b, stroke, length_zero, ctrl index
  ch   (n_ch, 12): area, dead volume, is_a, actuator index, 8 valve columns
  glob (12,):      R, k, T, n, laminar ratio, r_c, c_choke, c_sub, supply, room, dt,
                   slope of the linearised flow near r = 1
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .medium import _psi as _psi_ref

GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
MAX_HALVINGS = 6
MAX_REL_CHANGE = 0.25


@numba.njit(cache=True, error_model="numpy", inline="always")
def _unit_flow(p_up, p_down, glob):
    """(flow, d/d p_up, d/d p_down) per unit area for p_up >= p_down (medium.unit_flow).

    One power per call: with e = r^(1/k), r^(2/k) = e^2 and r^((k+1)/k) = r e.
    Helpers are inlined: as separate calls they cost more than their arithmetic.
    """
    k, rl, rc, c_choke, c_sub = glob[1], glob[4], glob[5], glob[6], glob[7]
    r = p_down / p_up
    if r <= rc:
        return c_choke * p_up, c_choke, 0.0
    if r <= rl:
        e = math.exp(math.log(r) / k)
        g = e * e - r * e
        psi = math.sqrt(g) if g > 0.0 else 0.0
        dg = (2.0 / k) * e * e / r - ((k + 1.0) / k) * e
        dpsi = dg / (2.0 * math.sqrt(max(g, 1e-300)))
        return c_sub * p_up * psi, c_sub * (psi - r * dpsi), c_sub * dpsi
    slope = glob[11]
    return slope * (p_up - p_down), slope, -slope


@numba.njit(cache=True, error_model="numpy", inline="always")
def _orifice(area, p_from, p_to, glob):
    """Signed mass flow [kg/s] and its derivatives (medium.orifice_flow)."""
    if p_from >= p_to:
        f, d_hi, d_lo = _unit_flow(p_from, p_to, glob)
        return area * f, area * d_hi, area * d_lo
    f, d_hi, d_lo = _unit_flow(p_to, p_from, glob)
    return -area * f, -area * d_lo, -area * d_hi


@numba.njit(cache=True, error_model="numpy", inline="always")
def _rate(p, volume, volume_rate, a_s, a_e, glob):
    rt = glob[0] * glob[2]
    n = glob[3]
    m_s, _, dms = _orifice(a_s, glob[8], p, glob)
    m_e, dme, _ = _orifice(a_e, p, glob[9], glob)
    return (n / volume * (rt * (m_s - m_e) - p * volume_rate),
            n / volume * (rt * (dms - dme) - volume_rate))


@numba.njit(cache=True, error_model="numpy")
def fluid_step_fast(p, areas, length, velocity, ctrl, act, ch, glob):
    """Write forces from p(t) into ``ctrl``, then advance ``p`` in place to t + dt.

    Args (shapes): p (n_ch,) Pa; areas (n_ch, 2) valve supply and exhaust areas [m^2]
    (pneumatics.valve.valve_areas of the commands); length, velocity (n_act,);
    ctrl (nu,) MuJoCo controls; act, ch, glob as in the module docstring.
    """
    room = glob[9]
    dt = glob[10]
    for j in range(act.shape[0]):
        aa, ab = act[j, 0], act[j, 1]
        ctrl[int(act[j, 4])] = aa * p[2 * j] - ab * p[2 * j + 1] - (aa - ab) * room
    for i in range(ch.shape[0]):
        j = int(ch[i, 3])
        stroke = act[j, 2]
        x = length[j] - act[j, 3]
        xdot = velocity[j]
        x_mid = min(max(x + 0.5 * dt * xdot, 0.0), stroke)
        is_a = ch[i, 2] > 0.5
        travel = x_mid if is_a else stroke - x_mid
        volume = ch[i, 1] + ch[i, 0] * travel
        if (x_mid <= 0.0 and xdot < 0.0) or (x_mid >= stroke and xdot > 0.0):
            vrate = 0.0
        else:
            vrate = (1.0 if is_a else -1.0) * ch[i, 0] * xdot
        a_s, a_e = areas[i, 0], areas[i, 1]
        p0 = p[i]
        for level in range(MAX_HALVINGS + 1):
            n_sub = 2 ** level
            h = dt / n_sub
            q = p0
            ok = True
            for _ in range(n_sub):
                f0, jac = _rate(q, volume, vrate, a_s, a_e, glob)
                denom = 1.0 - GAMMA * h * jac
                k1 = f0 / denom
                f1, _j = _rate(q + h * k1, volume, vrate, a_s, a_e, glob)
                k2 = (f1 - 2.0 * k1) / denom
                q_new = q + 1.5 * h * k1 + 0.5 * h * k2
                if not (math.isfinite(q_new) and abs(q_new - q) <= MAX_REL_CHANGE * q):
                    ok = False
                q = q_new
            if ok or level == MAX_HALVINGS:
                p[i] = q
                break


def pack(tables, ctrl_index, dt):
    """Kernel tables (act, ch, glob) from :class:`FluidTables`, ctrl indices and the step."""
    act, ch, glob = tables.packed()
    act = np.ascontiguousarray(np.column_stack([act, np.asarray(ctrl_index, float)]))
    gas = tables.gas
    slope = gas.c_sub * _psi_ref(gas.laminar_ratio, gas.heat_capacity_ratio) / (1.0 - gas.laminar_ratio)
    return act, ch, np.concatenate([glob, [dt, slope]])


# -- the whole physics loop, compiled -------------------------------------------------------
# mj_step1 / mj_step2 are called straight from compiled code through ctypes, so n steps run
# without returning to Python (a Python-level loop costs ~1 us a step, a third of a 2-DOF
# mj_step).  Where MuJoCo's shared library cannot be found, Simulation falls back to a
# Python loop around the same kernel.
def _load_mujoco_steps():
    import ctypes
    import glob as _glob
    import os

    import mujoco

    libs = sorted(_glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so*")))
    if not libs:
        return None
    lib = ctypes.CDLL(libs[0])
    fns = []
    for name in ("mj_step1", "mj_step2"):
        fn = getattr(lib, name)
        fn.argtypes = [ctypes.c_uint64, ctypes.c_uint64]  # (const mjModel*, mjData*)
        fn.restype = None
        fns.append(fn)
    return fns


_STEPS = _load_mujoco_steps()

if _STEPS is not None:
    _mj_step1, _mj_step2 = _STEPS

    @numba.njit(cache=False, error_model="numpy")
    def run_steps_compiled(n, model_addr, data_addr, p, areas, length, velocity, ctrl, act, ch, glob):
        """n x (mj_step1; fluid_step_fast; mj_step2) without leaving compiled code."""
        for _ in range(n):
            _mj_step1(model_addr, data_addr)
            fluid_step_fast(p, areas, length, velocity, ctrl, act, ch, glob)
            _mj_step2(model_addr, data_addr)
else:  # pragma: no cover - platforms without libmujoco.so
    run_steps_compiled = None
