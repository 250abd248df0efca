"""Reinsch's smoothing spline against SciPy's make_smoothing_spline, the obviously-correct
reference: the same spline, values and first two derivatives, on and between the knots."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import make_smoothing_spline

from identification.base.smoothing import smoothing_spline


def _max_rel(ref, got):
    return float(np.max(np.abs(ref - got)) / max(np.max(np.abs(ref)), 1e-300))


@settings(max_examples=40, deadline=None)
@given(n=st.integers(5, 400), log_lam=st.floats(-12, 0), seed=st.integers(0, 2**31), uniform=st.booleans())
def test_same_spline_as_scipy(n, log_lam, seed, uniform):
    rng = np.random.default_rng(seed)
    dt = 0.01
    t = np.arange(n) * dt if uniform else np.cumsum(rng.uniform(0.2, 1.8, n)) * dt
    y = np.sin(3 * t) + 0.05 * rng.standard_normal(n)
    lam = 10.0 ** log_lam
    ref, got = make_smoothing_spline(t, y, lam=lam), smoothing_spline(t, y, lam)
    x = np.concatenate([t, 0.5 * (t[1:] + t[:-1])])
    for k, tol in ((0, 1e-8), (1, 1e-7), (2, 1e-6)):
        assert _max_rel(ref.derivative(k)(x) if k else ref(x), got.derivative(k)(x) if k else got(x)) < tol


def test_channels_at_once_equal_one_by_one():
    rng = np.random.default_rng(1)
    t = np.arange(300) * 0.01
    y = rng.standard_normal((300, 3)).cumsum(axis=0)
    both = smoothing_spline(t, y, 1e-4)(t)
    for k in range(3):
        assert np.allclose(both[:, k], smoothing_spline(t, y[:, k], 1e-4)(t), rtol=0, atol=1e-12)


def test_limits_interpolate_and_fit_a_line():
    # lam -> 0: the interpolating spline; lam -> infinity: the least-squares line
    rng = np.random.default_rng(2)
    t = np.arange(50) * 0.1
    y = rng.standard_normal(50)
    assert np.allclose(smoothing_spline(t, y, 1e-14)(t), y, atol=1e-6)
    line = np.polyval(np.polyfit(t, y, 1), t)
    assert np.allclose(smoothing_spline(t, y, 1e9)(t), line, atol=1e-4)
