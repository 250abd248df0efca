import numpy as np
import pytest

from pneumatics.robot import load_robot


@pytest.fixture(scope="session")
def arm2():
    return load_robot("arm2")


@pytest.fixture(scope="session")
def diagnose_case():
    """The arm2 doctor's report on a made case (a truth dict of scenarios._cases or the random-form
    generator), read from its recording files as a user would give them: main and held out."""
    from identification.doctor.valve_arm.diagnose import diagnose
    from pneumatics.recording import read_csv

    def run(truth) -> dict:
        return diagnose(load_robot("arm2"), [read_csv(truth["recordings"]["main"])],
                        [read_csv(truth["recordings"]["heldout"])])
    return run


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def pytest_collection_modifyitems(items):
    """The tests marked ``heavy`` first (a stable sort keeps the others in their order): with
    a worker per core (pytest-xdist, ``--dist loadfile``) a file of several minutes handed out
    last would run alone at the end while the other workers idle."""
    items.sort(key=lambda item: item.get_closest_marker("heavy") is None)
