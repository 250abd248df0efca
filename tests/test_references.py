"""Standard reference trajectories (paper 002 §V): stored recordings, range, speed, loading."""
import numpy as np
import pytest

from controllers.reference import (
    STANDARD_MARGIN_RAD,
    JointReference,
    hand_moved,
    reference_path,
    standard_references,
)
from pneumatics.errors import RecordingError, UnknownNameError
from pneumatics.recording import Recording, read_csv
from pneumatics.robot import load_robot


@pytest.fixture(scope="module")
def humanoid():
    return load_robot("humanoid38")


@pytest.mark.parametrize("name", ["arm2", "humanoid38"])
def test_three_stored_references_stay_inside_range_minus_margin(name, arm2, humanoid):
    robot = arm2 if name == "arm2" else humanoid
    lo, hi = robot.joint_range().T
    refs = standard_references(name)
    assert len(refs) == 3
    for ref in refs:
        assert ref.joint_names == robot.joint_names
        assert ref.duration_s == pytest.approx(60.0)
        tol = 1e-5  # the files keep 6 significant digits
        assert np.all(ref.q >= lo + STANDARD_MARGIN_RAD - tol) and np.all(ref.q <= hi - STANDARD_MARGIN_RAD + tol)
        # a person moving the robot by hand uses most of every joint's free range
        usable = (hi - lo) - 2 * STANDARD_MARGIN_RAD
        assert np.median(np.ptp(ref.q, axis=0) / usable) > 0.7
    # three different motions
    assert np.corrcoef(refs[0].q[:, 0], refs[1].q[:, 0])[0, 1] < 0.5


def test_fast_version_is_the_same_motion_at_twice_the_speed():
    normal = standard_references("arm2", "normal")[0]
    fast = standard_references("arm2", "fast")[0]
    assert fast.duration_s == pytest.approx(normal.duration_s / 2)
    t = fast.time[::7]  # on the fast grid: samples of the stored recording in both
    assert np.allclose([fast.reference(x) for x in t], [normal.reference(2 * x) for x in t], atol=1e-9)
    # velocities (smoothing spline) double, accelerations quadruple
    _, qd_n, qdd_n = normal.derivatives(2 * t)
    _, qd_f, qdd_f = fast.derivatives(t)
    scale = np.abs(qd_n).max()
    assert np.abs(qd_f - 2 * qd_n).max() < 0.05 * 2 * scale
    assert np.median(np.abs(qdd_f)) == pytest.approx(4 * np.median(np.abs(qdd_n)), rel=0.15)
    # arm2 fast references reach speeds of paper 002 Fig. 6A's order (~1000 deg/s)
    assert np.degrees(np.abs(fast.derivatives(fast.time)[1]).max()) > 400


def test_recording_round_trip(tmp_path):
    ref = hand_moved(["shoulder", "elbow"], [[-1.0, 1.0], [-1.2, 1.2]], 5.0, seed=4)
    path = tmp_path / "mine.csv"
    ref.to_recording({"note": "mine"}).to_csv(path)
    back = JointReference.from_recording(path, ["elbow", "shoulder"])
    assert back.joint_names == ["elbow", "shoulder"]
    assert np.allclose(back.q[:, 1], ref.q[:, 0], atol=1e-6) and np.allclose(back.time, ref.time)
    assert read_csv(path).meta["note"] == "mine"


def test_from_recording_names_missing_joints():
    rec = Recording(np.arange(10) * 0.01, {"ref.shoulder": np.zeros(10), "q.elbow": np.zeros(10)})
    with pytest.raises(RecordingError, match=r"ref\.elbow.*elbow.*has ref columns for: shoulder"):
        JointReference.from_recording(rec, ["shoulder", "elbow"])
    with pytest.raises(RecordingError, match="no reference columns"):
        JointReference.from_recording(Recording(np.arange(10) * 0.01, {"q.elbow": np.zeros(10)}))
    with pytest.raises(UnknownNameError, match="normal"):
        standard_references("arm2", "slow")


def test_stored_files_are_recordings_with_metadata():
    rec = read_csv(reference_path("arm2", 1))
    assert rec.names("ref") == ["shoulder", "elbow"]
    assert rec.meta["model"] == "arm2" and "python -m controllers.reference" in rec.meta["regenerate"]


def test_reference_is_numpy_interp_per_joint_bit_for_bit():
    """JointReference.reference interpolates every joint at once; the obviously-correct
    reference is numpy.interp per joint (held at the ends): equal to the last bit, at random
    times, at every sample and outside the reference's span."""
    from controllers.reference import hand_moved
    from pneumatics.robot import load_robot

    robot = load_robot("arm2")
    ref = hand_moved(robot.joint_names, robot.joint_range(), 10.0, seed=3)
    rng = np.random.default_rng(1)
    times = np.concatenate([rng.uniform(ref.time[0] - 1.0, ref.time[-1] + 1.0, 3000), ref.time])
    for t in times:
        held = min(max(t, ref.time[0]), ref.time[-1])
        slow = np.array([np.interp(held, ref.time, ref.q[:, j]) for j in range(ref.q.shape[1])])
        np.testing.assert_array_equal(ref.reference(float(t)), slow)
