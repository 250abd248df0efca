"""The compiled kernels' polynomial of the flow function against its closed form."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pneumatics import flow_polynomial as fp
from pneumatics.kernel import orifice_flow_compiled, pack_glob
from pneumatics.medium import GasCfg, _dpsi_dr, flow_function, orifice_flow


@settings(max_examples=40, deadline=None)
@given(k=st.floats(1.1, 1.67), laminar=st.floats(0.9, 0.9999))
def test_polynomial_reproduces_psi_and_its_slope(k, laminar):
    gas = GasCfg(heat_capacity_ratio=k, laminar_ratio=laminar)
    packed = fp.flow_polynomial(k, gas.critical_ratio, laminar)
    r = np.linspace(gas.critical_ratio, laminar, 3001)
    g, dg = fp.evaluate(packed, r)
    psi = np.sqrt(g)
    np.testing.assert_allclose(psi, flow_function(r, k), rtol=1e-11, atol=0)
    # dpsi/dr = g' / (2 psi): zero at r_c (psi's maximum), so compare there against its scale
    slope = _dpsi_dr(r, k)
    np.testing.assert_allclose(dg / (2 * psi), slope, rtol=1e-9, atol=1e-10 * np.abs(slope).max())


def test_g_exact_has_no_cancellation_near_one():
    """g = r^(2/k) - r^((k+1)/k) ~ (k-1)/k (1 - r) as r -> 1 (first-order Taylor)."""
    k, eps = 1.4, 1e-9
    assert fp.g_exact(1.0 - eps, k) == pytest.approx((k - 1) / k * eps, rel=1e-8)


@pytest.mark.parametrize("k, laminar", [(1.0, 0.995), (1.4, 0.3), (1.4, 1.0)])
def test_a_gas_outside_the_fit_is_refused_by_name(k, laminar):
    gas = GasCfg(heat_capacity_ratio=k, laminar_ratio=laminar)
    with pytest.raises(ValueError, match="laminar_ratio"):
        fp.flow_polynomial(k, gas.critical_ratio if k > 1 else 0.5, laminar)


def test_compiled_orifice_flow_matches_the_reference_in_every_regime():
    gas = GasCfg()
    glob = pack_glob(gas, 7e5, 1e5, 1e-3, 0.0)
    p_to = np.concatenate([np.linspace(0.5e5, 7.5e5, 2001), 7e5 * np.array([gas.critical_ratio, gas.laminar_ratio])])
    for p_from in (7e5, 3e5):
        ref = orifice_flow(2e-6, p_from, p_to, gas)
        fast = np.array([orifice_flow_compiled(2e-6, p_from, q, glob) for q in p_to]).T
        for got, want in zip(fast, ref):  # d/d p_down passes through 0 at r_c: its scale there
            np.testing.assert_allclose(got, want, rtol=1e-11, atol=1e-10 * np.abs(want).max())
