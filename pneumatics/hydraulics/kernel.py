"""Compiled (numba) fast path of :meth:`.circuit.HydraulicCircuit.step`.

The same equations as :meth:`.circuit.HydraulicCircuit.rates` (the readable reference; read
that one), in scalar code: the Python reference costs ~200 us per step, which makes a 25 s
experiment at 0.2 ms take minutes.  tests/test_sarcos.py checks that both paths agree.
Parameters travel as one float array, see :func:`pack`.
"""
from __future__ import annotations

import numba
import numpy as np

from ..oil import CAVITATION_FLOOR_PA

MODE = {"valve": 0, "blocked": 1, "tap": 2}


def pack(circuit) -> np.ndarray:
    """Flat parameter vector of a :class:`HydraulicCircuit` for :func:`step_kernel`."""
    v = circuit.vane
    return np.array([
        circuit.k, circuit.dp_t2, circuit.valve.port_width_m, circuit.valve.tip_travel_m,
        circuit.g_sp, circuit.g_pr, circuit.g_sr,
        circuit.c_s, circuit.r_s, circuit.i_s, circuit.c_r, circuit.r_r, circuit.i_r,
        circuit.power.pump_pa, circuit.power.tank_pa, circuit.oil.bulk_modulus_pa,
        v.displacement_m3_per_rad, v.leak_coefficient_m3_per_pa_s,
        v.line_volume_m3 + v.dead_volume_m3, v.half_stroke_rad, CAVITATION_FLOOR_PA,
        v.extra_line_volume_a_m3, v.extra_line_volume_b_m3])


def pack_ports(ports) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    modes = np.array([MODE[p.mode] for p in ports], dtype=np.int64)
    return modes, np.array([p.pressure_pa for p in ports]), np.array([p.area_m2 for p in ports])


@numba.njit(cache=True, inline="always")
def _orifice(k_area, dp, t2):
    s = dp * dp + t2
    r = s ** -0.25
    return k_area * dp * r, k_area * (0.5 * dp * dp + t2) * r / s


@numba.njit(cache=True)
def rates_kernel(y, p, modes, tap_p, tap_a, x_v, theta, omega, f, J, tapq):
    """Fill f (6,), J (6, 6) and tapq (2,) (flow chamber -> tap) at state y."""
    k, t2, width, travel = p[0], p[1], p[2], p[3]
    g_sp, g_pr, g_sr = p[4], p[5], p[6]
    c_s, r_s, i_s, c_r, r_r, i_r = p[7], p[8], p[9], p[10], p[11], p[12]
    pump, tank, beta, d_v, r_l, v0, half = p[13], p[14], p[15], p[16], p[17], p[18], p[19]
    p_s, q_s, p_r, q_r = y[0], y[1], y[2], y[3]
    x = min(max(x_v, -travel), travel)
    a_pos = width * max(x, 0.0)
    a_neg = width * max(-x, 0.0)
    J[:, :] = 0.0
    q_sup = 2.0 * g_sr * (p_s - p_r)
    q_ret = q_sup
    J[0, 0] -= 2.0 * g_sr / c_s
    J[0, 2] += 2.0 * g_sr / c_s
    J[2, 0] += 2.0 * g_sr / c_r
    J[2, 2] -= 2.0 * g_sr / c_r
    qch0 = 0.0
    qch1 = 0.0
    v_a = v0 + p[21] + d_v * (half + theta)
    v_b = v0 + p[22] + d_v * (half - theta)
    for j in range(2):
        pj = y[4 + j]
        a_in = a_pos if j == 0 else a_neg    # supply -> a opens for x_v > 0, supply -> b for x_v < 0
        a_out = a_neg if j == 0 else a_pos
        c = beta / (v_a if j == 0 else v_b)
        row = 4 + j
        tapq[j] = 0.0
        if modes[j] == 0:
            q_in, d_in = _orifice(k * a_in, p_s - pj, t2)
            q_out, d_out = _orifice(k * a_out, pj - p_r, t2)
            qv = q_in - q_out + g_sp * (p_s - pj) - g_pr * (pj - p_r)
            J[row, 0] += c * (d_in + g_sp)
            J[row, 2] += c * (d_out + g_pr)
            J[row, row] += c * (-d_in - d_out - g_sp - g_pr)
            q_sup += q_in + g_sp * (p_s - pj)
            J[0, 0] -= (d_in + g_sp) / c_s
            J[0, row] += (d_in + g_sp) / c_s
            q_ret += q_out + g_pr * (pj - p_r)
            J[2, row] += (d_out + g_pr) / c_r
            J[2, 2] -= (d_out + g_pr) / c_r
        elif modes[j] == 1:
            qv = 0.0
        else:
            q_tap, d_tap = _orifice(k * tap_a[j], tap_p[j] - pj, t2)
            qv = q_tap
            J[row, row] -= c * d_tap
            tapq[j] = -q_tap
        if j == 0:
            qch0 = qv
        else:
            qch1 = qv
    q_leak = r_l * (y[4] - y[5])
    f[0] = (q_s - q_sup) / c_s
    f[1] = (pump - p_s - r_s * q_s) / i_s
    f[2] = (q_ret - q_r) / c_r
    f[3] = (p_r - tank - r_r * q_r) / i_r
    f[4] = beta / v_a * (qch0 - d_v * omega - q_leak)
    f[5] = beta / v_b * (qch1 + d_v * omega + q_leak)
    J[0, 1] += 1.0 / c_s
    J[1, 0] = -1.0 / i_s
    J[1, 1] = -r_s / i_s
    J[2, 3] -= 1.0 / c_r
    J[3, 2] = 1.0 / i_r
    J[3, 3] = -r_r / i_r
    J[4, 4] -= beta / v_a * r_l
    J[4, 5] += beta / v_a * r_l
    J[5, 4] += beta / v_b * r_l
    J[5, 5] -= beta / v_b * r_l


