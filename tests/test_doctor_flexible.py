"""The doctor's flexible mass-flow corrections (identification.doctor.valve_arm.flexible): which
group of physical inputs carries a planted mass flow, silence on clean recordings, and an
effect outside the library reported ``unexplained`` at its chamber rather than nothing."""
from pathlib import Path

import numpy as np
import pytest

from identification.doctor.valve_arm.calibrate import fit_chambers, pressure_sigma
from identification.doctor.valve_arm.data import prepare
from identification.doctor.valve_arm.flexible import (FLEX_FLOOR, SUPPLY_FLOOR, chamber_correction, paying,
                                                      supply_correction)
from identification.doctor.valve_arm.supply_time import SUPPLY_TIME_FLOOR, supply_in_time, supply_ripple
from identification.doctor.valve_arm.flow_error import flow_blocks
from identification.doctor.valve_arm.pneumatic import Windows
from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
from identification.doctor.valve_arm.rules import HORIZON
from pneumatics.recording import read_csv
from pneumatics.robot import load_robot

BLIND = Path(__file__).resolve().parents[2] / "shared" / "samples" / "arm2-blind"
NULL = "case_8e12431d"
needs_samples = pytest.mark.skipif(not BLIND.is_dir(), reason="shared/samples not beside the repo")


@pytest.fixture(scope="module")
def null_calibrated():
    """The published null sample's fitted and held-out recordings, prepared, and the chamber
    model calibrated on the fitted one (as the doctor calibrates it: its +-10 % valve area and
    dead volume errors would otherwise be the largest mass-flow error)."""
    robot = load_robot("arm2")
    exp = prepare(robot, read_csv(BLIND / f"{NULL}.csv"))
    held = prepare(robot, read_csv(BLIND / f"{NULL}_heldout.csv"))
    win = Windows.tile(len(exp.t), HORIZON, breaks=exp.breaks)
    mods, _ = fit_chambers(exp, win, PneumaticMods.nominal(robot.tables.n_chambers), pressure_sigma(exp))
    return robot, exp, held, mods


@pytest.fixture(scope="module")
def null_twin(null_calibrated):
    """twin.twin_gains on the null sample: each chamber's twin gain and the supply-in-time check."""
    from identification.doctor.valve_arm.twin import twin_gains
    robot, exp, held, mods = null_calibrated
    return twin_gains(exp, held, mods, pressure_sigma(exp), 10)


@pytest.fixture(scope="module")
def null_blocks(null_calibrated):
    """Block means (0.1 s) of the null sample's recordings under its calibrated chamber model."""
    robot, exp, held, mods = null_calibrated
    return robot, exp, held, flow_blocks(exp, mods, 10), flow_blocks(held, mods, 10)


def _sample_means(exp, blocks, x):
    """Block means (B, C) of a per-sample quantity x (N, C) over the blocks' samples."""
    half = 5
    return np.stack([x[max(k - half, 0): k + half].mean(axis=0) for k in blocks.sample])


def _with_term(tr, ho, exp, held, fn, c, size=1.5):
    """Copies of the blocks with fn(exp) (N, C) added to chamber c's equation error, scaled to
    ``size`` x the error's RMS there."""
    import dataclasses
    t_tr = _sample_means(exp, tr, fn(exp))[:, c]
    t_ho = _sample_means(held, ho, fn(held))[:, c]
    k = size * np.sqrt(np.mean(tr.error[:, c] ** 2)) / np.sqrt(np.mean(t_tr ** 2))
    e_tr, e_ho = tr.error.copy(), ho.error.copy()
    e_tr[:, c] += k * t_tr
    e_ho[:, c] += k * t_ho
    return dataclasses.replace(tr, error=e_tr), dataclasses.replace(ho, error=e_ho)


