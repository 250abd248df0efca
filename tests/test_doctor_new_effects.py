"""The doctor on pneumasim-made concealed cases of the effects added last: heat transfer in a
chamber, backlash at a joint, a tube (line dynamics) on a chamber, end stops (unconcealed) and a
piston leak the first calibration half-absorbed; and a joint spring, outside the library.  Each case is made, then
diagnosed from its CSV files alone; slow (1-4 min each), so outside the default run."""
import pytest

from identification.doctor.valve_arm.report import write
from pneumatics.robot import load_robot
from scenarios._cases import make_case, make_spring_case


def _diagnose(diagnose_case, tmp_path, seed, family, seconds=40.0):
    truth = make_case(tmp_path, seed, [family], seconds=seconds, heldout_seconds=seconds / 2)
    rep = diagnose_case(truth)
    return truth["effects"][0], rep


@pytest.mark.slow
@pytest.mark.parametrize("seed, family, key", [(601, "backlash", "gap_rad"), (501, "heat_transfer", "conductance_w_k"),
                                               (1034, "line_dynamics", "delay_s")])
def test_a_concealed_effect_is_named_placed_and_fitted(tmp_path, seed, family, key, diagnose_case):
    hidden, rep = _diagnose(diagnose_case, tmp_path, seed, family)
    assert [(f["effect"], f["where"]) for f in rep["findings"]] == [(family, hidden["where"])]
    f = rep["findings"][0]
    true = hidden["parameters"][family][key]
    assert abs(f["parameters"][key]["value"] / true - 1) < 0.3  # seen: 19 %, 5 %, 5 %
    assert f["heldout_nrmse"]["after"] < 0.6 * f["heldout_nrmse"]["before"]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [3001, 3003])
def test_an_end_stop_the_arm_touches_is_named_at_its_angle(tmp_path, seed, diagnose_case):
    """A bumper 11 deg inside the joint limit, not concealed (no end stop can be: the model
    without it lets the joint run on, see scenarios/_cases.BENCHMARK_FAMILIES)."""
    truth = make_case(tmp_path, seed, ["end_stop"], conceal=False)
    hidden = truth["effects"][0]
    rep = diagnose_case(truth)
    assert [(f["effect"], f["where"]) for f in rep["findings"]] == [("end_stop", hidden["where"])]
    p = rep["findings"][0]["parameters"]
    robot = load_robot("arm2")
    lo, hi = robot.model.jnt_range[robot.model.joint(hidden["where"]["joint"]).id]
    (side, intrusion), = hidden["parameters"]["end_stop"].items()
    stop = lo + intrusion if side.startswith("lower") else hi - intrusion
    assert abs(p["stop_rad"]["value"] - stop) < 0.02  # seen: 0.005 and 0.003 rad
    assert p["stiffness_nm_per_rad"]["value"] > 50  # a stop, not a spring (seen: 168, 298)


@pytest.mark.slow
def test_a_leak_the_calibration_half_absorbed_is_named_and_the_calibration_handed_back(tmp_path, diagnose_case):
    """Case 1019: a 9e-9 m^2 piston leak on the shoulder.  The first calibration takes part of
    it into the valve areas and dead volumes (up to 17 % off), which ranks the piston leak only
    4th by the score test; fitted, it wins, and the joint fit returns those scales to within
    the generator's 3 % errors."""
    truth = make_case(tmp_path, 1019, ["piston_leak"])
    hidden = truth["effects"][0]
    rep = diagnose_case(truth)
    assert [(f["effect"], f["where"]) for f in rep["findings"]] == [("piston_leak", hidden["where"])]
    fitted = rep["findings"][0]["parameters"]["leak_area_m2"]["value"]
    assert abs(fitted / hidden["parameters"]["piston_leak_m2"] - 1) < 0.1  # seen: 1 %
    before = [v for k, v in rep["calibrated"].items() if "shoulder" in k and "area" in k]
    after = [v for k, v in rep["calibrated_with_findings"].items() if "shoulder" in k and "area" in k]
    assert max(abs(v - 1) for v in before) > 0.1  # seen: 0.825 .. 1.148
    assert max(abs(v - 1) for v in after) < 0.05  # seen: 0.980 .. 1.018 (true factors within 3 %)


