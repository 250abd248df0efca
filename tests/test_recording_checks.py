"""Recordings meet a model: gauge pressures, degrees, too short or too coarse recordings get
one clear error naming the column, what it read and the fix (issue 18, input side, item 1)."""
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from identification.doctor.valve_arm.data import prepare
from identification.doctor.valve_arm.diagnose import diagnose
from identification.doctor.valve_arm.final_fit import final_terms
from identification.doctor.valve_arm.rules import passes_keep_rule
from pneumatics.errors import RecordingError
from pneumatics.recording import Recording, RecordingWarning, read_csv
from pneumatics.recording_checks import add_room_pressure, check_for_robot, check_pressures



def sample(arm2, seconds=20.0) -> Recording:
    """An arm2 recording that starts at rest for 1 s (every valve open to the room, the
    chambers at room pressure), as a lab recording does, then tracks a hand-moved reference."""
    from controllers.pid import ARM2_PIDF
    from controllers.reference import hand_moved
    from pneumatics.runner import run
    from pneumatics.sim import Simulation
    sim = Simulation(arm2)
    ref = hand_moved(arm2.joint_names, arm2.joint_range(), seconds, seed=3)
    sim.reset(qpos=ref.reference(0.0))
    pidf = ARM2_PIDF.build(ref, arm2.tables.valve[:, 0])

    class RestThenTrack:
        def reset(self):
            pidf.reset()

        def __call__(self, t, obs):
            return np.zeros(len(arm2.tables.valve)) if t < 1.0 else pidf(t, obs)

    return run(sim, RestThenTrack(), seconds)


def gauge(rec: Recording, room_pa: float) -> Recording:
    cols = {c: (v - room_pa if c.startswith("p_") else v) for c, v in rec.columns.items()}
    return Recording(rec.time, cols, dict(rec.meta), "gauge.csv")


@pytest.fixture(scope="module")
def rec(arm2):
    return sample(arm2)


def test_gauge_recording_is_refused_with_the_fix(arm2, rec):
    g = gauge(rec, arm2.tables.room_pa)
    assert g.matrix("p_a", arm2.actuator_names).max() > 1e5  # it reaches 1 bar: the old check let it pass
    assert abs(g["p_a.elbow"][50]) < 2e4  # at rest: about 0 Pa gauge
    with pytest.raises(RecordingError, match=r"gauge.csv: column p_.* reads down to .* look like gauge pressures "
                                             r".*pneumasim doctor --gauge.*gauge unit"):
        prepare(arm2, g)
    exp = prepare(arm2, add_room_pressure(g, arm2.tables.room_pa))  # the fix: absolute again
    assert np.allclose(exp.p, prepare(arm2, rec).p)


def test_subatmospheric_pressures_warn(rec):
    dip = Recording(rec.time, {"p_a.shoulder": np.linspace(7e4, 5e5, len(rec))}, {}, "dip.csv")
    with pytest.warns(RecordingWarning, match="dip.csv: column p_a.shoulder reads down to 7e\\+04 Pa.* gauge"):
        check_pressures(dip, 1e5, 7e5)