@needs_samples
@pytest.mark.parametrize("group, term", [
    # a laminar-like leak to the room growing as (p - p_room)^0.7: not one of the inputs' forms
    ("pressure level", lambda e: -np.maximum(e.p - e.robot.tables.room_pa, 0.0) ** 0.7),
    # an underlap feeding the chamber from the supply near null, narrower than the bumps and laminar
    ("command near null", lambda e: np.exp(-((e.u - e.robot.tables.valve[:, 0]) / 0.45) ** 2)
     * (e.robot.tables.supply_pa - e.p)),
])
def test_the_group_that_carries_a_planted_mass_flow_is_found(null_blocks, group, term):
    robot, exp, held, tr, ho = null_blocks
    c = 2  # elbow a
    tr2, ho2 = _with_term(tr, ho, exp, held, term, c)
    corr = chamber_correction(tr2, ho2, c, {"actuator": "elbow", "chamber": "a"})
    assert corr.gain > 0.5  # the planted term is 1.5 x the error's RMS: most of it is recovered
    # under tracking control the commands stay near null most of the time, so a leak to the room
    # and an underlap leak are both taken up by either group (seen: 0.77 and 0.74 alone): the
    # correction names both, and the fits of their families decide (flex_check.suggested_candidates)
    assert group in corr.depends_on
    assert not {"p_a - p_b", "volume", "command history"} & set(corr.depends_on)
    # the other chambers carry nothing planted: their corrections stay below the floor
    others = [chamber_correction(tr2, ho2, k, {}) for k in range(4) if k != c]
    assert max(o.best_group_gain for o in others) < FLEX_FLOOR
    assert [p.where for p in paying([corr, *others, supply_correction(tr2, ho2)])] == [corr.where]


@needs_samples
def test_a_common_supply_term_is_found_by_the_supply_correction(null_blocks):
    """A supply pressure sagging with the total supply flow's 0.1 s history acts on every
    filling chamber through its own d mdot / d p_supply: the supply's common-mode correction
    takes it up at every chamber."""
    import dataclasses
    robot, exp, held, tr, ho = null_blocks

    def sag(b):  # the supply inputs are d mdot_c/dp_s x (total flow and its histories)
        return -(0.6 * b.supply[:, :, 1] + 0.4 * b.supply[:, :, 2])
    k = 2.0 * np.sqrt(np.mean(tr.error ** 2)) / np.sqrt(np.mean(sag(tr) ** 2))
    tr2 = dataclasses.replace(tr, error=tr.error + k * sag(tr))
    ho2 = dataclasses.replace(ho, error=ho.error + k * sag(ho))
    s = supply_correction(tr2, ho2)
    # Huber's weights take the peaks of the sag (a valve opening wide) as outliers: part of it stays
    assert s.gain > 0.3 and min(s.per_chamber.values()) > SUPPLY_FLOOR
    assert s.suggests == ["supply_droop"]
    # the chambers' corrections are fitted to what the common mode leaves: none stands out
    rest_tr = dataclasses.replace(tr2, error=tr2.error - s.fitted_train)
    rest_ho = dataclasses.replace(ho2, error=ho2.error - s.fitted_h)
    chambers = [chamber_correction(rest_tr, rest_ho, c, {"c": c}) for c in range(4)]
    assert [p.where for p in paying([*chambers, s])] == [{"supply": "all"}]
    assert supply_correction(tr, ho).gain < SUPPLY_FLOOR  # and nothing without it


@needs_samples
def test_a_clean_recording_leaves_no_correction_paying(null_blocks):
    robot, exp, held, tr, ho = null_blocks
    corrs = [chamber_correction(tr, ho, c, {"c": c}) for c in range(4)] + [supply_correction(tr, ho)]
    assert paying(corrs) == []
    assert max(c.best_group_gain for c in corrs[:4]) < FLEX_FLOOR and corrs[4].gain < SUPPLY_FLOOR


