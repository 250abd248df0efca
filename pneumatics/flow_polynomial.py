"""The isentropic flow function as a polynomial, for the compiled kernels.

The subsonic orifice law (:mod:`pneumatics.medium`, paper 002 eqs. 6-8) needs
``psi(r) = sqrt(g(r))`` with ``g(r) = r^(2/k) - r^((k+1)/k)`` on ``r_c < r <= laminar_ratio``.
Evaluated as ``exp(log(r)/k)`` it costs a ``log`` and an ``exp`` per flow, about half of the
fluid step of a humanoid's 76 chambers, and the libm calls keep the compiler from running the
chambers through the processor's vector units.  ``g`` is analytic on that interval (its
nearest singularity is the branch point at r = 0), so its Chebyshev interpolant converges
geometrically (Trefethen, *Approximation Theory and Approximation Practice*, 2013, Thm 8.2);
degree 16 reproduces ``psi`` to a few 1e-14 relative for air and stays below 1e-12 for any
``1.1 <= k <= 1.67`` and ``laminar_ratio <= 0.9999`` — round-off of the direct formula near
r = 1, where ``r^(2/k)`` and ``r^((k+1)/k)`` cancel.  The node values are computed without
that cancellation: ``g = r^(1/k) r expm1(((1 - k)/k) log r)``.

The kernel evaluates the polynomial in monomials of ``t = (r - centre) / half_width`` in
``[-1, 1]`` by Horner's rule: for this smooth ``g`` the monomial coefficients stay below 0.1,
so no digits are lost to cancellation.  :func:`flow_polynomial` checks the fit on a fine grid
and refuses a gas it cannot reproduce.
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import Chebyshev
from numpy.polynomial import chebyshev

#: degree of the polynomial; a compile-time constant of the kernel (its loop is unrolled)
DEGREE = 16
#: largest relative error of psi the fit may make on [r_c, laminar_ratio]
MAX_RELATIVE_ERROR = 1e-11
#: entries of the packed polynomial: centre, 1 / half-width, DEGREE + 1 coefficients
SIZE = DEGREE + 3


def g_exact(r, k):
    """g(r) = r^(2/k) - r^((k+1)/k) = psi(r)^2 [-], without cancellation near r = 1."""
    log_r = np.log(r)
    return np.exp(log_r / k) * r * np.expm1((1.0 - k) / k * log_r)


def flow_polynomial(heat_capacity_ratio: float, critical_ratio: float, laminar_ratio: float) -> np.ndarray:
    """(SIZE,) [centre, 1/half-width, a_0 .. a_DEGREE]: g(r) = sum a_j t^j, t = (r - centre) / half.

    Raises ValueError naming the gas fields when the interval is empty or the fit misses
    MAX_RELATIVE_ERROR (a gas far outside the range the module docstring states).
    """
    k, rc, rl = heat_capacity_ratio, critical_ratio, laminar_ratio
    if not (k > 1.0 and 0.0 < rc < rl < 1.0):
        raise ValueError(f"gas: need heat_capacity_ratio > 1 and critical_ratio < laminar_ratio < 1, "
                         f"got heat_capacity_ratio={k}, critical_ratio={rc}, laminar_ratio={rl}")
    centre, half = 0.5 * (rc + rl), 0.5 * (rl - rc)
    series = Chebyshev.interpolate(lambda r: g_exact(r, k), DEGREE, domain=[rc, rl])
    coefficients = chebyshev.cheb2poly(series.coef)
    r = np.linspace(rc, rl, 4001)
    fitted = np.polynomial.polynomial.polyval((r - centre) / half, coefficients)
    error = np.max(np.abs(np.sqrt(np.maximum(fitted, 0.0) / g_exact(r, k)) - 1.0))
    if not error <= MAX_RELATIVE_ERROR:
        raise ValueError(f"gas: the flow function's polynomial misses psi by {error:.1e} (relative) for "
                         f"heat_capacity_ratio={k}, laminar_ratio={rl}; expected <= {MAX_RELATIVE_ERROR:g}")
    return np.concatenate([[centre, 1.0 / half], coefficients])


def evaluate(packed: np.ndarray, r):
    """(g, dg/dr) at r in [r_c, laminar_ratio] from :func:`flow_polynomial`'s array — the
    kernel's Horner loop, in numpy, for the tests."""
    centre, inv_half, a = packed[0], packed[1], packed[2:]
    t = (np.asarray(r, float) - centre) * inv_half
    g, d = np.full_like(t, a[-1]), np.zeros_like(t)
    for coefficient in a[-2::-1]:
        d = d * t + g
        g = g * t + coefficient
    return g, d * inv_half
