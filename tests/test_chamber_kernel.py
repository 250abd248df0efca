"""The doctor's compiled chamber step (identification.doctor.valve_arm.chamber_kernel) against its numpy reference
(ChamberModel.step_reference): one step on random states with each pneumatic hypothesis, and a
whole pressure replay of a recording."""
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from identification.doctor.valve_arm.data import prepare
from identification.doctor.valve_arm.pneumatic import SUPPLY_FLOW_ARG, ChamberModel, Windows, replay
from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
from pneumatics.recording import read_csv
from pneumatics.robot import load_robot

BLIND = Path(__file__).resolve().parents[2] / "shared" / "samples" / "arm2-blind"

ROBOT = load_robot("arm2")
C = ROBOT.tables.n_chambers
W = 7

EFFECTS = {
    "nominal": {},
    "calibration": {"supply_scale": np.array([0.9, 1.1, 1.0, 0.8]), "exhaust_scale": np.array([1.2, 0.9, 1.0, 1.1]),
                    "dead_volume_scale": np.array([1.3, 0.7, 1.0, 1.5])},
    "valve_leak": {"valve_leak_m2": np.array([2e-8, 0.0, 5e-8, 0.0]), "valve_leak_width_v": 0.4},
    "valve_leak_asymmetric": {"valve_leak_m2": np.array([1e-8, 0.0, 5e-8, 0.0]),
                              "valve_leak_exhaust_m2": np.array([4e-8, 2e-8, 5e-8, 0.0])},
    "valve_underlap": {"valve_underlap_m2": np.array([0.0, 3e-8, 2e-8, 0.0]),
                       "valve_underlap_width_v": np.array([0.6, 0.3, 1.2, 0.6]),
                       "valve_leak_m2": np.array([1e-8, 0.0, 0.0, 0.0])},
    "valve_clearance": {"valve_clearance_g": np.array([4e-11, 0.0, 2e-11, 0.0]),
                        "valve_clearance_width_v": np.array([0.6, 0.6, 0.3, 0.6]), "supply_droop_pa_per_kg_s": 3e7},
    "heat_transfer_with_clearance": {"heat_w_k": np.array([0.2, np.nan, np.nan, np.nan]),
                                     "valve_clearance_g": np.array([4e-11, 0.0, 0.0, 0.0])},
    "external_leak": {"external_leak_m2": np.array([0.0, 3e-8, 0.0, 1e-8])},
    "piston_leak": {"piston_leak_m2": np.array([2e-8, 4e-8])},
    "laminar_leaks": {"external_leak_g": np.array([0.0, 3e-11, 0.0, 1e-11]), "piston_leak_g": np.array([2e-11, 4e-11])},
    "both_leak_forms": {"external_leak_g": np.array([1e-11, 0.0, 0.0, 0.0]), "external_leak_m2": np.array([1e-8, 0.0, 0.0, 0.0]),
                        "piston_leak_g": np.array([2e-11, 0.0]), "piston_leak_m2": np.array([1e-8, 0.0])},
    "supply_droop": {"supply_droop_pa_per_kg_s": 3e7},
    "supply_reservoir": {"supply_droop_pa_per_kg_s": 3e7, "supply_droop_tau_s": 0.004},
    "regulator_orifice": {"supply_droop_pa_per_kg2_s2": 5e10, "supply_droop_tau_s": 0.004},
    "line_volume": {"extra_volume_m3": np.array([0.0, 2e-6, 1e-6, 0.0])},
    "lumped_line": {"tube_volume_m3": np.array([2e-6, 0.0, 5e-7, 0.0]),
                    "tube_time_constant_s": np.array([0.01, 0.01, 0.004, 0.01])},
    "lumped_line_with_leaks_and_heat": {"tube_volume_m3": np.array([1e-6, 0.0, 0.0, 3e-6]),
                                        "tube_time_constant_s": np.array([0.006, 0.01, 0.01, 0.015]),
                                        "heat_w_k": np.array([0.2, 0.1, np.nan, 0.3]),
                                        "piston_leak_m2": np.array([3e-8, 0.0]),
                                        "external_leak_g": np.array([2e-11, 0.0, 0.0, 1e-11]),
                                        "valve_clearance_g": np.array([4e-11, 0.0, 0.0, 2e-11]),
                                        "supply_droop_pa_per_kg_s": 3e7},
    "wall_compliance": {"wall_compliance_m3_pa": np.array([0.0, 2e-12, 0.0, 5e-13]), "piston_leak_m2": np.array([0.0, 2e-8])},
    "heat_transfer": {"heat_w_k": np.array([0.2, np.nan, 0.05, 0.3])},
    "heat_transfer_with_leaks": {"heat_w_k": np.array([0.2, 0.1, np.nan, np.nan]), "piston_leak_m2": np.array([3e-8, 0.0]),
                                 "external_leak_m2": np.array([2e-8, 0.0, 0.0, 0.0]), "supply_droop_pa_per_kg_s": 3e7},
    "heat_transfer_with_laminar_leaks": {"heat_w_k": np.array([0.2, 0.1, np.nan, np.nan]),
                                         "piston_leak_g": np.array([3e-11, 0.0]),
                                         "external_leak_g": np.array([2e-11, 0.0, 0.0, 0.0])},
}


def _mods(name):
    m = PneumaticMods.nominal(C)
    return m.copy(**EFFECTS[name])