@needs_samples
def test_a_supply_pressure_changing_in_time_is_found_across_actuators(null_blocks):
    """A supply that steps down by 0.4 bar halfway through each recording (another consumer
    switching on), acting on every filling chamber through its own d mdot / d p_supply: the
    time course fitted to one actuator's chambers predicts the other's, on both recordings, and
    takes up more than the flow-driven supply correction, whose constant term holds only the
    step's mean."""
    import dataclasses
    robot, exp, held, tr, ho = null_blocks

    def stepped(b, rate):
        t = b.sample / rate
        return b.supply_sensitivity * np.where(t > np.median(t), -0.4e5, 0.0)[:, None]
    tr2 = dataclasses.replace(tr, error=tr.error + stepped(tr, exp.rate_hz))
    ho2 = dataclasses.replace(ho, error=ho.error + stepped(ho, held.rate_hz))
    found = supply_in_time(tr2, ho2, exp.rate_hz, held.rate_hz)
    assert found.pays and min(found.train_gain, found.heldout_gain) > 0.3
    assert found.heldout_gain > supply_correction(tr2, ho2).gain + 0.2


@needs_samples
def test_one_block_of_outsized_supply_sensitivity_does_not_hide_a_supply_step(null_blocks):
    """A 12 kPa supply step, and in one training block the elbow's b chamber has twenty times
    the recording's largest supply sensitivity (a valve wide open to an empty chamber) while
    its flow error there stays what it was (the other simulator's valve did not follow the
    step there): the time course fitted to the shoulder predicts a large flow change in that
    one block.  Judged in Huber's loss, one missed block counts as far as it misses, not as its
    square, and the step is still found (development seed 882023949: training gain -1.10 with
    the error's Huber weights)."""
    import dataclasses
    robot, exp, held, tr, ho = null_blocks

    def stepped(b, rate):
        t = b.sample / rate
        return b.supply_sensitivity * np.where(t > np.median(t), -1.2e4, 0.0)[:, None]
    s_tr = tr.supply_sensitivity.copy()
    k = int(np.argmax(tr.sample / exp.rate_hz > 0.25 * tr.sample.max() / exp.rate_hz))
    e_tr = tr.error + stepped(tr, exp.rate_hz)
    s_tr[k, 3] = 20 * np.abs(tr.supply_sensitivity[:, 3]).max()
    tr2 = dataclasses.replace(tr, error=e_tr, supply_sensitivity=s_tr)
    ho2 = dataclasses.replace(ho, error=ho.error + stepped(ho, held.rate_hz))
    found = supply_in_time(tr2, ho2, exp.rate_hz, held.rate_hz)
    assert found.pays


@needs_samples
def test_a_supply_in_time_pays_only_above_its_twin(null_calibrated, null_blocks, null_twin):
    """The supply's change in time is judged against the calibrated model's twin of the
    recordings (module twin): on arm2's published null the twin finds no time course (the fixed
    floor decides there, as before the twin), and a gain no more than its twin's plus
    SUPPLY_TIME_TWIN_MARGIN does not pay (humanoid38's unresolved transients, shared in time)."""
    import dataclasses
    from identification.doctor.valve_arm.supply_time import SUPPLY_TIME_TWIN_MARGIN
    robot, exp, held, mods = null_calibrated
    _, twin = null_twin
    assert max(twin.train_gain, twin.heldout_gain) < SUPPLY_TIME_FLOOR - SUPPLY_TIME_TWIN_MARGIN
    _, _, _, tr, ho = null_blocks

    def stepped(b, rate):
        t = b.sample / rate
        return b.error + b.supply_sensitivity * np.where(t > np.median(t), -1.2e4, 0.0)[:, None]
    found = supply_in_time(dataclasses.replace(tr, error=stepped(tr, exp.rate_hz)),
                           dataclasses.replace(ho, error=stepped(ho, held.rate_hz)), exp.rate_hz, held.rate_hz)
    assert found.pays and found.pays_above(twin) and found.pays_above(None)
    close = dataclasses.replace(found, train_gain=found.train_gain - 0.5 * SUPPLY_TIME_TWIN_MARGIN,
                                heldout_gain=found.heldout_gain - 0.5 * SUPPLY_TIME_TWIN_MARGIN)
    assert not found.pays_above(close)


