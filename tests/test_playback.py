"""Simulation.play against set_command + step: the same states bit for bit, on the compiled
path and on the Python loop that valve dynamics keep; bad rows named."""
import warnings

import numpy as np
import pytest

from pneumatics.effects.effect_set import EffectSet
from pneumatics.errors import ArgumentError
from pneumatics.robot import load_robot
from pneumatics.sim import CommandClippedWarning, Simulation


def _commands(sim, rows, seed=3):
    rng = np.random.default_rng(seed)
    return sim.tables.valve[:, 0] + rng.normal(0, 0.8, (rows, sim.command.size))


def _stepped(sim, commands, steps):
    out = []
    for u in commands:
        sim.set_command(u)
        sim.step(steps)
        out.append(np.concatenate([sim.pressure, sim.data.qpos, sim.data.qvel, [sim.time]]))
    return np.array(out)


@pytest.mark.parametrize("name, effects", [
    ("arm2", EffectSet().add("valve_hysteresis", "shoulder.a", {"half_width_v": 0.1})),
    ("arm2", EffectSet().add("valve_lag", "elbow.b", {"time_constant_s": 0.004})),  # the Python loop
    ("humanoid38", EffectSet()),
])
def test_play_gives_the_states_of_set_command_and_step(name, effects):
    robot = load_robot(name)
    a, b = Simulation(robot, effects=effects), Simulation(robot, effects=effects)
    commands = _commands(a, 30)
    for sim in (a, b):
        sim.reset(pressure_pa=4e5)
    played = a.play(commands, 10)
    stepped = _stepped(b, commands, 10)
    np.testing.assert_array_equal(np.column_stack([played.pressure_pa, played.qpos, played.qvel]), stepped[:, :-1])
    np.testing.assert_allclose(played.time_s, stepped[:, -1], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(a.sums, b.sums)
    assert a.steps_summed == b.steps_summed == 300
    np.testing.assert_array_equal(a.areas, b.areas)


def test_a_bad_row_is_named_and_the_rows_before_it_are_played():
    sim, ref = Simulation(load_robot("arm2")), Simulation(load_robot("arm2"))
    commands = _commands(sim, 5)
    commands[3, 2] = np.nan
    for s in (sim, ref):
        s.reset(pressure_pa=4e5)
    with pytest.raises(ArgumentError, match=r"row 3: .*NaN or inf for chamber\(s\) elbow.a"):
        sim.play(commands, 10)
    np.testing.assert_array_equal(sim.pressure, _stepped(ref, commands[:3], 10)[-1, :4])
    assert sim.time == ref.time


@pytest.mark.parametrize("bad", [np.zeros(4), np.zeros((3, 5)), [["a"] * 4]])
def test_commands_of_the_wrong_shape_are_refused(bad):
    with pytest.raises(ArgumentError, match=r"play\(commands\): expected"):
        Simulation(load_robot("arm2")).play(bad, 10)


def test_clipped_rows_warn_once():
    sim = Simulation(load_robot("arm2"))
    commands = _commands(sim, 4)
    commands[1, 0] = 10.5
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sim.play(commands, 5)
    assert [w.category for w in caught] == [CommandClippedWarning]
