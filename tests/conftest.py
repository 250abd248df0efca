import numpy as np
import pytest

from pneumatics.robot import load_robot


@pytest.fixture(scope="session")
def arm2():
    return load_robot("arm2")


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def pytest_collection_modifyitems(items):
    """The tests marked ``heavy`` first (a stable sort keeps the others in their order): with
    a worker per core (pytest-xdist, ``--dist loadfile``) a file of several minutes handed out
    last would run alone at the end while the other workers idle."""
    items.sort(key=lambda item: item.get_closest_marker("heavy") is None)
