"""Recordings: the CSV format of DESIGN.md, its validation, and the DAQ of the runner."""
from pathlib import Path

import numpy as np
import pytest

from pneumatics.errors import RecordingError
from pneumatics.recording import RecordingWarning, read_csv, validate
from pneumatics.runner import OpenLoop, run
from pneumatics.sim import Simulation

BLIND = Path(__file__).resolve().parents[2] / "shared" / "samples" / "arm2-blind"


def small_run(arm2, seed=0, noise=True, seconds=0.5):
    sim = Simulation(arm2)
    sim.reset(pressure_pa=4e5)
    ctl = OpenLoop(lambda t: np.array([5.0, 5.0, 5.0 + 3 * np.sin(6 * t), 5.0 - 3 * np.sin(6 * t)]))
    return run(sim, ctl, seconds, noise=noise, seed=seed, record_velocity=True)


def test_round_trip(tmp_path, arm2):
    rec = small_run(arm2)
    rec.to_csv(tmp_path / "r.csv")
    back = read_csv(tmp_path / "r.csv")
    assert list(back.columns) == list(rec.columns)
    np.testing.assert_allclose(back.time, rec.time)
    np.testing.assert_allclose(back["p_a.elbow"], rec["p_a.elbow"], rtol=1e-6)
    assert back.meta["model"] == "arm2"
    assert validate(back, arm2.joint_names, arm2.actuator_names, model_name="arm2") == []


def test_runner_is_deterministic_for_a_seed(arm2):
    a, b, c = small_run(arm2, seed=3), small_run(arm2, seed=3), small_run(arm2, seed=4)
    for k in a.columns:
        np.testing.assert_array_equal(a[k], b[k])
    assert not np.array_equal(a["q.elbow"], c["q.elbow"])


def test_daq_average_is_the_mean_over_the_period(arm2):
    """Row k's sensors are the mean of the 10 physics steps ending at time[k]."""
    rec = small_run(arm2, noise=False, seconds=0.05)
    sim = Simulation(arm2)
    sim.reset(pressure_pa=4e5)
    samples = []
    u = np.column_stack([rec["u_a.shoulder"], rec["u_b.shoulder"], rec["u_a.elbow"], rec["u_b.elbow"]])
    for k in range(len(rec) - 1):
        sim.set_command(u[k])
        for _ in range(10):
            sim.step(1)
            samples.append(sim.pressure[2])
        assert abs(np.mean(samples[-10:]) - rec["p_a.elbow"][k + 1]) < 1e-6


def write(tmp_path, text, name="r.csv"):
    f = tmp_path / name
    f.write_text(text)
    return f


HEAD = "time,q.shoulder,q.elbow,p_a.shoulder,p_b.shoulder,p_a.elbow,p_b.elbow,u_a.shoulder,u_b.shoulder,u_a.elbow,u_b.elbow\n"
ROW = "{t},0,0,3e5,3e5,3e5,3e5,5,5,5,5\n"


def test_non_monotonic_time_names_the_line(tmp_path):
    f = write(tmp_path, HEAD + ROW.format(t=0) + ROW.format(t=0.01) + ROW.format(t=0.01))
    with pytest.raises(RecordingError, match="not strictly increasing at line 4"):
        read_csv(f)


def test_nan_names_line_and_column(tmp_path):
    f = write(tmp_path, HEAD + ROW.format(t=0) + ROW.format(t=0.01).replace("3e5,3e5,3e5,3e5", "3e5,nan,3e5,3e5"))
    with pytest.raises(RecordingError, match="line 3, column 'p_b.shoulder' is nan"):
        read_csv(f)


def test_text_in_a_number_field(tmp_path):
    f = write(tmp_path, HEAD + ROW.format(t=0) + ROW.format(t="0,01"))
    with pytest.raises(RecordingError, match="line 3 has 12 fields, the header has 11"):
        read_csv(f)


def test_unknown_joint_and_missing_commands(tmp_path, arm2):
    rec = read_csv(write(tmp_path, HEAD.replace("q.elbow", "q.wrist") + ROW.format(t=0) + ROW.format(t=0.01)))
    with pytest.raises(RecordingError, match="column 'q.wrist' names unknown joint 'wrist'; joints: shoulder, elbow"):
        validate(rec, arm2.joint_names, arm2.actuator_names)
    rec = read_csv(write(tmp_path, HEAD.replace(",u_b.elbow", "") + ROW.format(t=0)[:-3] + "\n" + ROW.format(t=0.01)[:-3] + "\n"))
    with pytest.raises(RecordingError, match="missing command column\\(s\\) u_b.elbow"):
        validate(rec, arm2.joint_names, arm2.actuator_names)


def test_gauge_pressures_warn_and_bar_pressures_fail(tmp_path, arm2):
    rec = read_csv(write(tmp_path, HEAD + "".join(ROW.format(t=k / 100).replace("3e5", "2e4") for k in range(5))))
    with pytest.warns(RecordingWarning, match="stays below 1 bar .* gauge pressure"):
        validate(rec, arm2.joint_names, arm2.actuator_names)
    rec = read_csv(write(tmp_path, HEAD + "".join(ROW.format(t=k / 100).replace("3e5", "3.2") for k in range(5))))
    with pytest.raises(RecordingError, match="looks like bar"):
        validate(rec, arm2.joint_names, arm2.actuator_names)


def test_model_mismatch_from_the_sidecar(tmp_path, arm2):
    rec = small_run(arm2, seconds=0.05)
    rec.meta["model"] = "humanoid38"
    rec.to_csv(tmp_path / "r.csv")
    with pytest.raises(RecordingError, match="recorded with model 'humanoid38'"):
        validate(read_csv(tmp_path / "r.csv"), arm2.joint_names, arm2.actuator_names, model_name="arm2")


@pytest.mark.skipif(not BLIND.is_dir(), reason="shared/samples not beside the repo")
def test_blind_samples_read_and_validate(arm2):
    for f in sorted(BLIND.glob("case_*.csv")):
        rec = read_csv(f)
        assert validate(rec, arm2.joint_names, arm2.actuator_names, model_name="arm2") == []
        assert abs(rec.rate_hz - 100.0) < 1e-6
