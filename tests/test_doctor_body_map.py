"""The doctor's body map: every finding on the joint it acts at, in the PNG and the .rrd."""
import subprocess
import sys

import pytest

from identification.doctor.valve_arm.body_map import actuator_joints, body_map_png, log_body_map, marks
from pneumatics.robot import load_robot


@pytest.fixture(scope="module")
def humanoid():
    return load_robot("humanoid38")


REPORT = {"model": "humanoid38",
          "findings": [{"effect": "valve_leak", "where": {"actuator": "left_elbow", "chamber": "a"}},
                       {"effect": "coulomb_friction", "where": {"joint": "right_knee"}},
                       {"effect": "supply_droop", "where": {"supply": "all"}}],
          "unexplained": [{"where": {"actuator": "left_elbow", "chamber": "b"}, "regime": "r", "share_of_residual": 0.2},
                          {"where": {"joint": "neck_yaw"}, "regime": "r", "share_of_residual": 0.3}]}


def test_every_actuator_drives_its_joint(humanoid):
    # humanoid38's linear cylinders act through spatial tendons, its rotary ones on the joint
    # itself; each is named after the joint it drives
    joints = actuator_joints(humanoid)
    assert len(joints) == len(humanoid.actuator_names) == 38
    assert all(a == j for a, j in joints.items())
    assert actuator_joints(load_robot("arm2")) == {"shoulder": "shoulder", "elbow": "elbow"}


def test_marks_put_each_entry_on_its_joint(humanoid):
    found, supply = marks(humanoid, REPORT)
    assert set(found) == {"left_elbow", "right_knee", "neck_yaw"}
    assert found["left_elbow"].findings == ["valve_leak (chamber a)"]
    assert found["left_elbow"].unexplained == ["chamber b"]
    assert found["neck_yaw"].findings == [] and found["neck_yaw"].unexplained == ["torque"]
    assert supply == ["supply_droop"]


def test_png_and_rerun_marks(humanoid, tmp_path):
    from workflow.rerun_log import RerunLogger

    assert body_map_png(humanoid, REPORT, tmp_path) == "body_map.png"
    assert (tmp_path / "body_map.png").stat().st_size > 10_000
    rrd = tmp_path / "map.rrd"
    logger = RerunLogger(humanoid, path=rrd)
    assert log_body_map(logger, humanoid, REPORT) == 3
    logger.close()
    done = subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", str(rrd)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
