"""What the valve-arm doctor's summary and report.md tell a user whose rigid body was held
nominal, and what they say of a finding whose coupled held-out replay got worse
(identification/doctor/valve_arm/report.py)."""
import numpy as np

from identification.doctor.valve_arm.report import change, kept_nominal_lines, summary

WHY = "the calibrated rigid body replayed the held-out angles worse than the nominal one"


def _report(body_kept: bool) -> dict:
    return {"model": "humanoid38", "verdict": "no_significant_mismatch", "findings": [], "unexplained": [],
            "diagnostics": {"train_seconds": 20.0, "heldout_seconds": 10.0, "seconds": 120.0,
                            "calibration_flags": [], "rigid_body_calibration_replay": {"kept": body_kept}}}


def test_the_summary_says_when_the_rigid_body_was_held_nominal_and_what_that_means():
    held = summary(_report(body_kept=False))
    assert "rigid body held nominal" in held and "replayed angle" in held
    assert "rigid body held nominal" not in summary(_report(body_kept=True))
    assert len(held.splitlines()) <= 6                     # fits a screen with nothing found


def test_a_body_held_nominal_as_a_whole_is_one_line_of_report_md():
    names = [f"mass_scale.link{i}" for i in range(38)] + [f"damping_scale.j{i}" for i in range(38)]
    kept = {n: WHY for n in names} | {"armature_scale.shoulder": "lumped with the upper link"}
    lines = kept_nominal_lines(kept)
    assert len(lines) == 2
    assert "and 70 more" in lines[0] and WHY in lines[0]
    assert lines[1] == "- kept nominal, armature_scale.shoulder: lumped with the upper link"


def _angle_offset_finding(before: float, after: float) -> dict:
    return {"effect": "angle_sensor_offset", "where": {"joint": "left_knee"}, "regime": "throughout",
            "windows": [], "parameters": {"offset_rad": {"value": 0.004, "stderr": 1e-4}}, "alternatives": [],
            "heldout_nrmse": {"before": before, "after": after}, "heldout_channel": "q.left_knee",
            "heldout_nrmse_in_regime": None,
            "heldout_nrmse_angle_replay": {"channel": "q.left_knee", "before": 0.0400, "after": 0.0350,
                                           "replay_horizon_s": 0.2}}


def test_a_finding_whose_coupled_replay_got_worse_says_worse_and_shows_the_numbers_that_kept_it():
    rep = _report(body_kept=True) | {"verdict": "missing_physics", "findings": [_angle_offset_finding(0.050, 0.052)]}
    text = summary(rep)
    assert "4 % worse" in text and "-4 % better" not in text
    assert "kept by its joint's angle, replayed 0.2 s at a time" in text and "0.0400 → 0.0350 (12 % better)" in text
    assert change(0.05, 0.04) == "20 % better" and change(0.05, 0.05) == "0 % better"


def test_report_md_says_why_each_joint_effect_fitted_by_output_error_was_named_or_not():
    from identification.doctor.valve_arm.report import candidate_lines

    records = [{"hypothesis": "coulomb_friction@left_hip_yaw", "round": 1, "joint": "left_hip_yaw",
                "values": [0.026], "stderr": [0.005], "t": [5.2], "train_gain": 0.31,
                "heldout_nrmse": {"before": None, "after": None},
                "verdict": "refused: a value under 8 cluster-robust standard errors from zero"},
               {"hypothesis": "viscous_friction@jaw", "round": 1, "joint": "jaw", "values": [0.02], "stderr": [0.001],
                "t": [20.0], "train_gain": 0.5, "heldout_nrmse": {"before": 0.204, "after": 0.097}, "verdict": "named"}]
    lines = candidate_lines(records)
    table = [line for line in lines if line.startswith("| 1 ")]
    assert len(table) == 2
    assert "0.026 (5.2)" in table[0] and "—" in table[0] and "8 cluster-robust" in table[0]
    assert "0.2040 → 0.0970" in table[1] and table[1].endswith("| named |")
    assert candidate_lines([]) == []   # no section where the search did not run


def test_report_md_and_the_summary_say_how_small_a_joint_effect_the_recordings_could_show():
    from identification.doctor.valve_arm.report import detection_lines

    screen = {"coulomb_friction": {"floor": 0.1, "gains": {}, "parameter": "coulomb_nm",
                                   "detection_limit": {"jaw": 0.02, "left_knee": 0.3, "right_elbow": 0.1}},
              "angle_sensor_offset": {"floor": 0.1, "gains": {}, "parameter": "offset_rad", "detection_limit": {}}}
    lines = detection_lines(screen)
    (row,) = [line for line in lines if line.startswith("| coulomb_friction")]
    assert row == "| coulomb_friction | coulomb_nm | 0.1 | 0.02 (jaw) | 0.3 (left_knee) |"
    assert not [line for line in lines if line.startswith("| angle_sensor_offset")]   # no limit there: no row
    assert detection_lines({}) == []                                                  # the screen did not run
    report = _report(body_kept=False)
    report["diagnostics"]["output_error_screen"] = screen
    text = summary(report)
    assert "smallest joint effects these recordings show" in text and "coulomb_friction coulomb_nm 0.1" in text
    assert len(text.splitlines()) <= 7


def test_report_md_says_how_small_a_chamber_effect_the_held_out_recording_could_show():
    """One row per family: median, smallest and largest place; a place whose probe changed
    nothing (inf in memory, None once written as JSON) is left out of the row."""
    from identification.doctor.valve_arm.report import chamber_detection_lines

    limits = {"valve_leak": {"parameter": "leak_area_m2",
                             "detection_limit": {"jaw.a": 2e-9, "jaw.b": 8e-9, "left_knee.a": 4e-9, "neck_pitch.b": np.inf}},
              "piston_leak": {"parameter": "leak_area_m2", "detection_limit": {"jaw": None}}}
    lines = chamber_detection_lines(limits)
    (row,) = [line for line in lines if line.startswith("| valve_leak")]
    assert row == "| valve_leak | leak_area_m2 | 4e-09 | 2e-09 (jaw.a) | 8e-09 (jaw.b) |"
    assert not [line for line in lines if line.startswith("| piston_leak")]
    assert chamber_detection_lines({}) == []


def test_report_md_says_why_each_chamber_effect_fitted_was_named_or_not():
    """One row per fitted pneumatic candidate, round by round, with its held-out gain and verdict."""
    from identification.doctor.valve_arm.report import pneumatic_candidate_lines

    records = [{"hypothesis": "external_leak@elbow.a", "form": "orifice", "round": 1, "predicted_gain": 0.31,
                "heldout_gain": 0.168, "verdict": "refused: held-out gain 0.168 under 0.2"},
               {"hypothesis": "valve_leak@elbow.a", "form": "underlap", "round": 1, "predicted_gain": 0.12,
                "heldout_gain": 0.41, "verdict": "named"}]
    lines = pneumatic_candidate_lines(records)
    assert "| 1 | external_leak@elbow.a | orifice | 0.310 | 0.168 | refused: held-out gain 0.168 under 0.2 |" in lines
    assert lines[-1] == "| 1 | valve_leak@elbow.a | underlap | 0.120 | 0.410 | named |"
    assert pneumatic_candidate_lines([]) == []
