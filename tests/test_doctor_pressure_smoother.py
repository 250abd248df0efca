"""The chambers' 1 ms pressures between the samples (identification/doctor/valve_arm/
pressure_smoother.py): the Kalman smoother against the exact least-squares answer of its own
model, against the simulator's own 1 ms pressures (closer than a cubic through the samples,
and its means what the DAQ read), a join of pooled recordings, and what its cache tells apart."""
import numpy as np
import pytest

from controllers.pid import ARM2_PIDF
from controllers.reference import hand_moved
from identification.doctor.valve_arm.data import fine_pressures, pool, prepare
from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
from identification.doctor.valve_arm.pressure_smoother import rts_smoother, smoothed_pressures
from pneumatics.robot import load_robot
from pneumatics.runner import run
from pneumatics.sim import Simulation


class RecordedSimulation(Simulation):
    """The simulator with its chambers' pressure kept after every 1 ms physics step (a
    subclass: the runner takes its Python loop, which steps it a control period at a time)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.fine = []

    def step(self, n: int = 1):
        for _ in range(int(n)):
            super().step(1)
            self.fine.append(self.pressure.copy())


@pytest.fixture(scope="module")
def arm2():
    return load_robot("arm2")


def _recorded(robot, seconds: float, seed: int):
    """(recording, the simulator's pressures at each 1 ms step of it (F, C)) of arm2 tracking a
    fast hand-moved reference under its PIDF, with its sensors' noise and DAQ means."""
    ref = hand_moved(robot.joint_names, robot.joint_range(), seconds, seed=seed, speed=3.0)
    sim = RecordedSimulation(robot)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=4.5e5)
    sim.fine.append(sim.pressure.copy())
    rec = run(sim, ARM2_PIDF.build(ref, robot.tables.valve[:, 0]), seconds, seed=seed)
    return rec, np.array(sim.fine)


@pytest.fixture(scope="module")
def recorded(arm2):
    return _recorded(arm2, 6.0, 5)


def test_the_smoother_is_the_least_squares_answer_of_its_linear_model():
    """The Kalman filter and Rauch-Tung-Striebel pass give exactly the minimiser of the model's
    quadratic objective (process, measurement and prior terms), solved here as one dense least
    squares problem; a cut restarts the chain from its prior."""
    rng = np.random.default_rng(0)
    N, C = 40, 3
    ref = rng.normal(3e5, 1e4, (N, C))
    phi, mu = rng.normal(3e5, 1e4, (N - 1, C)), rng.normal(3e5, 1e4, (N - 1, C))
    F, H = rng.uniform(0.5, 1.0, (N - 1, C)), rng.uniform(0.5, 1.0, (N - 1, C))
    z = rng.normal(3e5, 1e4, (N - 1, C))
    q, r, p0 = 1e6, 4e5, 1e8
    cut = np.zeros(N - 1, bool)
    cut[17] = True
    got = rts_smoother(phi, F, mu, H, z, ref, q, r, p0, cut)
    for c in range(C):
        rows, rhs = [], []

        def term(coef: dict, value: float, var: float):
            row = np.zeros(N)
            for i, a in coef.items():
                row[i] = a
            rows.append(row / np.sqrt(var))
            rhs.append(value / np.sqrt(var))

        term({0: 1.0}, ref[0, c], p0)
        for k in range(N - 1):
            if cut[k]:
                term({k + 1: 1.0}, ref[k + 1, c], p0)
            else:
                term({k: H[k, c]}, z[k, c] - mu[k, c] + H[k, c] * ref[k, c], r)
                term({k + 1: 1.0, k: -F[k, c]}, phi[k, c] - F[k, c] * ref[k, c], q)
        exact = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)[0]
        np.testing.assert_allclose(got[:, c], exact, rtol=0, atol=1e-6 * 3e5)


def test_the_smoothed_pressures_follow_the_simulators_own_between_the_samples(arm2, recorded):
    """On a recording of arm2 made by the simulator (noise, DAQ means, 100 Hz), the smoothed 1 ms
    pressures are closer to the simulator's than the cubic through the samples, and their
    means over each sample period are what the DAQ read, to within its noise."""
    rec, truth = recorded
    exp = prepare(arm2, rec)
    nominal = PneumaticMods.nominal(arm2.tables.n_chambers)
    smooth, cubic = smoothed_pressures(exp, nominal), fine_pressures(exp, nominal)
    assert smooth.shape == cubic.shape == truth.shape
    err_smooth, err_cubic = (np.sqrt(np.mean((x - truth) ** 2)) for x in (smooth, cubic))
    assert err_smooth < 0.7 * err_cubic, (err_smooth, err_cubic)
    S = exp.n_sub
    means = smooth[1:].reshape(-1, S, smooth.shape[1]).mean(axis=1)
    noise = arm2.fluid.sensors.pressure_noise_pa
    assert np.sqrt(np.mean((means - exp.p[1:]) ** 2)) < 2.0 * noise


def test_a_join_of_pooled_recordings_cuts_the_smoother(arm2, recorded):
    """Pooled with another recording, each keeps its own smoothed pressures: no state is carried
    across the join, and the DAQ mean read over the join's period is no one's."""
    rec, _ = recorded
    other, _ = _recorded(arm2, 3.0, 6)
    exps = [prepare(arm2, rec), prepare(arm2, other)]
    nominal = PneumaticMods.nominal(arm2.tables.n_chambers)
    pooled = smoothed_pressures(pool(exps), nominal)
    first = smoothed_pressures(exps[0], nominal)
    second = smoothed_pressures(exps[1], nominal)
    np.testing.assert_allclose(pooled[:first.shape[0]], first, atol=1.0)
    np.testing.assert_allclose(pooled[-second.shape[0]:], second, atol=1.0)


def test_the_cache_tells_chamber_models_apart_but_not_sensor_offsets(arm2, recorded):
    """The same recording and chamber model give the kept array back; another dead volume
    another answer; a sensor offset (taken off by the replays afterwards) the same one."""
    exp = prepare(arm2, recorded[0])
    C = arm2.tables.n_chambers
    nominal = PneumaticMods.nominal(C)
    first = smoothed_pressures(exp, nominal)
    assert smoothed_pressures(exp, PneumaticMods.nominal(C)) is first
    assert smoothed_pressures(exp, nominal.copy(sensor_offset_pa=np.full(C, 3e3))) is first
    bigger = smoothed_pressures(exp, nominal.copy(dead_volume_scale=np.full(C, 1.2)))
    assert bigger is not first and not np.allclose(bigger, first)
