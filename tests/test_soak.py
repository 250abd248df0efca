"""Soak: a million physics steps of random valve commands per model, and never a NaN, never
a pressure that is not finite and positive; and closed valves conserve the chambers' gas
(issue 18, input side, item 4)."""
import numpy as np
import pytest

from pneumatics.chamber import chamber_geometry
from pneumatics.robot import load_robot
from pneumatics.sim import COMMAND_RANGE_V, Simulation

SOAK_STEPS = 10 ** 6
PER_COMMAND = 10            # physics steps per random command (the 100 Hz controllers' period at 1 ms)


def soak_valve_robot(name: str, n_steps: int, seed: int = 0) -> dict:
    """Random commands over the whole 0-10 V range, held PER_COMMAND steps each; returns the
    counts of bad samples (checked after every command) and the pressure extremes [Pa]."""
    robot = load_robot(name)
    sim = Simulation(robot)
    sim.reset(pressure_pa=0.5 * (robot.tables.supply_pa + robot.tables.room_pa))
    rng = np.random.default_rng(seed)
    lo, hi = COMMAND_RANGE_V
    out = {"nonfinite": 0, "nonpositive": 0, "p_min": np.inf, "p_max": -np.inf}
    for _ in range(n_steps // PER_COMMAND):
        sim.set_command(rng.uniform(lo, hi, sim.command.size))
        sim.step(PER_COMMAND)
        p, q = sim.pressure, sim.data.qpos
        out["nonfinite"] += int(not (np.all(np.isfinite(p)) and np.all(np.isfinite(q)) and np.all(np.isfinite(sim.data.qvel))))
        out["nonpositive"] += int(np.any(p <= 0))
        out["p_min"], out["p_max"] = min(out["p_min"], p.min()), max(out["p_max"], p.max())
    return out


def soak_jetpipe(n_steps: int, seed: int = 0) -> dict:
    from pneumatics.jetpipe.sim import JetpipeSim
    sim = JetpipeSim()
    rng = np.random.default_rng(seed)
    limit = sim.cfg.driver.current_limit_a
    out = {"nonfinite": 0, "nonpositive": 0}
    for _ in range(n_steps // PER_COMMAND):
        sim.step(rng.uniform(-limit, limit), PER_COMMAND)
        p = sim.pressure
        out["nonfinite"] += int(not (np.all(np.isfinite(sim.y)) and np.isfinite(sim.data.qpos[0])))
        out["nonpositive"] += int(np.any(p <= 0))
    return out


def soak_hydraulic(n_steps: int, seed: int = 0) -> dict:
    from pneumatics.hydraulics.sim import load_hydraulic
    sim = load_hydraulic("sarcos_elbow")
    rng = np.random.default_rng(seed)
    i_sat = sim.cfg.hysteresis.saturation_current_a
    out = {"nonfinite": 0, "nonpositive": 0}
    for _ in range(n_steps // PER_COMMAND):
        sim.set_current(rng.uniform(-i_sat, i_sat))
        sim.step(PER_COMMAND)
        p = np.array(list(sim.pressures.values()))
        out["nonfinite"] += int(not (np.all(np.isfinite(p)) and np.all(np.isfinite(sim.data.qpos))))
        out["nonpositive"] += int(np.any(p <= 0))
    return out


def closed_valve_gas(name: str, n_steps: int, torque_nm: float = 0.0, seed: int = 0) -> np.ndarray:
    """Relative drift (n_steps // 1000, n_ch) of each chamber's gas content with every valve
    shut while the robot swings under unequal pressures and gravity, and, with ``torque_nm``,
    random joint torques up to that (new ones every 0.1 s).  For the polytropic chamber of
    paper 002 eq. 9 with no flow, p V^n is constant (n: the polytropic exponent), i.e. the
    mass m = p V / (R T) with T ~ p^((n-1)/n) is kept."""
    robot = load_robot(name)
    sim = Simulation(robot)
    rng = np.random.default_rng(seed)
    n_ch = robot.tables.n_chambers
    sim.reset(pressure_pa=np.where(np.arange(n_ch) % 2 == 0, 5.5e5, 2.0e5))
    sim.areas[:] = 0.0  # every valve shut (no set_command afterwards: it would reopen them)
    n = robot.tables.gas.polytropic_exponent

    def content():
        length = sim.data.actuator_length[robot.actuator_ids]
        volume, _ = chamber_geometry(robot.tables, length, length, sim.dt)
        return sim.pressure * volume ** n

    c0, drift = content(), []
    for _ in range(n_steps // 1000):
        for _ in range(10):
            sim.data.qfrc_applied[robot.dof_index] = rng.uniform(-torque_nm, torque_nm, robot.dof_index.size)
            sim.step(100)
        drift.append(content() / c0 - 1.0)
    return np.array(drift)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["arm2", "humanoid38"])
def test_soak_valve_robots(name):
    out = soak_valve_robot(name, SOAK_STEPS)
    tab = load_robot(name).tables
    assert out["nonfinite"] == 0 and out["nonpositive"] == 0
    # physics bounds: no chamber near a vacuum, none far above the supply (a chamber shut near
    # null and compressed by a limb's swing goes above it: 1.07 MPa seen on humanoid38)
    assert out["p_min"] > 0.3 * tab.room_pa and out["p_max"] < 3.0 * tab.supply_pa


@pytest.mark.slow
def test_soak_jetpipe():
    assert soak_jetpipe(SOAK_STEPS) == {"nonfinite": 0, "nonpositive": 0}


@pytest.mark.slow
def test_soak_sarcos_elbow():
    assert soak_hydraulic(SOAK_STEPS) == {"nonfinite": 0, "nonpositive": 0}


@pytest.mark.slow
def test_closed_valves_conserve_the_gas_over_a_long_swing():
    # the pressure imbalance swings the arm into its limits; it settles on its air springs
    drift = closed_valve_gas("arm2", SOAK_STEPS // 10)
    assert np.max(np.abs(drift)) < 1e-3


def test_closed_valves_conserve_the_gas_short():
    drift = closed_valve_gas("arm2", 5000)
    assert np.max(np.abs(drift)) < 1e-3


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="known defect, measured 2026-11-25: with the valves shut and random joint "
                   "torques of up to 3 N m (the arm at a joint limit 22 % of the time) chamber b0's p V^n drifts "
                   "by -1.7 % in 20 s and -7 % in 100 s, with the numpy and the compiled kernel alike: the "
                   "step's third-order error accumulating where compressions are faster than expansions "
                   "(docs/reliability.md)")
def test_closed_valves_conserve_the_gas_under_forced_motion():
    drift = closed_valve_gas("arm2", 20000, torque_nm=3.0)
    assert np.max(np.abs(drift)) < 1e-3


def test_soak_short_every_model():
    for out in (soak_valve_robot("arm2", 20000), soak_jetpipe(5000), soak_hydraulic(5000)):
        assert out["nonfinite"] == 0 and out["nonpositive"] == 0
