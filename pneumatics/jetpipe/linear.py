"""Linearisation of the hysteresis-free model about a steady force (paper 000 Sec. V-B, Table II).

The operating point: piston on the stopper at x_s, a steady actuator force F (P1 - P2 = F/A_p),
the current that holds it.  A = d(rhs)/dy and B = d(rhs)/d(i_cmd) by central differences
(step scaled to each state), output C = dF/dy = A_p (e_P1 - e_P2).  Poles are the eigenvalues
of A; the fluid block's zero is explicit (2 states); the open-loop bandwidth comes from
H(jw) = C (jw I - A)^-1 B.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..errors import PneumasimError
from .chambers import static_pressures
from .params import JetpipeCfg
from .plant import I_CURRENT, I_P1, I_P2, I_X, I_Z1, rhs_no_hysteresis
from .valve import static_force as jet_force_for_position

_SCALE = np.array([1e-3, 1e-6, 1e-6, 1e-3, 10.0, 10.0])  # perturbation per state (A, m, m, m/s, Pa, Pa)


@dataclass
class OperatingPoint:
    force_n: float
    current_a: float
    jet_abs_m: float
    state: np.ndarray  # (6,)
    piston_m: float


def jet_position_for_force(force_n: float, cfg: JetpipeCfg) -> float:
    """x_jp,abs [m] at which the steady force is ``force_n`` (brentq on the static solution)."""
    def f(x):
        p1, p2 = static_pressures(np.array([x]), cfg)
        return cfg.cylinder.piston_area_m2 * (p1[0] - p2[0]) - force_n
    hi = cfg.ports.port_centre_m
    if f(hi) < 0:
        raise PneumasimError(f"a steady force of {force_n:g} N is beyond this actuator's maximum "
                         f"({f(hi) + force_n:.1f} N at full deflection)")
    return optimize.brentq(f, 1e-7, hi, xtol=1e-10)


def operating_point(force_n: float, cfg: JetpipeCfg) -> OperatingPoint:
    """Steady state (6,) holding ``force_n`` with the piston on the stopper (no hysteresis)."""
    x_abs = jet_position_for_force(force_n, cfg)
    x_jp = x_abs - cfg.jet.offset_m
    current = float(jet_force_for_position(x_jp, cfg.jet)) / cfg.driver.force_constant_n_per_a
    p1, p2 = static_pressures(np.array([x_abs]), cfg)
    y = np.zeros(6)
    y[I_CURRENT], y[I_Z1], y[I_X] = current, x_jp, x_jp
    y[I_P1], y[I_P2] = p1[0], p2[0]
    return OperatingPoint(force_n, current, x_abs, y, cfg.cylinder.chamber1_length_m)


def linearize(op: OperatingPoint, cfg: JetpipeCfg):
    """(A (6,6), B (6,1), C (1,6), D (1,1)) of the force response to the current command."""
    n = 6
    a = np.zeros((n, n))
    for k in range(n):
        dy = np.zeros(n)
        dy[k] = _SCALE[k]
        fp = rhs_no_hysteresis(op.state + dy, op.current_a, op.piston_m, cfg)
        fm = rhs_no_hysteresis(op.state - dy, op.current_a, op.piston_m, cfg)
        a[:, k] = (fp - fm) / (2 * _SCALE[k])
    du = 1e-4
    b = ((rhs_no_hysteresis(op.state, op.current_a + du, op.piston_m, cfg)
          - rhs_no_hysteresis(op.state, op.current_a - du, op.piston_m, cfg)) / (2 * du))[:, None]
    c = np.zeros((1, n))
    c[0, I_P1], c[0, I_P2] = cfg.cylinder.piston_area_m2, -cfg.cylinder.piston_area_m2
    return a, b, c, np.zeros((1, 1))


def poles(op: OperatingPoint, cfg: JetpipeCfg) -> np.ndarray:
    """(6,) poles [rad/s] of the linearised actuator: eigenvalues of A (driver, jet, fluid)."""
    return np.sort_complex(np.linalg.eigvals(linearize(op, cfg)[0]))


def fluid_poles_zeros(op: OperatingPoint, cfg: JetpipeCfg):
    """Poles and zero [rad/s] of the chamber block alone (states P1, P2; input x_jp; output
    A_p (P1 - P2)): Table II's 'fluid dynamics' row.  For this 2-state block the transfer
    function is C adj(sI - A) B / det(sI - A), so its single zero is explicit."""
    a, _, c, _ = linearize(op, cfg)
    idx = [I_P1, I_P2]
    (a11, a12), (a21, a22) = a[np.ix_(idx, idx)]
    b1, b2 = a[idx, I_X]
    c1, c2 = c[0, idx]
    lead = c1 * b1 + c2 * b2
    const = c1 * (a12 * b2 - a22 * b1) + c2 * (a21 * b1 - a11 * b2)
    zeros = np.array([-const / lead + 0j]) if lead != 0 else np.array([], complex)
    return zeros, np.sort_complex(np.linalg.eigvals(a[np.ix_(idx, idx)]))


def dominant_pole_rad_s(op: OperatingPoint, cfg: JetpipeCfg) -> float:
    """|rad/s| of the dominant fluid pole as the paper reads Table II: the fluid block has two
    poles and a zero between them that (nearly) cancels the slower one (Table II: zero 7.1
    rad/s against pole 5.0), leaving the faster one (14.5 rad/s) to set the response.  The
    faster pole is chamber 1's: it falls as chamber 1 grows (Fig. 21, Sec. V-B)."""
    _, p = fluid_poles_zeros(op, cfg)
    return float(max(abs(p)))


def bandwidth_hz(op: OperatingPoint, cfg: JetpipeCfg) -> float:
    """-3 dB frequency [Hz] of the linearised force/current response (relative to DC),
    from H(jw) = C (jw I - A)^-1 B on a log grid."""
    a, b, c, _ = linearize(op, cfg)
    w = np.logspace(-2, 4, 2000)
    eye = np.eye(a.shape[0])
    h = np.array([(c @ np.linalg.solve(1j * wk * eye - a, b))[0, 0] for wk in w])
    mag = np.abs(h) / np.abs(h[0])
    below = np.nonzero(mag < 1 / np.sqrt(2))[0]
    if below.size == 0:
        return float("nan")
    k = below[0]
    return float(np.interp(1 / np.sqrt(2), [mag[k], mag[k - 1]], [w[k], w[k - 1]]) / (2 * np.pi))
