"""Least-squares summaries: the Gauss-Newton standard errors and condition number."""
import numpy as np
import scipy.sparse as sp
from hypothesis import given, settings, strategies as st

from scipy.optimize import lsq_linear

from identification.base.lsq import bounded_linear, covariance, linear


def test_standard_errors_are_the_textbook_ones():
    """OLS of a line through noisy points: se = sqrt(s^2 diag((A^T A)^-1)) (Gauss-Markov)."""
    rng = np.random.default_rng(0)
    x = np.linspace(0.0, 1.0, 200)
    A = np.column_stack([np.ones_like(x), x])
    b = 0.5 + 2.0 * x + 0.1 * rng.normal(size=x.size)
    fit = linear(A, b, ["c", "m"])
    s2 = fit.rss / (x.size - 2)
    assert np.allclose(fit.stderr, np.sqrt(s2 * np.diag(np.linalg.inv(A.T @ A))), rtol=1e-10)
    assert abs(fit.values[1] - 2.0) < 4 * fit.stderr[1]


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(2, 12), st.floats(0.05, 0.9))
def test_a_sparse_jacobian_gives_what_its_dense_form_gives(seed, p, density):
    """The sparse path (J^T J formed sparse, the Jacobian never made dense) is the dense one."""
    rng = np.random.default_rng(seed)
    jac = sp.random(300, p, density=density, random_state=rng, format="csr") + sp.eye(300, p)
    se_sparse, cond_sparse = covariance(jac, 3.7, 300)
    se_dense, cond_dense = covariance(jac.toarray(), 3.7, 300)
    assert np.allclose(se_sparse, se_dense, rtol=1e-9, atol=0.0)
    assert np.isclose(cond_sparse, cond_dense, rtol=1e-6)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 8), st.integers(0, 3))
def test_the_bounded_fit_on_the_triangular_factor_is_lsq_linear_on_the_whole_matrix(seed, k, n_binding):
    """bounded_linear (a k x k problem from A's QR) gives lsq_linear's minimiser of the m x k
    one, bounds binding or not (``n_binding`` parameters pushed against a bound)."""
    rng = np.random.default_rng(seed)
    m = 50 * k
    A = rng.normal(size=(m, k)) * rng.uniform(0.1, 10.0, size=k)
    x_true = rng.normal(size=k)
    b = A @ x_true + 0.1 * rng.normal(size=m)
    lower, upper = np.full(k, -np.inf), np.full(k, np.inf)
    for i in rng.permutation(k)[:n_binding]:            # a bound on the wrong side of the free optimum
        upper[i] = x_true[i] - 0.5
    fast = bounded_linear(A, b, lower, upper)
    full = lsq_linear(A, b, bounds=(lower, upper)).x
    assert np.all(fast <= upper + 1e-12) and np.all(fast >= lower - 1e-12)
    cost = lambda x: float(np.sum((A @ x - b) ** 2))
    assert cost(fast) <= cost(full) * (1 + 1e-9) + 1e-12
    assert np.allclose(fast, full, rtol=1e-6, atol=1e-8)
