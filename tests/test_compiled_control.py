"""The compiled closed loop (controllers.compiled_loop) against the Python loop of
pneumatics.runner.run it replaces: the same recording bit for bit, on arm2 and humanoid38,
with PID, PIDF and the model-based PIDF, with and without sensor noise and DAQ averaging,
with sensor offsets and valve hysteresis; the same states left behind; the same error for
commands the valves refuse; user controllers and subclasses keep the Python path."""
import numpy as np
import pytest

from controllers.compiled_loop import CompiledPIDF
from controllers.model_based import ModelBasedCfg
from controllers.pid import ARM2_PID, ARM2_PIDF, PIDF
from controllers.reference import JointReference, hand_moved
from identification.inverse_dynamics import InverseDynamics, torque_gain
from pneumatics.effects.effect_set import EffectSet
from pneumatics.errors import ArgumentError
from pneumatics.robot import load_robot
from pneumatics.runner import compiled_law, run
from pneumatics.sim import Simulation

SECONDS = 3.0


@pytest.fixture(scope="module")
def robots():
    return {name: load_robot(name) for name in ("arm2", "humanoid38")}


def _controller(robot, law: str, seconds: float = SECONDS, reference=None):
    ref = reference or hand_moved(robot.joint_names, robot.joint_range(), seconds, seed=2)
    null = robot.tables.valve[:, 0]
    if robot.name == "arm2":
        cfg = ARM2_PID if law == "pid" else ARM2_PIDF
    else:
        from scenarios._humanoid import pidf_gains

        cfg = pidf_gains(np.full(len(robot.joint_names), 0.5))
        if law == "pid":
            from dataclasses import replace

            cfg = replace(cfg, kf_v_per_bar=(0.0,))
    if law == "model_based":
        model = InverseDynamics(np.array([0.012, 0.007, 0.015, -0.7, 0.03, 0.02, 0.1, -0.05]), torque_gain(robot))
        return ModelBasedCfg(pidf=cfg, lead_s=0.03).build(ref, null, model)
    return cfg.build(ref, null)


def _both(sim, make, seconds=SECONDS, **kw):
    """(Python recording, compiled recording, states after each) of the same run from the same start."""
    out = []
    for compiled in (False, True):
        sim.reset(pressure_pa=4.0e5)
        ctrl = make()
        rec = run(sim, ctrl, seconds, compiled=compiled, record_velocity=True, record_force=True, **kw)
        state = {"pressure": sim.pressure.copy(), "qpos": sim.data.qpos.copy(), "qvel": sim.data.qvel.copy(),
                 "command": sim.command.copy(), "areas": sim.areas.copy(), "sums": sim.sums.copy(),
                 "n_summed": sim.steps_summed, "integral": ctrl._integral.copy(), "deriv": ctrl._deriv.copy(),
                 "time": sim.time}
        out.append((rec, state))
    return out


def _assert_same(pair):
    (a, sa), (b, sb) = pair
    assert list(a.columns) == list(b.columns)
    np.testing.assert_array_equal(a.time, b.time)
    for col in a.columns:
        np.testing.assert_array_equal(a[col], b[col], err_msg=col)
    for key in sa:
        np.testing.assert_array_equal(sa[key], sb[key], err_msg=key)


@pytest.mark.parametrize("name", ["arm2", "humanoid38"])
@pytest.mark.parametrize("law", ["pid", "pidf"])
@pytest.mark.parametrize("noise", [True, False])
def test_compiled_run_records_what_the_python_loop_records(robots, name, law, noise):
    robot = robots[name]
    sim = Simulation(robot)
    pair = _both(sim, lambda: _controller(robot, law), noise=noise, seed=5)
    _assert_same(pair)
    rec = pair[1][0]
    # a real closed loop: the valves moved; under the PIDF the joints follow the reference
    # (arm2's shipped plain PID limit-cycles, controllers.pid.ARM2_PID)
    assert np.ptp(rec.matrix("u_a", robot.actuator_names)) > 0.5
    err = rec.matrix("ref", robot.joint_names) - rec.matrix("q", robot.joint_names)
    assert np.all(np.isfinite(err))
    if law == "pidf":  # better than standing still, by far
        standing = rec.matrix("ref", robot.joint_names) - rec.matrix("q", robot.joint_names)[0]
        assert np.sqrt(np.mean(err ** 2)) < 0.5 * np.sqrt(np.mean(standing ** 2))