@numba.njit(cache=True)
def solve_small(A, b):
    """Solve A x = b in place (b becomes x) by Gaussian elimination with partial pivoting;
    for the 6x6 step matrix this compiles far faster than np.linalg.solve (LAPACK)."""
    n = b.shape[0]
    for col in range(n):
        piv = col
        for r in range(col + 1, n):
            if abs(A[r, col]) > abs(A[piv, col]):
                piv = r
        if piv != col:
            for c in range(n):
                A[col, c], A[piv, c] = A[piv, c], A[col, c]
            b[col], b[piv] = b[piv], b[col]
        for r in range(col + 1, n):
            factor = A[r, col] / A[col, col]
            if factor != 0.0:
                for c in range(col, n):
                    A[r, c] -= factor * A[col, c]
                b[r] -= factor * b[col]
    for r in range(n - 1, -1, -1):
        acc = b[r]
        for c in range(r + 1, n):
            acc -= A[r, c] * b[c]
        b[r] = acc / A[r, r]


@numba.njit(cache=True)
def step_kernel(y, p, modes, tap_p, tap_a, x_v, theta, omega, dt, tap_volume):
    """One linearly-implicit Euler step of the circuit, in place; returns P_a - P_b."""
    f = np.empty(6)
    J = np.empty((6, 6))
    tapq = np.empty(2)
    rates_kernel(y, p, modes, tap_p, tap_a, x_v, theta, omega, f, J, tapq)
    A = np.eye(6) - dt * J
    dy = dt * f
    solve_small(A, dy)
    for i in range(6):
        y[i] += dy[i]
    if modes[0] == 2 or modes[1] == 2:
        rates_kernel(y, p, modes, tap_p, tap_a, x_v, theta, omega, f, J, tapq)
        tap_volume[0] += dt * tapq[0]
        tap_volume[1] += dt * tapq[1]
    floor = p[20]  # circuit.CAVITATION_FLOOR_PA on every pressure state (circuit.FLOORED_STATES)
    y[0] = max(y[0], floor)
    y[2] = max(y[2], floor)
    y[4] = max(y[4], floor)
    y[5] = max(y[5], floor)
    return y[4] - y[5]
