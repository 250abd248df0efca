"""A joint's unexplained torque is reported only when the yardstick's fitted torque replays the
joint's held-out angle (search._moves_its_angle, angle_replay.yardstick_angle): the keep rule of
the torque balance's findings, applied to its yardsticks.  On humanoid38's nulls the limit
cycle's equation error at the jaw is paid by a yardstick that is no torque on the link."""
import pytest

import identification.doctor.valve_arm.search as search
from identification.doctor.valve_arm.diagnose import diagnose
from pneumatics.recording import read_csv
from pneumatics.robot import load_robot
from scenarios._variantsim.cases import make_case

OUTSIDE = "outside_vocabulary"


@pytest.fixture(scope="module")
def hose(tmp_path_factory):
    """A hose pulling arm2's shoulder (random-form generator, a development seed), 20 s + 10 s."""
    truth = make_case(tmp_path_factory.mktemp("hose"), 739800660, [OUTSIDE], seconds=20.0, heldout_seconds=10.0,
                      name="hose", forms=["hose_spring"])
    assert truth["effects"][0]["where"] == {"joint": "shoulder"}
    return [read_csv(truth["recordings"]["main"])], [read_csv(truth["recordings"]["heldout"])]


def test_a_hose_on_the_shoulder_replays_its_angle_and_stays_unexplained(hose):
    rep = diagnose(load_robot("arm2"), *hose)
    assert rep["findings"] == []
    (u,) = [u for u in rep["unexplained"] if u["where"] == {"joint": "shoulder"}]
    # the hose's torque, fitted on the torque balance, replays the held-out angle far better
    evidence = u["evidence"].split("replays the held-out angle at NRMSE ")[1]
    after, before = float(evidence.split(" (")[0]), float(evidence.split("(")[1].split(" without")[0])
    assert after < 0.7 * before
    assert rep["diagnostics"]["unexplained_withdrawn"] == []


def test_a_yardstick_whose_torque_does_not_replay_the_angle_is_withdrawn(hose, monkeypatch):
    """The same recording with the replay's verdict forced to 'worse': the entry goes to
    diagnostics.unexplained_withdrawn with the two NRMSEs, and the doctor reports nothing."""
    monkeypatch.setattr(search, "yardstick_angle", lambda run, yard: (0.010, 0.012))
    rep = diagnose(load_robot("arm2"), *hose)
    assert not [u for u in rep["unexplained"] if u["where"] == {"joint": "shoulder"}]
    withdrawn = [w for w in rep["diagnostics"]["unexplained_withdrawn"] if w["where"] == {"joint": "shoulder"}]
    assert withdrawn and "0.01 without it, 0.012 with it" in withdrawn[0]["why"]