@pytest.mark.slow
def test_a_joint_spring_outside_the_library_is_unexplained_at_its_joint(tmp_path, diagnose_case):
    """A torsion spring on the shoulder (0.125 N m/rad after concealment, rest at 0.3 rad): an
    angle offset takes up its preload (28 % of the held-out torque residual) but a smooth
    torque of the joint's state takes up 96 %, so the doctor names nothing there and reports
    the residual as unexplained at the shoulder, where the spring pulls hardest."""
    truth = make_spring_case(tmp_path, 7, "shoulder", 1.0)
    rep = diagnose_case(truth)
    assert not [f for f in rep["findings"] if f["where"].get("joint") == "shoulder"]
    (u,) = [u for u in rep["unexplained"] if u["where"] == {"joint": "shoulder"}]
    assert u["share_of_residual"] > 0.5  # seen: 0.96
    assert u["regime"] == "lower third of the angles visited"  # furthest from the rest angle
    assert u["depends_on"] == ["joint angle and velocity"] and u["suggests"] == []
    write(rep, tmp_path / "out", load_robot("arm2"), rerun=False)  # the entry reads in report.md
    assert '{"joint": "shoulder"}' in (tmp_path / "out" / "report.md").read_text()


@pytest.mark.slow
def test_a_joint_spring_no_library_effect_mimics_is_unexplained_at_its_joint(tmp_path, diagnose_case):
    """A torsion spring on the elbow (0.0625 N m/rad after concealment, rest at 0.3 rad), where
    gravity is weak: no finding is made at the elbow; a smooth torque of the joint's state takes
    up 93-94 % of the held-out torque residual, and the doctor reports it as unexplained at the
    elbow.  When this test was written no library effect took up any of it (best held-out gain
    0.000); the doctor of 2026-11-28 finds an angle offset taking up 32 %, a partial projection
    the yardstick beats (search._keep_mechanical), and the evidence names it."""
    truth = make_spring_case(tmp_path, 11, "elbow", 0.25)
    rep = diagnose_case(truth)
    assert not [f for f in rep["findings"] if f["where"].get("joint") == "elbow"]
    (u,) = [u for u in rep["unexplained"] if u["where"] == {"joint": "elbow"}]
    assert u["share_of_residual"] > 0.5  # seen: 0.93
    assert "no library effect pays" in u["evidence"] or "the library's best (angle_sensor_offset)" in u["evidence"]


@pytest.mark.slow
def test_a_pressure_sensor_warming_up_is_named_with_its_drift_at_its_chamber(tmp_path, diagnose_case):
    """A transducer whose zero settles while it warms up (random-form generator: offset +
    drift (1 - exp(-t / tau)), seed 367338335 of a development run): without a form that drifts
    in time the doctor named an angle offset at the elbow; the warm-up form, in the replays and
    the torque balance, names the sensor at its chamber, with a drift of the true sign."""
    from scenarios._variantsim.cases import make_case as make_variant_case

    truth = make_variant_case(tmp_path / "c", 367338335, ["pressure_sensor_offset"], forms=["drifting_offset"],
                              seconds=60.0, heldout_seconds=30.0, name="drift")
    hidden = truth["effects"][0]
    report = diagnose_case(truth)
    first = report["findings"][0]
    assert (first["effect"], first["where"]) == ("pressure_sensor_offset", hidden["where"])
    assert first["form"] == "warm_up_drift"
    assert first["parameters"]["drift_pa"]["value"] * hidden["effective"]["drift_pa"] > 0
    assert first["heldout_nrmse"]["after"] < first["heldout_nrmse"]["before"]


@pytest.mark.slow
def test_a_supply_that_steps_down_is_not_taken_for_a_drifting_sensor(tmp_path, diagnose_case):
    """A supply pressure step mid-recording (outside the vocabulary; seed 800900006 of a
    development run) changes the true pressures: a drifting offset in one chamber's replays
    mimicked it, but the torque balance, which saw the true pressures, contradicts that
    offset, so nothing is named and the supply is reported unexplained."""
    from scenarios._variantsim.cases import make_case as make_variant_case

    truth = make_variant_case(tmp_path / "c", 800900006, ["outside_vocabulary"], forms=["supply_step"],
                              seconds=60.0, heldout_seconds=30.0, name="step")
    report = diagnose_case(truth)
    assert report["findings"] == []
    assert [u["where"] for u in report["unexplained"]] == [{"supply": "all"}]
