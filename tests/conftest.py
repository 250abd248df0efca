import numpy as np
import pytest

from pneumatics.robot import load_robot


@pytest.fixture(scope="session")
def arm2():
    return load_robot("arm2")


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