@needs_samples
def test_one_chambers_error_is_not_a_supply_changing_in_time(null_blocks):
    """Clean blocks, and a large error planted in one chamber only (a leak of its own): neither
    is a supply time course, since one actuator's chambers cannot predict another's."""
    import dataclasses
    robot, exp, held, tr, ho = null_blocks
    assert not supply_in_time(tr, ho, exp.rate_hz, held.rate_hz).pays
    e_tr, e_ho = tr.error.copy(), ho.error.copy()
    e_tr[:, 2] += 3 * tr.supply_sensitivity[:, 2] * 1e4 * np.sin(tr.sample / exp.rate_hz)
    e_ho[:, 2] += 3 * ho.supply_sensitivity[:, 2] * 1e4 * np.sin(ho.sample / held.rate_hz)
    one = supply_in_time(dataclasses.replace(tr, error=e_tr), dataclasses.replace(ho, error=e_ho),
                         exp.rate_hz, held.rate_hz)
    assert not one.pays and one.heldout_gain < SUPPLY_TIME_FLOOR


@needs_samples
def test_a_supply_pulsation_is_found_at_its_frequency(null_blocks):
    """A reciprocating compressor's pulsation, 0.2 bar at 2.3 Hz with another phase in each
    recording: too fast for the time course's knots, found by the periodic check at its
    frequency (chosen on the training recording, judged on the held-out one), while the clean
    blocks give neither."""
    import dataclasses
    robot, exp, held, tr, ho = null_blocks
    block = 10

    def pulsing(b, rate, phase):
        return b.supply_sensitivity * 0.2e5 * np.sin(2 * np.pi * 2.3 * b.sample / rate + phase)[:, None]
    tr2 = dataclasses.replace(tr, error=tr.error + pulsing(tr, exp.rate_hz, 0.0))
    ho2 = dataclasses.replace(ho, error=ho.error + pulsing(ho, held.rate_hz, 1.9))
    found = supply_ripple(tr2, ho2, exp.rate_hz, held.rate_hz, block)
    assert found.pays and abs(found.frequency_hz - 2.3) <= 0.02
    assert not supply_in_time(tr2, ho2, exp.rate_hz, held.rate_hz).pays
    clean = supply_ripple(tr, ho, exp.rate_hz, held.rate_hz, block)
    assert not clean.pays and clean.heldout_gain < 0.05


@needs_samples
def test_a_fast_supply_pulsation_is_found_on_the_fine_blocks(null_calibrated):
    """A 4.8 Hz pulsation lies above the 0.1 s blocks' 4.5 Hz reach; on RIPPLE_BLOCK_S means
    (0.05 s: up to 9 Hz) it is found at its frequency, and the clean blocks give nothing."""
    import dataclasses
    from identification.doctor.valve_arm.supply_time import RIPPLE_BLOCK_S
    robot, exp, held, mods = null_calibrated
    block = int(round(RIPPLE_BLOCK_S * held.rate_hz))
    tr, ho = flow_blocks(exp, mods, block), flow_blocks(held, mods, block)

    def pulsing(b, rate, phase):
        return b.supply_sensitivity * 0.15e5 * np.sin(2 * np.pi * 4.8 * b.sample / rate + phase)[:, None]
    found = supply_ripple(dataclasses.replace(tr, error=tr.error + pulsing(tr, exp.rate_hz, 0.4)),
                          dataclasses.replace(ho, error=ho.error + pulsing(ho, held.rate_hz, 2.5)),
                          exp.rate_hz, held.rate_hz, block)
    assert found.pays and abs(found.frequency_hz - 4.8) <= 0.02
    clean = supply_ripple(tr, ho, exp.rate_hz, held.rate_hz, block)
    assert not clean.pays and clean.heldout_gain < 0.05


@pytest.mark.slow
def test_a_clean_pneumasim_recording_is_silent(tmp_path, diagnose_case):
    """pneumasim's own simulator, no effect, 3 % parameter errors: no finding, no unexplained
    entry, and no flexible correction pays."""
    from scenarios._cases import make_case
    rep = diagnose_case(make_case(tmp_path, 21, [], seconds=40.0, heldout_seconds=20.0))
    assert rep["findings"] == [] and rep["unexplained"] == []
    flex = rep["diagnostics"]["flexible_corrections"]
    assert max(v["best_group_gain"] for k, v in flex.items() if k != "supply") < FLEX_FLOOR
    assert flex["supply"]["heldout_gain"] < SUPPLY_FLOOR
    assert max(flex["supply"]["in_time"].values()) < SUPPLY_TIME_FLOOR


