"""The naming steps after the search (identification/doctor/valve_arm/naming.py): a delay
without a tube's volume is the valve's dead time, and that finding still replays."""
from types import SimpleNamespace

import numpy as np
import pytest

from identification.doctor.valve_arm.naming import LINE_MIN_VOLUME_FRACTION, line_named
from identification.doctor.valve_arm.rules import Finding
from pneumatics.effects.from_finding import form_of


def _line_finding(arm2, volume_m3: float) -> tuple:
    hyp = SimpleNamespace(chambers=[0], family="line_dynamics")
    params = {"delay_s": {"value": 0.012, "stderr": 1e-4}, "volume_m3": {"value": volume_m3, "stderr": 2e-8}}
    finding = Finding(SimpleNamespace(hyp=hyp), "line_dynamics", {"actuator": "shoulder", "chamber": "a"},
                      params, 0.5)
    return SimpleNamespace(robot=arm2), finding


def test_a_delay_without_a_tubes_volume_is_the_valves_dead_time(arm2):
    dead = float(arm2.tables.dead_volume[0])
    run, finding = _line_finding(arm2, 0.05 * dead)
    named = line_named(run, finding)
    assert named.family == "valve_lag" and named.alternatives[0] == "line_dynamics"
    assert named.params == {"dead_time_s": {"value": 0.012, "stderr": 1e-4}}
    assert form_of(named.family, named.params) == "dead_time"
    assert "dead time" in named.evidence


def test_a_delay_with_a_tubes_volume_stays_a_line(arm2):
    dead = float(arm2.tables.dead_volume[0])
    run, finding = _line_finding(arm2, 2 * LINE_MIN_VOLUME_FRACTION * dead)
    assert line_named(run, finding) is finding


def test_the_dead_time_form_delays_the_spool_as_a_line_without_volume(arm2):
    """The simulator's entry: a dead time adds to the delay of a line at the same chamber."""
    from pneumatics.effects.effect_set import EffectSet

    effects = EffectSet().add("valve_lag", "elbow.a", {"dead_time_s": 0.01}, "dead_time")
    delay, volume = effects.line_arrays(arm2)
    assert delay[2] == pytest.approx(0.01) and np.all(volume == 0)
    effects.add("line_dynamics", "elbow.a", {"delay_s": 0.005, "volume_m3": 1e-6})
    delay, volume = effects.line_arrays(arm2)
    assert delay[2] == pytest.approx(0.015) and volume[2] == pytest.approx(1e-6)
    other_order = EffectSet().add("line_dynamics", "elbow.a", {"delay_s": 0.005, "volume_m3": 1e-6})
    other_order.add("valve_lag", "elbow.a", {"dead_time_s": 0.01}, "dead_time")
    assert other_order.line_arrays(arm2)[0][2] == pytest.approx(0.015)


# a whole doctor's run (37 s on a slow 2-core machine), slow for CI's 15 minutes;
# the dead time's naming rule is tested above
@pytest.mark.slow
def test_the_doctor_names_a_valve_dead_time_and_hands_back_the_model_it_proved(tmp_path):
    """A 5-25 ms dead time of one valve in a recording of the random-form generator (no tube):
    the search's line hypothesis fits the delay with almost no volume, the finding is the
    valve's dead time, and the fitted model replays the held-out recording to the report."""
    from identification.doctor.valve_arm.diagnose import diagnose
    from identification.doctor.valve_arm.fitted_model import heldout_replay
    from identification.doctor.valve_arm.report import write
    from pneumatics.recording import read_csv
    from pneumatics.robot import load_robot
    from scenarios._variantsim.cases import make_case

    truth = make_case(tmp_path, 263004997, ["valve_lag"], forms=["dead_time"], seconds=30.0, heldout_seconds=15.0,
                      name="dead")
    where = truth["effects"][0]["where"]
    held = [read_csv(tmp_path / "dead_heldout.csv")]
    report = diagnose(load_robot("arm2"), [read_csv(tmp_path / "dead.csv")], held)
    f = report["findings"][0]
    assert (f["effect"], f["form"], f["where"]) == ("valve_lag", "dead_time", where)
    assert f["alternatives"][0] == "line_dynamics"
    assert 0.005 < f["parameters"]["dead_time_s"]["value"] < 0.025
    write(report, tmp_path / "out", load_robot("arm2"), rerun=False)
    fitted = load_robot("arm2", fitted=tmp_path / "out" / "model.toml")
    after = heldout_replay(fitted, held).nrmse()
    for ch, v in report["after"]["heldout_nrmse"].items():
        assert after[ch] == pytest.approx(v, rel=1e-9), ch
