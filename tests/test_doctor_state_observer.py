"""The chambers' pressures and the joints' velocities between the samples
(identification/doctor/valve_arm/state_observer.py): against the simulator's own 1 ms states
(closer than a cubic through the pressure samples and the angles' spline's velocities, and the
pressures' means what the DAQ read), a join of pooled recordings, and what its cache tells
apart."""
import numpy as np
import pytest

from controllers.pid import ARM2_PIDF
from controllers.reference import hand_moved
from identification.doctor.valve_arm.data import FINE_DT, fine_pressures, pool, prepare
from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
from identification.doctor.valve_arm.state_observer import observed_states
from pneumatics.effects.backlash import addresses
from pneumatics.runner import run
from pneumatics.sim import Simulation


class RecordedSimulation(Simulation):
    """The simulator with its chambers' pressures and joints' velocities kept after every 1 ms
    physics step (a subclass: the runner takes its Python loop, which steps it a control period
    at a time)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.fine, self.fine_v = [], []

    def keep(self):
        self.fine.append(self.pressure.copy())
        self.fine_v.append(self.data.qvel.copy())

    def step(self, n: int = 1):
        for _ in range(int(n)):
            super().step(1)
            self.keep()


def _recorded(robot, seconds: float, seed: int):
    """(recording, the simulator's pressures (F, C) and joint velocities (F, J) at each 1 ms step
    of it) of arm2 tracking a fast hand-moved reference under its PIDF, with its sensors' noise
    and DAQ means."""
    ref = hand_moved(robot.joint_names, robot.joint_range(), seconds, seed=seed, speed=3.0)
    sim = RecordedSimulation(robot)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=4.5e5)
    sim.keep()
    rec = run(sim, ARM2_PIDF.build(ref, robot.tables.valve[:, 0]), seconds, seed=seed)
    _, dadr = addresses(robot.model, robot.joint_names)
    return rec, np.array(sim.fine), np.array(sim.fine_v)[:, dadr]


@pytest.fixture(scope="module")
def recorded(arm2):
    return _recorded(arm2, 6.0, 5)


def test_the_observed_states_follow_the_simulators_own_between_the_samples(arm2, recorded):
    """On a recording of arm2 made by the simulator (noise, DAQ means, 100 Hz), the observer's
    1 ms pressures are closer to the simulator's than a cubic through the samples (seeds 5-7:
    225-385 Pa against 2.4-3.3 kPa), their means over each sample period are what the DAQ read
    to within its noise, and its velocities are closer to the simulator's than the angles'
    spline's."""
    rec, truth_p, truth_v = recorded
    exp = prepare(arm2, rec)
    nominal = PneumaticMods.nominal(arm2.tables.n_chambers)
    observed, cubic = observed_states(exp, nominal), fine_pressures(exp, nominal)
    p = observed.pressure_pa
    assert p.shape == cubic.shape == truth_p.shape
    err_observed, err_cubic = (np.sqrt(np.mean((x - truth_p) ** 2)) for x in (p, cubic))
    assert err_observed < 0.3 * err_cubic, (err_observed, err_cubic)
    S = exp.n_sub
    means = p[1:].reshape(-1, S, p.shape[1]).mean(axis=1)
    noise = arm2.fluid.sensors.pressure_noise_pa
    assert np.sqrt(np.mean((means - exp.p[1:]) ** 2)) < 2.0 * noise
    spline_v = (exp.fine_q[2:] - exp.fine_q[:-2]) / (2 * FINE_DT)
    err_v = np.sqrt(np.mean((observed.velocity_rad_s[1:-1] - truth_v[1:-1]) ** 2))
    err_spline_v = np.sqrt(np.mean((spline_v - truth_v[1:-1]) ** 2))
    assert err_v < err_spline_v, (err_v, err_spline_v)


def test_a_join_of_pooled_recordings_restarts_the_observer(arm2, recorded):
    """Pooled with another recording, each keeps its own observed states: no state is carried
    across the join."""
    rec = recorded[0]
    other = _recorded(arm2, 3.0, 6)[0]
    exps = [prepare(arm2, rec), prepare(arm2, other)]
    nominal = PneumaticMods.nominal(arm2.tables.n_chambers)
    pooled = observed_states(pool(exps), nominal)
    first, second = (observed_states(e, nominal) for e in exps)
    n1, n2 = first.pressure_pa.shape[0], second.pressure_pa.shape[0]
    np.testing.assert_allclose(pooled.pressure_pa[:n1], first.pressure_pa, atol=1.0)
    np.testing.assert_allclose(pooled.pressure_pa[-n2:], second.pressure_pa, atol=1.0)
    np.testing.assert_allclose(pooled.velocity_rad_s[-n2:], second.velocity_rad_s, atol=1e-6)


def test_the_cache_tells_chamber_models_apart_but_not_sensor_offsets(arm2, recorded):
    """The same recording and chamber model give the kept states back; another dead volume
    another answer; a sensor offset (taken off by the replays afterwards) the same one."""
    exp = prepare(arm2, recorded[0])
    C = arm2.tables.n_chambers
    nominal = PneumaticMods.nominal(C)
    first = observed_states(exp, nominal)
    assert observed_states(exp, PneumaticMods.nominal(C)) is first
    assert observed_states(exp, nominal.copy(sensor_offset_pa=np.full(C, 3e3))) is first
    bigger = observed_states(exp, nominal.copy(dead_volume_scale=np.full(C, 1.2)))
    assert bigger is not first and not np.allclose(bigger.pressure_pa, first.pressure_pa)