@pytest.mark.slow
def test_a_valve_curve_outside_the_library_is_unexplained_at_its_chamber(tmp_path, diagnose_case):
    """elbow a's valve opens as the 2.2 power of the command past its dead band instead of the
    model's 1.3 (pneumatics.valve.valve_areas): no family of the library changes a valve's
    curve, and the calibrated area scale fits it only on average.  The doctor names nothing
    there and reports the chamber's mass flow unexplained, carried by the valve opening
    (seen 2026-11-25: 89 % of the held-out equation error, no finding)."""
    from scenarios._cases import _record, _write, perturbed_robot
    robot, _ = perturbed_robot(np.random.default_rng(11), 0.03)
    robot.tables.valve[2, 5] = 2.2                       # elbow a: the ramp's exponent
    paths = _write(tmp_path, "case", _record(robot, None, 11, 40.0, 20.0))
    rep = diagnose_case({"recordings": paths})
    assert not [f for f in rep["findings"] if f["where"] == {"actuator": "elbow", "chamber": "a"}]
    (u,) = [u for u in rep["unexplained"] if u["where"] == {"actuator": "elbow", "chamber": "a"}]
    assert u["residual"] == "mass flow" and u["share_of_residual"] > FLEX_FLOOR
    assert "valve opening" in u["depends_on"]
    assert rep["verdict"] == "missing_physics"


@pytest.mark.slow
def test_a_supply_step_is_unexplained_at_the_supply(tmp_path, diagnose_case):
    """The random-form generator's supply step outside the vocabulary (seed 883927900 of the
    first fresh generalization run: -0.26 bar at 70 % of each recording): no finding, one
    unexplained entry at the supply, in time."""
    from scenarios._variantsim.cases import make_case as make_variant_case

    truth = make_variant_case(tmp_path / "c", 883927900, ["outside_vocabulary"], seconds=60.0,
                              heldout_seconds=30.0, name="step", forms=["supply_step"])
    assert truth["effects"][0]["where"] == {"supply": "all"}
    report = diagnose_case(truth)
    assert report["findings"] == []
    assert [(u["where"], u["regime"]) for u in report["unexplained"]] == [({"supply": "all"},
                                                                           "in time (not with the flow drawn)")]
    assert report["diagnostics"]["flexible_corrections"]["supply"]["in_time"]["heldout_gain"] > 0.3


def _correction(gain, c):
    from identification.doctor.valve_arm.flexible import Correction

    return Correction(where={"actuator": f"a{c // 2}", "chamber": "ab"[c % 2]}, gain=gain,
                      alone={"volume": gain}, drop={"volume": gain}, fitted_h=np.zeros(1), error_h=np.zeros(1),
                      chambers=[c])


def test_the_chambers_floor_is_set_per_robot_from_their_spread():
    """76 chambers of a clean robot spread their corrections' gains (humanoid38, seed 7000:
    median 0.23, up to 0.74): none stands out.  One effect lifts its own chamber above the
    spread.  With arm2's 4 chambers there is no spread to estimate: the fixed floor alone."""
    from identification.doctor.valve_arm.flexible import paying

    rng = np.random.default_rng(0)
    clean = np.clip(rng.normal(0.23, 0.2, 76), 0.0, 0.74)
    assert paying([_correction(g, c) for c, g in enumerate(clean)]) == []
    lifted = np.where(np.arange(76) == 9, 0.97, np.clip(rng.normal(0.1, 0.05, 76), 0, 1))
    assert [c.chambers for c in paying([_correction(g, c) for c, g in enumerate(lifted)])] == [[9]]
    arm2 = [_correction(g, c) for c, g in enumerate([0.05, 0.08, 0.35, 0.06])]
    assert [c.chambers for c in paying(arm2)] == [[2]] and FLEX_FLOOR <= 0.35


