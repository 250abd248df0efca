"""supply_droop's compressor_cycling form in the doctor: the receiver's path (receiver.py) and
its naming from the chambers' flow errors (supply_receiver.py)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from identification.doctor.valve_arm.receiver import path, path_reference
from pneumatics.effects.supply_droop import CompressorCycling, receiver_step

RT = 287.0 * 293.15
ROOM = 1.013e5


def _compressor(volume=1e-3, delivery=4e-4, band=3e4, leak=3e-11):
    return CompressorCycling(volume, delivery, band, 7e5, leak)


@settings(max_examples=25, deadline=None)
@given(st.floats(2e-4, 5e-3), st.floats(1e-4, 2e-3), st.floats(5e3, 8e4), st.floats(0.0, 1e-10), st.integers(0, 2**31))
def test_the_compiled_path_is_its_reference(volume, delivery, band, leak, seed):
    """Random draws of 0-1.5 g/s over 2000 steps of 1-100 ms, two restarts: equal to round-off."""
    rng = np.random.default_rng(seed)
    total, dt = rng.uniform(0.0, 1.5e-3, 2000), rng.uniform(1e-3, 0.1, 2000)
    c = _compressor(volume, delivery, band, leak)
    args = (total, dt, c, [0, 700], [6.9e5, 6.8e5], [0.0, 1.0], RT, ROOM)
    np.testing.assert_allclose(path(*args), path_reference(*args), rtol=1e-12)


def test_the_switch_flips_inside_a_step_so_the_period_does_not_depend_on_the_step():
    """No leak, a draw held over each 0.1 s block: a path of one step per block passes through
    the 1 ms path's pressures at the block boundaries (the switch meets its limits exactly), and
    the receiver cycles between cut-in and cut-out."""
    c = _compressor(leak=0.0)
    blocks = np.random.default_rng(1).uniform(0.0, 3e-4, 300)  # within the delivery: the switch holds it
    fine = path(np.repeat(blocks, 100), np.full(30000, 1e-3), c, [0], [7e5], [0.0], RT, ROOM)
    coarse = path(blocks, np.full(300, 0.1), c, [0], [7e5], [0.0], RT, ROOM)
    np.testing.assert_allclose(coarse, fine[::100], rtol=1e-9)
    assert fine.min() >= 7e5 - 3e4 - 1.0 and fine.max() <= 7e5 + 1.0
    assert np.sum(np.diff((fine < 7e5 - 2.9e4).astype(int)) == 1) >= 3


def test_the_doctors_path_follows_the_simulators_receiver():
    """The simulator steps the receiver by effects.supply_droop.receiver_step (1 ms, switching
    at a step's end); the doctor's path at 1 ms keeps within 0.5 % of the band of it over 20 s
    of a varying draw (about eight cycles)."""
    c = _compressor()
    total = 2e-4 + 2e-4 * np.sin(np.arange(20000) * 1e-3 * 2.0)
    p, running, ref = 7e5, False, []
    for m in total:
        ref.append(p)
        p, running = receiver_step(p, running, float(m), c, RT, ROOM, 1e-3)
    doctor = path(total, np.full(total.size, 1e-3), c, [0], [7e5], [0.0], RT, ROOM)
    assert np.max(np.abs(doctor - np.array(ref))) < 0.005 * c.band_pa * 20


@pytest.fixture(scope="module")
def compressor_case(tmp_path_factory):
    """pneumasim's own arm2 (nominal parameters) tracking under PIDF, its supply a 1 L receiver
    refilled at 0.4 g/s between 6.7 and 7 bar (a cycle of about 5 s): 30 s + 15 s held out."""
    from pneumatics.effects.effect_set import EffectSet
    from pneumatics.robot import load_robot
    from scenarios._cases import _record, _write

    robot = load_robot("arm2")
    effects = EffectSet().add("supply_droop", "all", {"receiver_volume_m3": 1e-3, "compressor_kg_s": 4e-4,
                                                      "band_pa": 3e4, "cut_out_pa": 7e5, "leak_kg_s_pa": 3e-11},
                              form="compressor_cycling")
    out = tmp_path_factory.mktemp("compressor")
    return _write(out, "compressor", _record(robot, effects, 5, 30.0, 15.0))


# a whole doctor's run (45 s on a slow 2-core machine), slow for CI's 15 minutes;
# the receiver fit's tests are beside it
@pytest.mark.slow
def test_the_doctor_names_a_cycling_compressor(compressor_case):
    from identification.doctor.valve_arm.diagnose import diagnose
    from pneumatics.recording import read_csv
    from pneumatics.robot import load_robot

    rep = diagnose(load_robot("arm2"), [read_csv(compressor_case["main"])], [read_csv(compressor_case["heldout"])])
    first = rep["findings"][0]
    assert (first["effect"], first["form"], first["where"]) == ("supply_droop", "compressor_cycling", {"supply": "all"})
    band = first["parameters"]["band_pa"]["value"]
    assert 1.5e4 < band < 6e4  # the switch's 0.3 bar
    assert first["heldout_nrmse"]["after"] < first["heldout_nrmse"]["before"]


def _sawtooth_target(c: CompressorCycling, seconds: float = 60.0, noise_pa: float = 3e3, seed: int = 0):
    """A _Target of 0.1 s blocks whose four chambers' flow errors are a receiver's saw-tooth
    (``c`` under a varying draw) seen through each chamber's supply sensitivity, plus noise of
    ``noise_pa`` in the supply's units: what flow_error gives for a cycling compressor."""
    total = _draw(seconds)
    p = path(total, np.full(total.size, 1e-3), c, [0], [c.cut_out_pa], [0.0], RT, ROOM)
    return _supply_target(p - c.cut_out_pa, total, noise_pa, seed)


def _draw(seconds: float) -> np.ndarray:
    """(F,) a varying total supply draw [kg/s] on the 1 ms grid."""
    return 1e-4 + 5e-5 * np.abs(np.sin(np.arange(int(seconds * 1000)) * 1e-3 * 0.7))


def _supply_target(dp_fine: np.ndarray, total: np.ndarray, noise_pa: float, seed: int):
    """A _Target of 0.1 s blocks whose four chambers' flow errors are the supply pressure error
    ``dp_fine`` (F,) [Pa] seen through each chamber's supply sensitivity, plus noise."""
    from identification.doctor.valve_arm.supply_receiver import _Target

    rng = np.random.default_rng(seed)
    length = 100
    first = np.arange(0, dp_fine.size - length + 1, length)
    pb = np.array([dp_fine[f:f + length].mean() for f in first])
    s = rng.uniform(2e-10, 8e-10, (first.size, 4))
    dp = pb[:, None] + rng.normal(0.0, noise_pa, (first.size, 4))
    return _Target(s * dp, s, np.ones_like(s), total, np.array([0]), first, length)


def test_the_supply_estimate_and_its_period_read_the_sawtooth():
    """The per-block supply error recovers the receiver's band (5-95 % range within 15 %) and
    its cycle's period (within 3 %, the zero-padded transform's peak)."""
    from identification.doctor.valve_arm.supply_receiver import dominant_period_s

    c = _compressor(volume=7e-4, delivery=5e-4, band=2.3e4, leak=0.0)
    t = _sawtooth_target(c)
    est = t.supply_estimate()
    assert abs(np.subtract(*np.percentile(est, [95, 5])) / c.band_pa - 1.0) < 0.15
    p = path(t.total, np.full(t.total.size, 1e-3), c, [0], [c.cut_out_pa], [0.0], RT, ROOM)
    period_true = 60.0 / np.sum(np.diff((p > c.cut_out_pa - 0.5 * c.band_pa).astype(int)) == 1)  # upward mid-crossings
    assert abs(dominant_period_s(est, 0.1) / period_true - 1.0) < 0.03
    assert dominant_period_s(np.zeros(100), 0.1) is None  # flat: no frequency at all
    assert dominant_period_s(np.arange(8.0), 0.1, cycles_min=3.0) is None  # 0.8 s: too short for three cycles


def test_the_receiver_fit_finds_a_small_fast_cycling_receiver():
    """A 0.7 L receiver refilled at 0.5 g/s between limits 23 kPa apart (the cycle of fresh
    generalization seed 273211245, where the global search alone ended at 3.7 L, 5.4 g/s):
    volume, delivery and band within a factor 1.5, and the fit pays on a held-out stretch."""
    from identification.doctor.valve_arm.supply_receiver import fit_receiver

    c = _compressor(volume=7e-4, delivery=5e-4, band=2.3e4, leak=0.0)
    fit = fit_receiver(_sawtooth_target(c, seed=1), _sawtooth_target(c, 30.0, seed=2), c.cut_out_pa, RT, ROOM)
    got = fit.compressor
    for name in ("receiver_volume_m3", "compressor_kg_s", "band_pa"):
        assert 1 / 1.5 < getattr(got, name) / getattr(c, name) < 1.5, (name, getattr(got, name))
    assert fit.pays and fit.heldout_gain > 0.5


def test_a_pulsation_is_not_named_a_receivers_cycle():
    """A running compressor's 1.2 Hz, 0.3 bar pulsation of the supply (outside the vocabulary;
    fresh seed 646247226 had one named compressor_cycling): the steady pulsation is found at
    its frequency and predicts the held-out stretch better than any receiver's cycle, so the
    receiver is not kept (flex_check's ripple check is left to report it)."""
    from identification.doctor.valve_arm.supply_receiver import fit_receiver, pulsation_gains

    def ripple(seconds, seed):
        total = _draw(seconds)
        t = np.arange(total.size) * 1e-3
        return _supply_target(3e4 * np.sin(2 * np.pi * 1.2 * t), total, 3e3, seed)

    train, held = ripple(60.0, 1), ripple(30.0, 2)
    f, train_gain, held_gain = pulsation_gains(train, held)
    assert abs(f - 1.2) <= 0.01 and min(train_gain, held_gain) > 0.8
    fit = fit_receiver(train, held, 7e5, RT, ROOM)
    assert fit.pulsation_heldout_gain == held_gain > fit.heldout_gain + 0.05
    assert not fit.pays


def test_a_receiver_fit_pays_only_with_a_pressure_switchs_cycle():
    """The keep rule itself: gains above the floor and three switches or more, at a mean cycle
    of at least MIN_CYCLE_S (two switch events a cycle), the held-out gain above a steady
    pulsation's less PULSATION_MARGIN."""
    from identification.doctor.valve_arm.supply_receiver import MIN_CYCLE_S, ReceiverFit

    def fit(switches, pulsation=0.2):
        return ReceiverFit(_compressor(), 0.5, 0.5, switches, np.zeros(1), np.zeros(1), 60.0,
                           pulsation_heldout_gain=pulsation)
    assert fit(20).pays and fit(20).mean_cycle_s == 6.0
    assert not fit(int(2 * 60.0 / MIN_CYCLE_S) + 2).pays  # faster than a pressure switch cycles
    assert not fit(2).pays  # a step, not a cycle
    assert fit(20, pulsation=0.52).pays  # a tie goes to the receiver
    assert not fit(20, pulsation=0.6).pays  # a steady pulsation predicts the held-out recording clearly better


def test_a_start_clipped_to_a_bound_is_one_the_global_search_accepts():
    """A saw-tooth start at the edge of the receiver's bounds (a band at its 10^5.2 Pa cap):
    SciPy's differential_evolution rescales x0 to [0, 1], where the rounding of exactly the
    upper bound gave 1 + 2e-16 and a ValueError; inside_bounds keeps the start inside."""
    from scipy.optimize import differential_evolution

    from identification.doctor.valve_arm.supply_receiver import (LOG10_BAND_PA, LOG10_DELIVERY_KG_S,
                                                                 LOG10_VOLUME_M3, inside_bounds)

    bounds = [LOG10_VOLUME_M3, LOG10_DELIVERY_KG_S, LOG10_BAND_PA, (0.0, 1.0), (0.0, 1.0), (0.0, 1.0)]
    lo, hi = inside_bounds(bounds)
    assert np.all(lo > np.array(bounds)[:, 0]) and np.all(hi < np.array(bounds)[:, 1])
    assert np.allclose(hi, np.array(bounds)[:, 1], rtol=0, atol=1e-8)
    for start in (hi, lo):
        differential_evolution(lambda x: float(np.sum(x ** 2)), bounds, x0=start, maxiter=1, popsize=2,
                               polish=False, seed=0)