def test_subatmospheric_dips_beside_a_column_at_the_supply_do_not_warn(rec):
    """A column near the supply (99th percentile within 0.75 bar of 7 bar) cannot be gauge, so
    another's dip to 0.7 bar is a chamber expanded with its valve shut: no warning."""
    n = len(rec)
    cols = {"p_a.shoulder": np.linspace(7e4, 5e5, n), "p_b.shoulder": np.linspace(1e5, 6.9e5, n)}
    cols["p_b.shoulder"][: n // 2] = 6.6e5
    with warnings.catch_warnings():
        warnings.simplefilter("error", RecordingWarning)
        check_pressures(Recording(rec.time, cols, {}, "dip_beside_supply.csv"), 1e5, 7e5)
    cols["p_b.shoulder"] = cols["p_b.shoulder"] - 1e5  # gauge: under the supply's 6 bar gauge
    with pytest.warns(RecordingWarning, match="dip_beside_supply.csv: column p_a.shoulder .* gauge pressures\\?"):
        check_pressures(Recording(rec.time, cols, {}, "dip_beside_supply.csv"), 1e5, 7e5)


def test_pressures_that_never_reach_room_or_exceed_the_supply(rec):
    low = Recording(rec.time, {"p_a.shoulder": np.full(len(rec), 8e4)}, {}, "low.csv")
    with pytest.raises(RecordingError, match="no pressure column reaches the room pressure 100000 Pa"):
        check_pressures(low, 1e5, 7e5)
    high = Recording(rec.time, {"p_a.shoulder": rec["p_a.shoulder"] * 10}, {}, "x10.csv")
    with pytest.raises(RecordingError, match="x10.csv: column p_a.shoulder reads up to .* more than 1.5 x the supply"):
        check_pressures(high, 1e5, 7e5)


def test_degrees_are_named_with_the_joint_range(arm2, rec):
    deg = Recording(rec.time, {**rec.columns, "q.elbow": np.degrees(rec["q.elbow"])}, {}, "deg.csv")
    big = np.degrees(rec["q.elbow"])
    extreme = big.max() if abs(big.max()) >= abs(big.min()) else big.min()
    with pytest.raises(RecordingError, match=rf"deg.csv: column q.elbow looks like degrees \((max|min) "
                                             rf"{extreme:.4g}, joint range ±1.22 rad\)"):
        prepare(arm2, deg)


def test_angles_outside_the_range_in_no_known_unit(arm2, rec):
    off = Recording(rec.time, {**rec.columns, "q.shoulder": rec["q.shoulder"] + 3.0}, {}, "off.csv")
    with pytest.raises(RecordingError, match=r"column q.shoulder spans .* outside the joint range ±1.05 rad"):
        check_for_robot(off, arm2)


def test_too_short_says_the_real_minimum(arm2, rec):
    with pytest.raises(RecordingError, match=r"500 rows \(4.99 s\) is too short for the doctor: it needs at least "
                                             r"667 rows \(6.67 s at 100 Hz\); without --holdout files"):
        diagnose(arm2, [rec.slice(0.0, 5.0)])


def test_gauge_option_of_the_cli_and_its_error(arm2, rec, tmp_path, capsys):
    from pneumasim.cli import main
    g = gauge(rec, arm2.tables.room_pa)
    g.to_csv(tmp_path / "g.csv")
    with pytest.raises(SystemExit) as e:
        main(["doctor", "--model", "arm2", str(tmp_path / "g.csv"), "--out", str(tmp_path / "out")])
    msg = str(e.value.code)
    assert msg.startswith("pneumasim: error: ") and "gauge pressures" in msg and "--gauge" in msg
    assert "Traceback" not in capsys.readouterr().err


def test_sidecar_room_pressure_is_used_by_gauge(tmp_path):
    from pneumasim.cli import build_parser, recordings_from_args
    (tmp_path / "g.csv").write_text("time,p_a.x\n0,0\n0.01,2e5\n")
    (tmp_path / "g.json").write_text(json.dumps({"room_pa": 95000.0}))
    args = build_parser().parse_args(["doctor", "--model", "arm2", str(tmp_path / "g.csv"), "--out", "o", "--gauge"])
    (recs, _) = recordings_from_args(args)
    assert np.allclose(recs[0]["p_a.x"], [95000.0, 295000.0]) and recs[0].meta["gauge_room_pa"] == 95000.0


def test_jetpipe_gauge_recording_names_the_fix():
    from identification.doctor.jetpipe.data import check, load_model_cfg
    cfg = load_model_cfg("jetpipe")
    t = np.arange(2000) * 1e-3
    cols = {"p_a.piston": 2e5 + 0 * t, "p_b.piston": 0 * t + 50.0, "force.piston": 0 * t, "i_cmd.piston": 0 * t}
    with pytest.raises(RecordingError, match="column p_b.piston reads down to 50 Pa, .* gauge pressures"):
        check(Recording(t, cols, {}, "jp.csv"), "jetpipe", cfg)


def test_keep_rule_on_final_values():
    assert passes_keep_rule([4.0], [1.0]) and passes_keep_rule([-8.0, 5.0], [2.0, 1.0])
    assert not passes_keep_rule([3.9], [1.0])
    assert not passes_keep_rule([1.0], [np.nan]) and not passes_keep_rule([1.0], [0.0])


def test_final_terms_report_the_refined_offset_as_the_replays_plus_the_refinement():
    class H:  # a kept torque-balance term: one parameter, on chamber 2
        def __init__(self, n):
            self.params, self.chambers = [("p", 0, 0)] * n, [2]
    offset, friction = H(1), H(2)
    finals = final_terms([offset, friction], [offset], np.array([-300.0, 0.5, 0.1]), np.array([900.0, 0.01, 0.2]),
                         np.array([0.0, 0.0, 2000.0, 0.0]))
    (h0, v0, e0), (h1, v1, e1) = finals
    assert h0 is offset and v0[0] == 1700.0 and e0[0] == 900.0   # 1.9 s.e.: fails the rule
    assert not passes_keep_rule(v0, e0)
    assert h1 is friction and np.allclose(v1, [0.5, 0.1]) and not passes_keep_rule(v1, e1)


def test_sample_rate_is_named_with_what_the_doctor_needs(arm2, rec):
    coarse = Recording(rec.time[::10], {c: v[::10] for c, v in rec.columns.items()}, {}, "coarse.csv")
    with pytest.raises(RecordingError, match="sample rate 10 Hz is below the 20 Hz the doctor needs"):
        prepare(arm2, coarse)
    odd = Recording(rec.time * 1.25, dict(rec.columns), {}, "odd.csv")
    with pytest.raises(RecordingError, match="sample rate 80 Hz is not a whole fraction of 1 kHz"):
        prepare(arm2, odd)


def test_sample_rate_above_1khz(arm2, rec):
    fast = Recording(rec.time / 20, dict(rec.columns), {}, "fast.csv")
    with pytest.raises(RecordingError, match="2000 Hz is above 1 kHz"):
        prepare(arm2, fast)


BLIND = Path(__file__).resolve().parents[2] / "shared" / "samples" / "arm2-blind"


@pytest.mark.slow
@pytest.mark.skipif(not BLIND.is_dir(), reason="shared/samples not beside the repo")
def test_every_reported_finding_passes_the_keep_rule_at_its_final_values(arm2):
    """A gauge recording whose chambers never came near the room pressure passes the checks
    with a warning, and the doctor names pressure-sensor offsets of about the room pressure;
    whatever it reports, each fitted parameter is >= 4 standard errors from 0 as reported."""
    from identification.doctor.valve_arm.rules import MIN_T
    case = "case_2e0854bc"
    recs = [gauge(read_csv(BLIND / f"{case}{s}.csv"), arm2.tables.room_pa) for s in ("", "_heldout")]
    with pytest.warns(RecordingWarning, match="gauge pressures\\?"):
        rep = diagnose(arm2, [recs[0]], [recs[1]])
    assert rep["findings"]
    for f in rep["findings"]:
        for name, p in f["parameters"].items():
            if isinstance(p, dict) and "stderr" in p and not name.startswith("offset_pa_if_") and name != "volume_m3":
                assert abs(p["value"]) >= MIN_T * p["stderr"] > 0, (f["effect"], name, p)
    assert all(w["final_parameters"] for w in rep["diagnostics"]["withdrawn_after_final_fit"])
