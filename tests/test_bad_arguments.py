"""The Python API refuses bad arguments with the library's ArgumentError, naming the argument
and the valid range, before any state changes (issue 18, input side, item 3)."""
import numpy as np
import pytest

from pneumatics.errors import ArgumentError, PneumasimError, UnknownNameError
from pneumatics.sim import Simulation


@pytest.fixture
def sim(arm2):
    s = Simulation(arm2)
    s.reset(pressure_pa=4e5)
    return s


@pytest.mark.parametrize("n, match", [(0, ">= 1 physics step, got 0"), (-5, ">= 1 physics step, got -5"),
                                      (2.5, "whole number .* got 2.5"), (True, "whole number"),
                                      ("3", "whole number")])
def test_step_needs_a_positive_whole_number(sim, n, match):
    p0, t0 = sim.pressure.copy(), sim.time
    sim.set_command([10, 0, 10, 0])
    with pytest.raises(ArgumentError, match=match):
        sim.step(n)
    # nothing happened: time and chambers stand where they were, the DAQ sums untouched
    assert sim.time == t0 and np.array_equal(sim.pressure, p0) and sim.steps_summed == 0


def test_step_accepts_numpy_integers_and_averages_positively(sim):
    sim.step(np.int64(5))
    assert sim.time == pytest.approx(5 * sim.dt)
    assert np.all(sim.take_mean().p > 0)


def test_argument_error_is_a_value_error_and_a_pneumasim_error():
    assert issubclass(ArgumentError, ValueError) and issubclass(ArgumentError, PneumasimError)


@pytest.mark.parametrize("p, match", [(-1, "-1 Pa for chamber shoulder.a is outside 1000..1.4e\\+06 Pa"),
                                      (0, "0 Pa for chamber shoulder.a is outside"),
                                      (np.nan, "NaN or inf at shoulder.a, shoulder.b, elbow.a, elbow.b"),
                                      (1e9, "1e\\+09 Pa .* 2 x the supply 700000 Pa"),
                                      ([4e5, 4e5, 4e5], "expected shape \\(4,\\), got \\(3,\\)"),
                                      ([4e5, 4e5, 4e5, np.inf], "NaN or inf at elbow.b"),
                                      ("four bar", "expected a number")])
def test_reset_pressure_must_be_absolute_finite_and_below_twice_the_supply(sim, p, match):
    with pytest.raises(ArgumentError, match=match):
        sim.reset(pressure_pa=p)
    assert np.allclose(sim.pressure, 4e5)  # refused before any change


def test_reset_unknown_keyframe_lists_the_valid_ones(sim):
    with pytest.raises(UnknownNameError, match="unknown keyframe 'hmoe'; did you mean 'home'\\? valid: home"):
        sim.reset(keyframe="hmoe")


def test_reset_joint_angles_outside_the_range_are_named(sim):
    with pytest.raises(ArgumentError, match=r"joint elbow = 2 is outside its range \[-1.22173, 1.22173\]"):
        sim.reset(qpos=[0.0, 2.0])
    with pytest.raises(ArgumentError, match=r"qpos\): NaN or inf at shoulder"):
        sim.reset(qpos=[np.nan, 0.0])
    with pytest.raises(ArgumentError, match=r"expected shape \(2,\)"):
        sim.reset(qpos=[0.0])
    sim.reset(qpos=[0.5, -0.5])  # inside: accepted
    assert np.allclose(sim.observe().q, [0.5, -0.5])


def test_set_command_unit_slip_raises_small_excess_clips(sim):
    with pytest.raises(ArgumentError, match="5000 V for chamber shoulder.a is far outside the valve's 0-10 V"):
        sim.set_command([5000, 5, 5, 5])
    with pytest.raises(ArgumentError, match="expected 4 numbers"):
        sim.set_command(["a", 5, 5, 5])


def test_humanoid_reset_checks_its_joint_ranges():
    from pneumatics.robot import load_robot
    humanoid = load_robot("humanoid38")
    sim = Simulation(humanoid)
    q = np.zeros(len(humanoid.joint_names))
    j = int(np.argmax(humanoid.joint_range()[:, 1] < 3.0))
    q[j] = 3.0
    with pytest.raises(ArgumentError, match=f"joint {humanoid.joint_names[j]} = 3 is outside its range"):
        sim.reset(qpos=q)
    with pytest.raises(ArgumentError, match="for chamber .* is outside 1000"):
        sim.reset(pressure_pa=500.0)


def test_jetpipe_step_and_reset_arguments():
    from pneumatics.jetpipe.sim import JetpipeSim
    sim = JetpipeSim()
    for n in (0, -1, 1.5):
        with pytest.raises(ArgumentError, match="JetpipeSim.step\\(n\\)"):
            sim.step(0.01, n)
    with pytest.raises(ArgumentError, match="command_a\\): nan is not a finite number"):
        sim.step(np.nan)
    with pytest.raises(ArgumentError, match="command_a\\): 80 A is outside -4..4 A"):
        sim.step(80.0)
    with pytest.raises(ArgumentError, match="reset\\(force_n\\): 1e\\+06 N is outside"):
        sim.reset(force_n=1e6)
    with pytest.raises(ArgumentError, match="reset\\(force_n\\): nan"):
        sim.reset(force_n=np.nan)


def test_hydraulic_step_current_and_keyframe_arguments():
    from pneumatics.hydraulics.sim import load_hydraulic
    sim = load_hydraulic("sarcos_elbow")
    with pytest.raises(ArgumentError, match="HydraulicJointSim.step\\(n\\): n must be >= 1"):
        sim.step(0)
    with pytest.raises(ArgumentError, match="set_current\\(current_a\\): nan is not a finite number"):
        sim.set_current(float("nan"))
    with pytest.raises(ArgumentError, match="set_current\\(current_a\\): 500 A is outside"):
        sim.set_current(500.0)
    with pytest.raises(UnknownNameError, match="unknown keyframe 'braced'; valid: home"):
        sim.reset(keyframe="braced")
