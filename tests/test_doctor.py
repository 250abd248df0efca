"""pneumasim doctor on the published blind samples (made by code that is not pneumasim) and on bad input."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from identification.doctor.valve_arm.diagnose import diagnose
from identification.doctor.valve_arm.report import write
from pneumatics.errors import RecordingError
from pneumatics.recording import Recording, read_csv
from pneumatics.robot import load_robot

BLIND = Path(__file__).resolve().parents[2] / "shared" / "samples" / "arm2-blind"
pytestmark = pytest.mark.skipif(not BLIND.is_dir(), reason="shared/samples not beside the repo")

KEYS = {"model", "verdict", "baseline", "calibrated", "findings", "unexplained"}


def doctor(case):
    robot = load_robot("arm2")
    rep = diagnose(robot, [read_csv(BLIND / f"{case}.csv")], [read_csv(BLIND / f"{case}_heldout.csv")])
    return robot, rep


# a whole doctor's run, slow for CI's 15 minutes;
# the --fast variant benchmark names a LuGre friction in the default run
@pytest.mark.slow
def test_lugre_friction_on_the_shoulder_is_named_coulomb_friction(tmp_path):
    robot, rep = doctor("case_befd9d0f")
    assert rep["verdict"] == "missing_physics"
    assert [(f["effect"], f["where"]) for f in rep["findings"]] == [("coulomb_friction", {"joint": "shoulder"})]
    f = rep["findings"][0]
    fc = f["parameters"]["coulomb_nm"]
    assert 0.02 < fc["value"] < 0.08 and fc["stderr"] < 0.2 * fc["value"]  # truth: 0.045 N m (LuGre)
    assert f["heldout_nrmse"]["after"] < 0.8 * f["heldout_nrmse"]["before"]
    # friction lives where the joint moves slowly or reverses: the fit gets better there too
    inside = f["heldout_nrmse_in_regime"]
    assert f["regime"] != "throughout" and inside["after"] < 0.8 * inside["before"]
    by = f["heldout_nrmse_by_regime"]
    assert by[f["regime"]]["before"] == inside["before"] and all(0 < v["share_of_time"] <= 1 for v in by.values())
    assert rep["unexplained"] == []
    write(rep, tmp_path, robot)
    on_disk = json.loads((tmp_path / "report.json").read_text())
    assert KEYS <= set(on_disk) and on_disk["findings"][0]["effect"] == "coulomb_friction"
    assert (tmp_path / "report.md").read_text().startswith("# pneumasim doctor report")
    assert "![regimes_finding_1.png](regimes_finding_1.png)" in (tmp_path / "report.md").read_text()
    # Ljung's residual tests, before and after, per pressure channel
    d = on_disk["diagnostics"]
    assert set(d["ljung_box_heldout_pressure"]) == set(d["input_xcorr_heldout_pressure"]) - {"input"} == \
        {f"p_{c}.{a}" for a in ("shoulder", "elbow") for c in "ab"}
    for k, v in d["ljung_box_heldout_pressure"].items():
        assert v["after"]["q"] > 0 and 0 <= v["after"]["p"] <= 1
        x = d["input_xcorr_heldout_pressure"][k]["after"]
        assert 0 <= x["max_abs"] <= 1 and 0 < x["bound"] < 0.1 and 0 <= x["lag_ms"] <= 50
    assert "Residual tests (Ljung)" in (tmp_path / "report.md").read_text()
    subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", str(tmp_path / "doctor.rrd")], check=True,
                   capture_output=True)


def test_null_case_finds_nothing():
    _, rep = doctor("case_8e12431d")
    assert rep["verdict"] == "no_significant_mismatch" and rep["findings"] == [] and rep["unexplained"] == []
    # calibration absorbed the +-10 % parameter errors: the fit is good on every channel
    assert min(rep["baseline"]["heldout_r2"].values()) > 0.95
    # ...and the rigid body's share of them: the hidden link factors 1.070 and 1.082
    truth = json.loads((BLIND / "case_8e12431d.truth.json").read_text())["parameter_perturbation"]["factors"]
    cal = rep["calibrated"]
    assert cal["mass_scale.upper_link"] == pytest.approx(truth["link.shoulder.mass_and_inertia"], rel=0.02)
    assert cal["mass_scale.forearm"] == pytest.approx(truth["link.elbow.mass_and_inertia"], rel=0.01)
    # the shoulder armature is one more shoulder inertia: lumped with the upper link, kept nominal
    kept = rep["diagnostics"]["rigid_body_kept_nominal"]
    assert "mass_scale.upper_link" in kept["armature_scale.shoulder"] and cal["armature_scale.shoulder"] == 1.0


@pytest.mark.slow
def test_bouc_wen_valve_hysteresis_is_named_and_located():
    _, rep = doctor("case_2e0854bc")
    assert [(f["effect"], f["where"]) for f in rep["findings"]] == [("valve_hysteresis", {"actuator": "elbow", "chamber": "b"})]


@pytest.mark.slow
def test_effect_outside_the_vocabulary_lands_in_unexplained_located():
    _, rep = doctor("case_2e6a35dc")
    assert rep["findings"] == []
    assert [u["where"] for u in rep["unexplained"]] == [{"actuator": "elbow", "chamber": "a"}]


def test_doctor_cli_bad_input_is_one_line_and_keeps_old_reports(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.json").write_text('{"old": true}')
    rec = read_csv(BLIND / "case_8e12431d.csv")
    short = rec.slice(0, 1.0)
    short.to_csv(tmp_path / "short.csv")
    nocmd = Recording(rec.time, {k: v for k, v in rec.columns.items() if not k.startswith("u_b")})
    nocmd.to_csv(tmp_path / "nocmd.csv")
    cases = {"short.csv": "too short for the doctor", "nocmd.csv": "missing command column(s) u_b.shoulder"}
    for name, msg in cases.items():
        r = subprocess.run([sys.executable, "-m", "pneumasim.cli", "doctor", "--model", "arm2", str(tmp_path / name),
                            "--out", str(out)], capture_output=True, text=True)
        assert r.returncode != 0 and msg in r.stderr and "Traceback" not in r.stderr, r.stderr
    r = subprocess.run([sys.executable, "-m", "pneumasim.cli", "doctor", "--model", "humanoid38",
                        str(BLIND / "case_8e12431d.csv"), "--out", str(out)], capture_output=True, text=True)
    assert r.returncode != 0 and "unknown joint" in r.stderr
    assert json.loads((out / "report.json").read_text()) == {"old": True}


def test_gaps_in_time_are_refused(tmp_path):
    rec = read_csv(BLIND / "case_8e12431d.csv")
    keep = np.ones(len(rec), bool)
    keep[3000:3050] = False
    gap = Recording(rec.time[keep], {k: v[keep] for k, v in rec.columns.items()}, {}, "gap.csv")
    with pytest.raises(RecordingError, match="not uniform"):
        diagnose(load_robot("arm2"), [gap])


def test_pooled_recordings_keep_their_joins_out_of_windows_and_torque_samples():
    from identification.doctor.valve_arm.data import pool, prepare
    from identification.doctor.valve_arm.torque_balance import torque_data
    from identification.doctor.valve_arm.pneumatic import Windows

    robot = load_robot("arm2")
    rec = read_csv(BLIND / "case_befd9d0f.csv")
    mid = rec.time[0] + 0.5 * (rec.time[-1] - rec.time[0])
    parts = [prepare(robot, rec.slice(rec.time[0], mid)), prepare(robot, rec.slice(mid, rec.time[-1] + 1))]
    exp = pool(parts)
    n0 = parts[0].t.size
    assert exp.breaks == (n0,) and exp.t.size == n0 + parts[1].t.size
    assert np.allclose(np.diff(exp.t), np.diff(rec.time).mean(), rtol=1e-6)  # one uniform grid
    assert exp.fine_t.size == int(round((exp.t[-1] - exp.t[0]) / 1e-3)) + 1
    np.testing.assert_array_equal(exp.p[n0:], parts[1].p)
    win = Windows.tile(exp.t.size, 30, breaks=exp.breaks)
    assert not np.any((win.starts < n0) & (win.starts + 31 >= n0))  # no window straddles the join
    td = torque_data(exp)
    assert not td.valid[n0 - 5:n0 + 5].any() and td.valid[n0 + 50]


def test_replay_nrmse_inside_a_regime_shares_the_overall_scale():
    """ReplayResult.nrmse(rows): the RMS error over the replayed samples of the given rows,
    divided by the measured channel's s.d. over all samples (not the subset's own)."""
    import numpy as np

    from identification.doctor.valve_arm.replay import ReplayResult

    meas = np.sin(np.linspace(0, 6, 40))
    pred = meas + np.where(np.arange(40) < 10, 0.2, 0.0)       # wrong only on the first rows
    rr = ReplayResult({"x": pred}, {"x": meas}, np.arange(40) * 0.01, np.arange(40) + 5)
    rows = np.zeros(50, bool)
    rows[5:15] = True                                           # experiment rows 5..14 = samples 0..9
    assert rr.nrmse(np.ones(50, bool))["x"] == pytest.approx(rr.nrmse()["x"])
    assert rr.nrmse(rows)["x"] == pytest.approx(0.2 / np.std(meas))
    assert rr.nrmse(~rows)["x"] == pytest.approx(0.0)
