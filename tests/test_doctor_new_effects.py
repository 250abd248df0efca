"""The doctor on pneumasim-made concealed cases of the effects added last: heat transfer in a
chamber, backlash at a joint, a tube (line dynamics) on a chamber, and end stops (unconcealed).  Each case is made, then
diagnosed from its CSV files alone; slow (1-4 min each), so outside the default run."""
import pytest

from identification.doctor import diagnose
from pneumatics.recording import read_csv
from pneumatics.robot import load_robot
from scenarios._cases import make_case


def _diagnose(tmp_path, seed, family, seconds=40.0):
    truth = make_case(tmp_path, seed, [family], seconds=seconds, heldout_seconds=seconds / 2)
    rep = diagnose(load_robot("arm2"), [read_csv(truth["recordings"]["main"])],
                   [read_csv(truth["recordings"]["heldout"])])
    return truth["effects"][0], rep


@pytest.mark.slow
@pytest.mark.parametrize("seed, family, key", [(601, "backlash", "gap_rad"), (501, "heat_transfer", "conductance_w_k"),
                                               (1034, "line_dynamics", "delay_s")])
def test_a_concealed_effect_is_named_placed_and_fitted(tmp_path, seed, family, key):
    hidden, rep = _diagnose(tmp_path, seed, family)
    assert [(f["effect"], f["where"]) for f in rep["findings"]] == [(family, hidden["where"])]
    f = rep["findings"][0]
    true = hidden["parameters"][family][key]
    assert abs(f["parameters"][key]["value"] / true - 1) < 0.3  # seen: 19 %, 5 %, 5 %
    assert f["heldout_nrmse"]["after"] < 0.6 * f["heldout_nrmse"]["before"]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [3001, 3003])
def test_an_end_stop_the_arm_touches_is_named_at_its_angle(tmp_path, seed):
    """A bumper 11 deg inside the joint limit, not concealed (no end stop can be: the model
    without it lets the joint run on, see scenarios/_cases.BENCHMARK_FAMILIES)."""
    truth = make_case(tmp_path, seed, ["end_stop"], conceal=False)
    hidden = truth["effects"][0]
    rep = diagnose(load_robot("arm2"), [read_csv(truth["recordings"]["main"])],
                   [read_csv(truth["recordings"]["heldout"])])
    assert [(f["effect"], f["where"]) for f in rep["findings"]] == [("end_stop", hidden["where"])]
    p = rep["findings"][0]["parameters"]
    robot = load_robot("arm2")
    lo, hi = robot.model.jnt_range[robot.model.joint(hidden["where"]["joint"]).id]
    (side, intrusion), = hidden["parameters"]["end_stop"].items()
    stop = lo + intrusion if side.startswith("lower") else hi - intrusion
    assert abs(p["stop_rad"]["value"] - stop) < 0.02  # seen: 0.005 and 0.003 rad
    assert p["stiffness_nm_per_rad"]["value"] > 50  # a stop, not a spring (seen: 168, 298)