def test_a_chamber_paying_no_more_than_on_its_twin_is_not_flagged():
    """Five humanoid38 cylinders whose pressures the 100 Hz samples do not resolve pay about
    0.6 on every recording, effect or none (docs/humanoid_doctor.md): above the robot's
    ceiling, so flagged, unless their twin's gains (module twin) say the model pays as much
    where nothing is missing.  An effect at a chamber the samples resolve stands far above its
    twin; a chamber whose partner its twin holds below the floor must stand out of it
    (PARTNER_STANDOUT)."""
    from identification.doctor.valve_arm.flexible import TWIN_MARGIN, paying

    rng = np.random.default_rng(2)
    gains = np.clip(rng.normal(0.2, 0.05, 76), 0.0, 1.0)
    unresolved = [20, 21, 30, 31, 40, 41, 50, 51, 60, 61]
    gains[unresolved] = 0.6
    gains[9] = 0.95
    corrs = [_correction(g, c) for c, g in enumerate(gains)]
    assert sorted(c.chambers[0] for c in paying(corrs)) == sorted([9, *unresolved])
    twin = {(f"a{c // 2}", "ab"[c % 2]): (0.58 if c in unresolved else 0.2) for c in range(76)}
    assert [c.chambers for c in paying(corrs, twin)] == [[9]]
    # the twin lifts a chamber's floor by TWIN_MARGIN exactly: at it, the cylinder pays
    twin[("a10", "a")] = twin[("a10", "b")] = 0.6 - TWIN_MARGIN
    assert [c.chambers for c in paying(corrs, twin)] == [[9], [20], [21]]
    # one chamber of it alone does not stand out of its cylinder (PARTNER_STANDOUT)
    twin[("a10", "b")] = 0.58
    assert [c.chambers for c in paying(corrs, twin)] == [[9]]


@needs_samples
def test_the_twin_of_the_null_sample_follows_it_and_pays_nowhere(null_calibrated, null_twin):
    """The calibrated chamber model replayed as the twin (restarted from the measured pressures
    every TWIN_RESTART_S) stays within the sensor noise's order of the null sample's pressures,
    and the flexible corrections find nothing on it: the floor a twin sets on a recording
    whose model lacks nothing is the robot's own (FLEX_FLOOR)."""
    from identification.doctor.valve_arm.data import pool, with_pressures
    from identification.doctor.valve_arm.flexible import TWIN_MARGIN
    from identification.doctor.valve_arm.twin import TWIN_RESTART_S, model_pressures

    robot, exp, held, mods = null_calibrated
    sigma = pressure_sigma(exp)
    p = model_pressures(exp, mods)
    assert np.array_equal(p[0], exp.p[0]) and TWIN_RESTART_S * exp.rate_hz < len(exp.t) / 10
    assert np.all(np.sqrt(np.mean((p - exp.p) ** 2, axis=0)) < 3 * sigma)
    np.testing.assert_array_equal(with_pressures(exp, exp.p).p_at_t, exp.p_at_t)
    # pooled recordings (several files given): their pressures at the sample times per recording
    pooled = pool([exp, held])
    np.testing.assert_allclose(with_pressures(pooled, pooled.p).p_at_t, pooled.p_at_t, rtol=1e-9)
    assert model_pressures(pooled, mods)[len(exp.t)].tolist() == held.p[0].tolist()  # restarted at the join
    gains, _ = null_twin
    assert set(gains) == set(robot.chamber_names)
    assert max(gains.values()) < FLEX_FLOOR - TWIN_MARGIN


def test_robust_ceiling_is_median_plus_three_robust_deviations():
    from identification.base.statistics import SPREAD_MIN_PLACES, robust_ceiling

    x = np.random.default_rng(1).normal(5.0, 2.0, 20001)
    assert robust_ceiling(x) == pytest.approx(11.0, abs=0.1)
    assert robust_ceiling(np.exp(x / 10), log=True) == pytest.approx(np.exp(1.1), rel=0.02)
    assert robust_ceiling(x[: SPREAD_MIN_PLACES - 1]) == -np.inf


