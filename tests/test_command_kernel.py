"""The compiled command path (pneumatics.command_kernel) against the numpy path it replaces:
same commands, spool and valve areas on random commands, with hysteresis and both valve-leak
forms; bad commands change nothing and get the numpy path's errors; clipping warns once."""
import warnings

import numpy as np
import pytest

from pneumatics.effects.effect_set import EffectSet
from pneumatics.errors import ArgumentError
from pneumatics.robot import load_robot
from pneumatics.sim import CommandClippedWarning, Simulation


def _effects():
    return (EffectSet().add("valve_hysteresis", "shoulder.a", {"half_width_v": 0.15})
            .add("valve_leak", "elbow.b", {"leak_area_m2": 3e-8})
            .add("valve_leak", "shoulder.b", {"supply_leak_area_m2": 2e-8, "exhaust_leak_area_m2": 5e-8},
                 form="asymmetric"))


@pytest.fixture(scope="module")
def pair():
    robot = load_robot("arm2")
    return Simulation(robot, effects=_effects()), Simulation(robot, effects=_effects(), kernel="reference")


def test_random_commands_give_the_numpy_paths_areas_and_spool(pair):
    fast, ref = pair
    rng = np.random.default_rng(4)
    for sim in pair:
        sim.reset(pressure_pa=4e5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CommandClippedWarning)
        lagging = 0
        for _ in range(500):
            u = rng.uniform(-1.0, 11.0, 4) if rng.random() < 0.2 else 5.0 + rng.normal(0, 0.5, 4)
            fast.set_command(u)
            ref.set_command(u)
            np.testing.assert_array_equal(fast.command, ref.command)
            np.testing.assert_allclose(fast.spool, ref.spool, rtol=0, atol=1e-15)
            np.testing.assert_allclose(fast.areas, ref.areas, rtol=1e-13, atol=1e-22)
            lagging += fast.spool[0] != fast.command[0]
    assert lagging > 50  # the play held shoulder a's spool behind its command often
    assert fast.areas[[1, 3]].min() > 0.0  # the leaking valves are never shut


def test_bad_commands_change_nothing_and_are_named(pair):
    fast, _ = pair
    fast.reset(pressure_pa=4e5)
    fast.set_command([5.0, 5.0, 6.0, 4.0])
    before = fast.command.copy(), fast.spool.copy(), fast.areas.copy()
    with pytest.raises(ArgumentError, match="NaN or inf for chamber"):
        fast.set_command([5.0, np.nan, 5.0, 5.0])
    with pytest.raises(ArgumentError, match="far outside the valve's 0-10 V"):
        fast.set_command([5.0, 5.0, 500.0, 5.0])
    for a, b in zip(before, (fast.command, fast.spool, fast.areas)):
        np.testing.assert_array_equal(a, b)


def test_clipping_warns_once_per_run(pair):
    fast, _ = pair
    fast.reset(pressure_pa=4e5)
    with pytest.warns(CommandClippedWarning):
        fast.set_command([11.0, 5.0, 5.0, -1.0])
    assert list(fast.command) == [10.0, 5.0, 5.0, 0.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", CommandClippedWarning)
        fast.set_command([12.0, 5.0, 5.0, 5.0])  # no second warning in the same run


def test_the_c_entry_point_and_numbas_dispatcher_agree(pair):
    """step_call.CommandCall: the C entry point where every array is C-contiguous float64, the
    dispatcher otherwise (here a Fortran-ordered area table), same statuses and arrays."""
    from pneumatics.command_kernel import command_step
    from pneumatics.step_call import CommandCall

    fast, _ = pair
    args = fast.command_step_args()

    def fresh(order):
        out = [np.array(a, order=order) if isinstance(a, np.ndarray) else a for a in args]
        return tuple(out)

    c_args, f_args, expected_args = fresh("C"), fresh("F"), fresh("C")
    c_call, f_call = CommandCall(c_args), CommandCall(f_args)
    assert c_call.address is not None and f_call.address is None
    rng = np.random.default_rng(7)
    for u in [rng.uniform(-1.0, 11.0, 4) for _ in range(50)] + [np.array([5.0, np.nan, 5.0, 5.0])]:
        assert c_call(u) == f_call(u) == command_step(u, *expected_args)
        for a, b, c in zip(c_args, f_args, expected_args):
            np.testing.assert_array_equal(a, b)
            np.testing.assert_array_equal(a, c)
