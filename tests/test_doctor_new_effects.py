"""The doctor on pneumasim-made concealed cases of the effects added last: heat transfer in a
chamber, backlash at a joint, a tube (line dynamics) on a chamber.  Each case is made, then
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
