"""What the valve-arm doctor's summary and report.md tell a user whose rigid body was held
nominal (identification/doctor/valve_arm/report.py)."""
from identification.doctor.valve_arm.report import kept_nominal_lines, summary

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