@settings(max_examples=25, deadline=None)
@given(st.sampled_from(sorted(EFFECTS)), st.integers(0, 2**32 - 1))
def test_compiled_step_matches_the_numpy_reference(effect, seed):
    """Random pressures (room to supply), gas temperatures (250-350 K), commands (0-10 V) and
    piston motions (up to 0.5 m/s): three successive steps agree to 1e-10 relative, pressures,
    temperatures and tube pressures (the droop carries the supply flow over)."""
    _three_steps_agree(effect, seed)


@pytest.mark.parametrize("effect", ["lumped_line", "lumped_line_with_leaks_and_heat"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_lumped_line_step_matches_the_numpy_reference(effect, seed):
    """The lumped line's own state, the tube pressure, in every draw (the random test above
    samples a few of its many effects)."""
    _three_steps_agree(effect, seed)


def _three_steps_agree(effect, seed):
    rng = np.random.default_rng(seed)
    tab = ROBOT.tables
    a, b = ChamberModel(ROBOT, _mods(effect), W), ChamberModel(ROBOT, _mods(effect), W)
    a.T = rng.uniform(250.0, 350.0, (W, C))
    b.T = a.T.copy()
    p_a = p_b = rng.uniform(tab.room_pa, tab.supply_pa, (W, C))
    x = rng.uniform(0.0, 0.07, (W, C))
    for _ in range(3):
        u = rng.uniform(0.0, 10.0, (W, C))
        x1 = np.clip(x + rng.uniform(-5e-4, 5e-4, (W, C)), 0.0, 0.07)
        p_a, p_b = a.step(p_a, u, x, x1), b.step_reference(p_b, u, x, x1)
        np.testing.assert_allclose(p_a, p_b, rtol=1e-10)
        np.testing.assert_allclose(a.T, b.T, rtol=1e-10)
        np.testing.assert_allclose(a.p_tube, b.p_tube, rtol=1e-10)
        x = x1
    assert np.all(np.isfinite(p_a)) and np.all(p_a > 0)


@pytest.fixture(scope="module")
def experiment():
    if not BLIND.is_dir():
        pytest.skip("shared/samples not beside the repo")
    return prepare(ROBOT, read_csv(BLIND / "case_8e12431d.csv").slice(0.0, 4.0))


@pytest.mark.parametrize("effect", ["nominal", "valve_leak", "piston_leak", "supply_droop", "supply_reservoir",
                                    "regulator_orifice", "heat_transfer_with_leaks",
                                    "laminar_leaks", "wall_compliance", "lumped_line_with_leaks_and_heat"])
def test_compiled_replay_matches_the_numpy_replay(experiment, effect, monkeypatch):
    """A whole pressure replay (1 s windows over 4 s of a published recording) through the compiled loop
    and step equals the numpy reference's (a Python loop of numpy steps) to 1e-9 relative."""
    win = Windows.tile(experiment.t.size, 100, stride=50)
    fast, meas = replay(experiment, win, _mods(effect))
    monkeypatch.setattr(ChamberModel, "step", ChamberModel.step_reference)
    monkeypatch.setattr(ChamberModel, "run_windows", ChamberModel.run_windows_reference)
    slow, meas2 = replay(experiment, win, _mods(effect))
    np.testing.assert_array_equal(meas, meas2)
    np.testing.assert_allclose(fast, slow, rtol=1e-9)
    if effect == "nominal":  # and it replays the recording (made without effects) [Pa]
        assert np.sqrt(np.mean((fast - meas) ** 2)) < 2e4


@pytest.mark.parametrize("effect", ["nominal", "valve_underlap", "valve_clearance", "supply_reservoir",
                                    "heat_transfer_with_leaks", "receiver", "lumped_line"])
@pytest.mark.parametrize("averaged", [True, False])
def test_the_compiled_loop_over_the_fine_steps_is_its_python_loop_to_the_bit(effect, averaged):
    """ChamberModel.run_windows (chamber_kernel.replay_batch) against run_windows_reference, the
    Python loop of compiled steps it replaces: the same pressures, gas temperatures and supply
    flows to the bit, a receiver's supply path followed step by step included."""
    rng = np.random.default_rng(7)
    tab = ROBOT.tables
    F, H, S = 3000, 40, 10
    u = rng.uniform(3.0, 7.0, (F, C))
    travel = np.clip(0.035 + np.cumsum(rng.normal(0.0, 2e-5, (F, C)), axis=0), 0.0, 0.07)
    first = np.array([0, 700, 1500, 2550])
    p0 = rng.uniform(tab.room_pa, tab.supply_pa, (first.size, C))
    receiver = tab.supply_pa - 2e4 * (1 + np.sin(np.arange(F) * 2e-3)) if effect == "receiver" else None
    mods = _mods("nominal" if effect == "receiver" else effect)
    models = [ChamberModel(ROBOT, mods, first.size) for _ in range(2)]
    for m in models:
        m.T = np.full((first.size, C), 300.0)
        m.set_supply_flow(np.full(first.size, 2e-4))
    fast = models[0].run_windows(p0, u, travel, first, H, S, averaged, receiver)
    slow = models[1].run_windows_reference(p0, u, travel, first, H, S, averaged, receiver)
    np.testing.assert_array_equal(fast, slow)
    np.testing.assert_array_equal(models[0].T, models[1].T)
    np.testing.assert_array_equal(models[0].p_tube, models[1].p_tube)
    np.testing.assert_array_equal(*(m._kernel_args[SUPPLY_FLOW_ARG] for m in models))
    np.testing.assert_array_equal(models[0].supply_shift, models[1].supply_shift)
    assert np.all(np.isfinite(fast)) and np.ptp(fast) > 1e3