def test_model_based_pidf_without_averaging_with_sensor_offsets_and_hysteresis(robots):
    robot = robots["arm2"]
    effects = EffectSet(valve_hysteresis_v={"shoulder.a": 0.15}, pressure_offset_pa={"elbow.b": 3000.0},
                        angle_offset_rad={"elbow": 0.01}, friction={"elbow": {"coulomb_nm": 0.2}})
    sim = Simulation(robot, effects=effects)
    pair = _both(sim, lambda: _controller(robot, "model_based"), noise=True, average=False, seed=9)
    _assert_same(pair)
    assert pair[0][1]["n_summed"] == round(SECONDS * 100) * 10  # the sums ran on, as the Python loop's do


def test_an_angle_sensor_with_a_gain_error_reads_alike_on_both_paths(robots):
    """angle_sensor_offset, offset_and_scale form: both paths read (1 + g) q + offset and
    (1 + g) qd, averaged over the period or not."""
    robot = robots["arm2"]
    effects = EffectSet().add("angle_sensor_offset", "elbow", {"offset_rad": 0.01, "scale_error": 0.03},
                              form="offset_and_scale")
    for average in (True, False):
        pair = _both(Simulation(robot, effects=effects), lambda: _controller(robot, "pidf"), average=average, seed=4)
        _assert_same(pair)


def test_a_warming_up_pressure_sensor_reads_alike_on_both_paths(robots):
    """The drift is evaluated at the simulation's time on the Python path and at the row's time
    t0 + k / rate in the compiled loop: equal up to the clock's rounding, so the recordings
    agree to round-off (not bit for bit)."""
    robot = robots["arm2"]
    effects = EffectSet(pressure_offset_pa={"elbow.b": 2000.0},
                        pressure_drift={"elbow.b": {"drift_pa": 1.2e4, "time_constant_s": 1.0}})
    (a, _), (b, _) = _both(Simulation(robot, effects=effects), lambda: _controller(robot, "pidf"), average=True)
    for col in a.columns:
        np.testing.assert_allclose(a[col], b[col], rtol=1e-9, atol=1e-6, err_msg=col)


def test_a_run_continues_where_the_last_left_off(robots):
    """Two runs back to back (state carried in the simulation) and a run at another rate."""
    robot = robots["arm2"]
    sim = Simulation(robot)
    recs = {}
    for compiled in (False, True):
        sim.reset(pressure_pa=4.0e5)
        first = run(sim, _controller(robot, "pidf"), 1.0, compiled=compiled, seed=1)
        second = run(sim, _controller(robot, "pidf"), 1.5, rate_hz=50.0, compiled=compiled, seed=2)
        recs[compiled] = (first, second)
    for a, b in zip(recs[False], recs[True]):
        for col in a.columns:
            np.testing.assert_array_equal(a[col], b[col], err_msg=col)
    assert recs[True][1].time[0] == pytest.approx(1.0)


def test_commands_the_valves_refuse_raise_the_same_error(robots):
    robot = robots["arm2"]
    base = hand_moved(robot.joint_names, robot.joint_range(), SECONDS, seed=2)
    q = base.q.copy()
    q[len(q) // 2:, 1] = np.nan  # a broken reference half-way: NaN commands
    sim = Simulation(robot)
    messages = []
    for compiled in (False, True):
        sim.reset(pressure_pa=4.0e5)
        with pytest.raises(ArgumentError, match="NaN or inf") as info:
            run(sim, _controller(robot, "pidf", reference=JointReference(base.time, q, base.joint_names)),
                SECONDS, compiled=compiled)
        messages.append((str(info.value), sim.time))
    assert messages[0] == messages[1]


def test_only_the_built_in_laws_on_a_joint_reference_are_compiled(robots):
    robot = robots["arm2"]
    sim = Simulation(robot)
    pidf = _controller(robot, "pidf")
    assert isinstance(compiled_law(sim, pidf, 2), CompiledPIDF)

    class Tweaked(PIDF):  # a user's subclass may change the law: the Python path runs it
        pass

    assert compiled_law(sim, Tweaked(pidf.cfg, pidf.ref, pidf.null_v), 2) is None

    class Held:  # a reference object of the user's own
        def reference(self, t):
            return np.zeros(2)

    assert compiled_law(sim, ARM2_PIDF.build(Held(), pidf.null_v), 2) is None
    assert compiled_law(sim, pidf, 2, logger=object()) is None  # a logger looks at every period
    assert compiled_law(Simulation(robot, kernel="reference"), pidf, 2) is None
    lagging = Simulation(robot, effects=EffectSet(valve_lag_s={"shoulder.a": 0.005}))
    assert compiled_law(lagging, pidf, 2) is None

    class Braked(Simulation):  # a simulation of the user's own: its methods must run
        def forces(self):
            return super().forces() - 100.0 * self.data.qvel

    assert compiled_law(Braked(robot), pidf, 2) is None
