"""A finding's regime is where it removes the residual, not where the residual is largest."""
import numpy as np

from identification.base.statistics import locate_energy, locate_regime


def test_the_regime_a_finding_explains_is_not_the_noisiest_one():
    """Half the samples move fast and carry three times the noise; a friction-like term of
    size 1 acts only in the slow half.  The residual before the finding is densest in the fast
    half, the energy the finding removes in the slow half, where the term lives."""
    rng = np.random.default_rng(0)
    n = 20000
    fast = np.arange(n) % 2 == 0
    term = np.where(fast, 0.0, 1.0)
    noise = rng.normal(0.0, np.where(fast, 3.0, 1.0))
    before, after = noise + term, noise
    regimes = {"fast": fast, "slow": ~fast}
    assert locate_regime(before, regimes)[0] == "fast"
    name, lift, share = locate_energy(before ** 2 - after ** 2, regimes)
    assert name == "slow" and lift > 1.8 and share > 0.9


def test_energy_that_nothing_removes_stays_throughout():
    regimes = {"a": np.arange(100) < 50}
    assert locate_energy(np.zeros(100), regimes)[0] == "throughout"
    assert locate_energy(-np.ones(100), regimes)[0] == "throughout"