def test_a_weak_finding_that_leaves_as_much_as_it_took_is_a_projection():
    """A finding that takes 0.21 of its chamber's held-out residual and leaves 0.21 there
    through the valve opening (an orifice external leak fitted to a supply area that shrinks
    with pressure, published sample case_2e6a35dc) is another law's projection; a strong one
    leaving the same, or a remainder through the inputs its own family acts through, is not."""
    from types import SimpleNamespace

    from identification.doctor.valve_arm.flex_check import REMAINDER_FLOOR, leaves_as_much
    from identification.doctor.valve_arm.flexible import Correction

    def corr(**alone):
        return Correction({"actuator": "elbow", "chamber": "a"}, max(alone.values()), alone, alone,
                          np.zeros(1), np.zeros(1), [2])

    def finding(family, gain):
        return SimpleNamespace(family=family, scored=SimpleNamespace(heldout_gain=gain))

    weak, strong = finding("external_leak", 0.214), finding("external_leak", 0.68)
    assert leaves_as_much(corr(**{"valve opening": 0.21, "pressure level": 0.08}), weak)
    assert not leaves_as_much(corr(**{"valve opening": 0.24}), strong)
    assert not leaves_as_much(corr(**{"pressure level": 0.3, "valve opening": 0.05}), weak)
    assert not leaves_as_much(corr(**{"valve opening": REMAINDER_FLOOR - 0.01}), finding("valve_leak", 0.1))
    # a robot whose clean chambers spread wider sets the floor higher (flexible.paying)
    assert not leaves_as_much(corr(**{"valve opening": 0.21}), weak, floor=0.4)


def test_what_a_chamber_leaves_is_no_other_law_when_its_twin_leaves_as_much():
    """A chamber whose correction gains 0.77 on the calibrated model's own twin (nothing
    missing: humanoid38's jaw.b, whose pressures the samples do not resolve) leaves 0.75 beside
    a true valve lag that took 0.99 of its held-out error: under the twin's floor, not another
    law's projection; the same remainder at a chamber whose twin gains nothing is."""
    from types import SimpleNamespace

    from identification.doctor.valve_arm.flex_check import leaves_as_much
    from identification.doctor.valve_arm.flexible import TWIN_MARGIN, Correction, twin_floor

    alone = {"valve opening": 0.75, "command history": 0.59}
    c = Correction({"actuator": "jaw", "chamber": "b"}, 0.75, alone, alone, np.zeros(1), np.zeros(1), [9])
    lag = SimpleNamespace(family="valve_lag", scored=SimpleNamespace(heldout_gain=0.994))
    robot_floor = 0.6
    assert twin_floor(c, {("jaw", "b"): 0.77}, robot_floor) == pytest.approx(0.77 + TWIN_MARGIN)
    assert not leaves_as_much(c, lag, twin_floor(c, {("jaw", "b"): 0.77}, robot_floor))
    assert leaves_as_much(c, lag, twin_floor(c, {("jaw", "b"): 0.05}, robot_floor))
    assert twin_floor(c, None, robot_floor) == robot_floor


@pytest.mark.slow
def test_a_backlash_beside_a_heat_transfer_is_not_taken_for_its_remainder(tmp_path):
    """A backlash at the elbow beside a heat transfer at elbow chamber b (random-form generator,
    seed 251294696 of fresh generalization run 19): with the heat transfer named, what chamber
    b's flexible correction still takes through the volume is that finding's remainder, not a
    sign that the backlash, acting on both of the elbow's chambers, is another law's projection.
    Both are named, each at its place."""
    from identification.doctor.valve_arm.diagnose import diagnose
    from scenarios._variantsim.cases import make_case

    truth = make_case(tmp_path, 251294696, ["backlash", "heat_transfer"], seconds=60.0, heldout_seconds=30.0,
                      name="pair")
    assert [e["where"] for e in truth["effects"]] == [{"joint": "elbow"}, {"actuator": "elbow", "chamber": "b"}]
    report = diagnose(load_robot("arm2"), [read_csv(tmp_path / "pair.csv")], [read_csv(tmp_path / "pair_heldout.csv")])
    named = sorted((f["effect"], tuple(f["where"].values())) for f in report["findings"])
    assert named == [("backlash", ("elbow",)), ("heat_transfer", ("elbow", "b"))]
