"""The pneumatic screen on a robot of many chambers: the score-test gain worth a full fit is a
share of a few chambers' residual, not of every chamber's (rules.min_predicted)."""
import pytest

from identification.doctor.valve_arm.rules import MIN_PREDICTED, SCREEN_CHAMBERS, min_predicted
from pneumatics.robot import load_robot


def test_arm2s_screen_threshold_is_the_share_it_was_developed_with():
    assert load_robot("arm2").tables.n_chambers == SCREEN_CHAMBERS
    assert min_predicted(SCREEN_CHAMBERS) == MIN_PREDICTED
    assert min_predicted(2) == MIN_PREDICTED  # a single cylinder: never above the share


def test_the_threshold_falls_as_the_chambers_that_dilute_the_total_grow():
    # one chamber's effect touches one chamber's residual, whatever the robot's size: the share
    # of the total it can remove falls as 1 / n_chambers, and so does the threshold
    n = load_robot("humanoid38").tables.n_chambers
    assert n == 76
    assert min_predicted(n) == pytest.approx(MIN_PREDICTED * SCREEN_CHAMBERS / n)
    assert min_predicted(2 * n) == pytest.approx(min_predicted(n) / 2)


@pytest.mark.slow
def test_a_humanoid38_valve_leak_is_found_at_its_chamber():
    """Development seed 702 (20 s + 10 s, +-3 % link masses, a valve leaking 1.0e-8 m² near
    null at neck_pitch chamber b, concealed): the leak scores 0.013 of the 76 chambers' squared
    residual, eight times any other place, and was never fitted while the threshold was a share
    of all of them."""
    import scenarios._humanoid_cases as cases
    from identification.doctor.valve_arm.diagnose import diagnose

    main, held, truth = cases.make_case(702, ["valve_leak"], 20.0, 10.0)
    assert truth["effects"][0]["where"] == {"actuator": "neck_pitch", "chamber": "b"}
    report = diagnose(load_robot("humanoid38"), [main], [held])
    first = report["findings"][0]
    assert (first["effect"], first["where"]) == ("valve_leak", {"actuator": "neck_pitch", "chamber": "b"})
    assert report["unexplained"] == []
