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
