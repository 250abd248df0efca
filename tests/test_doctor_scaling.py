"""The doctor's work grows linearly with the places: hypotheses at disjoint chambers share their
probe replays, with the same scores as one at a time."""
import dataclasses
from pathlib import Path

import numpy as np

from identification.doctor.valve_arm.calibrate import pressure_sigma
from identification.doctor.valve_arm.data import prepare
from identification.doctor.valve_arm.hypotheses import pneumatic_hypotheses
from identification.doctor.valve_arm.joint_fit import folds_at_joint, two_fold_rss_at
from identification.doctor.valve_arm.pneumatic import Windows
from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
from identification.doctor.valve_arm.screening import probe_groups, score_pneumatic
from pneumatics.recording import read_csv
from pneumatics.robot import load_robot

SAMPLE = Path(__file__).resolve().parents[2] / "shared" / "samples" / "arm2-blind" / "case_2e0854bc.csv"


def test_grouped_scores_equal_one_at_a_time():
    robot = load_robot("arm2")
    exp = prepare(robot, read_csv(SAMPLE).slice(0, 20))
    win = Windows.tile(len(exp.t), 30)
    hyps = pneumatic_hypotheses(robot)
    args = (exp, win, PneumaticMods.nominal(4), hyps, pressure_sigma(exp))
    grouped, total_g = score_pneumatic(*args)
    alone, total_a = score_pneumatic(*args, grouped=False)
    assert total_g == total_a
    assert max(s.predicted_gain for s in alone) > 0.5  # the sample's hysteresis shows
    assert np.allclose([s.predicted_gain for s in grouped], [s.predicted_gain for s in alone], rtol=0, atol=1e-12)


def test_groups_are_disjoint_and_few_on_the_humanoid():
    robot = load_robot("humanoid38")
    hyps = pneumatic_hypotheses(robot)
    groups = probe_groups(hyps, robot.tables.n_chambers)
    assert sorted(id(h) for g in groups for h in g) == sorted(id(h) for h in hyps)
    for g in groups:
        chambers = [c for h in g for c in h.chambers]
        assert len(chambers) == len(set(chambers)) or len(g) == 1
        assert len({(h.family, tuple(p[0] for p in h.params)) for h in g}) == 1
    # one group per family and form (the score test's cost), against ~1100 hypotheses
    forms = {(h.family, tuple(p[0] for p in h.params)) for h in hyps}
    assert len(hyps) > 1000 and len(groups) == len(forms) < 25


def test_effect_fits_at_one_joint_equal_the_whole_fit():
    from identification.doctor.valve_arm.hypotheses import mechanical_hypotheses
    from identification.doctor.valve_arm.joint_fit import coupled_joints, fit_at_joints, fit_effect
    from identification.doctor.valve_arm.mechanics import fit_rigid_body
    from identification.doctor.valve_arm.torque_balance import torque_data
    from identification.doctor.valve_arm.screening import stack_terms, torque_rms
    from identification.doctor.valve_arm.torque_judge import crossval_torque
    from identification.doctor.valve_arm.screening import Scored

    robot = load_robot("arm2")
    exp = prepare(robot, read_csv(SAMPLE).slice(0, 30))
    td = torque_data(exp)
    base = fit_rigid_body(td)
    hyps = mechanical_hypotheses(robot, exp, td)
    confined, shared = 0, {}
    for h in hyps:
        extra, names, bounds = stack_terms(None, h.regressor(exp, td), h)
        whole, local = fit_rigid_body(td, extra, names, bounds), fit_effect(td, extra, names, bounds, base, 0)
        confined += coupled_joints(extra, td.valid, 0).size == 1
        # the rows and factors an earlier effect left for its joints (joint_fit.JointBlock)
        again = fit_effect(td, extra, names, bounds, base, 0, shared=shared)
        np.testing.assert_allclose(again.values, local.values, rtol=0, atol=1e-12)
        np.testing.assert_allclose(again.stderr, local.stderr, rtol=1e-12)
        assert again.rss == local.rss
        assert np.allclose(whole.values, local.values, rtol=0, atol=1e-9), h.label
        # the same split over a set of joints (on arm2 the set of both is the whole fit)
        both = fit_at_joints(td, extra, names, bounds, base, np.arange(2))
        assert np.allclose(whole.values, both.values, rtol=0, atol=1e-9)
        assert abs(whole.rss - both.rss) <= 1e-9 * whole.rss
        assert abs(whole.rss - local.rss) <= 1e-9 * whole.rss
        bare = fit_effect(td, extra, names, bounds, base, 0, stderr=False)  # a cross-validation's fit
        if coupled_joints(extra, td.valid, 0).size == 1:
            assert np.array_equal(bare.values, local.values) and bare.rss == local.rss
            assert np.all(np.isnan(bare.stderr[-len(h.params):]))
        k = len(h.params)
        # 1e-7: a warm-up drift of 3 s is nearly collinear with the constant offset beside it
        # (1 - exp(-t/3) is 1 after the first seconds), which costs the errors two digits
        assert np.allclose(whole.stderr[-k:], local.stderr[-k:], rtol=1e-7), h.label
        # the two-fold cross-validation with shared folds, against the whole fits fold by fold
        s, block = Scored(h, 0.0), 10
        crossval_torque(s, exp, td, None, block, {})
        before = after = 0.0
        for fit_on, test_on in td.two_fold():
            b = fit_rigid_body(fit_on)
            before = before + torque_rms(test_on, b, None, block) ** 2
            after = after + torque_rms(test_on, fit_rigid_body(fit_on, extra, names, bounds), extra, block) ** 2
        assert np.allclose(s.heldout_after, np.sqrt(after / 2), rtol=1e-9) and np.allclose(s.heldout_before, np.sqrt(before / 2))
    assert confined >= len(hyps) // 2  # most act at one joint: the split is what is being tested
    # the screen takes the hypotheses joint by joint and returns them in their own order
    from identification.doctor.valve_arm.screening import score_mechanical
    scored, _ = score_mechanical(td, exp, hyps)
    assert [s.hyp for s in scored] == hyps
    for s in scored[::7]:
        extra, names, bounds = stack_terms(None, s.hyp.regressor(exp, td), s.hyp)
        np.testing.assert_allclose(s.fit.values, fit_effect(td, extra, names, bounds, base, 0).values, rtol=0, atol=1e-12)


def test_the_rigid_body_fit_equals_its_reference_with_every_column():
    """fit_rigid_body takes the held inertias' torque without copying their regressors: the
    same values, errors, RSS and residual as the reference that fits one matrix of every
    column, with no effect and with each mechanical hypothesis's terms."""
    from identification.doctor.valve_arm.hypotheses import mechanical_hypotheses
    from identification.doctor.valve_arm.mechanics import fit_rigid_body, fit_rigid_body_reference, hold_nominal
    from identification.doctor.valve_arm.torque_balance import torque_data
    from identification.doctor.valve_arm.screening import stack_terms

    robot = load_robot("arm2")
    exp = prepare(robot, read_csv(SAMPLE).slice(0, 30))
    td = torque_data(exp)
    cases = [(None, (), None)] + [stack_terms(None, h.regressor(exp, td), h)
                                  for h in mechanical_hypotheses(robot, exp, td)[::5]]
    nominal = dataclasses.replace(td)
    hold_nominal(nominal, "held for the test")  # every column held: no free one without an effect
    for data, (extra, names, bounds) in [(td, c) for c in cases] + [(nominal, c) for c in cases[:2]]:
        fast, ref = fit_rigid_body(data, extra, names, bounds), fit_rigid_body_reference(data, extra, names, bounds)
        assert fast.names == ref.names and fast.at_bound == ref.at_bound
        np.testing.assert_allclose(fast.values, ref.values, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(fast.stderr, ref.stderr, rtol=1e-7)  # NaN where held, in both
        np.testing.assert_allclose(fast.residual, ref.residual, rtol=0, atol=1e-9 * np.abs(ref.residual).max())
        assert abs(fast.rss - ref.rss) <= 1e-9 * ref.rss and fast.n == ref.n


def test_the_unidentified_parameters_from_the_triangular_factor_are_those_from_every_row():
    """The calibration's choice of parameters held nominal (dependent columns, then the worst
    standard error one at a time) made on the scaled rows' QR factor equals the choice made on
    the rows: on arm2's sample, and on it with a column made a copy of another and a column
    too small to identify, so both kinds of choice are made."""
    from identification.doctor.valve_arm.mechanics import _scaled, _unidentified, unidentified_columns
    from identification.doctor.valve_arm.torque_balance import torque_data

    robot = load_robot("arm2")
    td = torque_data(prepare(robot, read_csv(SAMPLE).slice(0, 30)))
    A2, y2, _ = _scaled(td.decimate(td.regressors), td.decimate(td.residual))
    names, lo, hi = list(td.names), td.lower, td.upper
    rng = np.random.default_rng(3)
    doubled = A2.copy()
    doubled[:, 1] = 2.0 * doubled[:, 0]                          # moves exactly with the first column
    doubled[:, 2] *= 1e-4                                        # its standard error over ESSENTIAL_SE
    noisy = y2 + 0.01 * rng.normal(size=y2.size)
    for A, y in ((A2, y2), (doubled, noisy)):
        fast, ref = _unidentified(A, y, names, lo, hi), unidentified_columns(A, y, names, lo, hi)
        assert fast == ref
    assert names[1] in fast and "moves exactly with" in fast[names[1]]
    assert "not identifiable" in fast[names[2]]


def test_a_kept_terms_rounding_at_another_joint_neither_couples_nor_moves_it():
    """A kept term acting at the shoulder that leaves rounding (1e-12 of its size) at the elbow,
    and an effect at the elbow: the elbow alone is refitted, the kept term keeps its value (a
    refit from its rounding alone would make it anything), as the whole fit has it."""
    from identification.doctor.valve_arm.hypotheses import mechanical_hypotheses
    from identification.doctor.valve_arm.joint_fit import coupled_joints, fit_effect
    from identification.doctor.valve_arm.mechanics import fit_rigid_body
    from identification.doctor.valve_arm.torque_balance import torque_data
    from identification.doctor.valve_arm.screening import stack_terms

    robot = load_robot("arm2")
    exp = prepare(robot, read_csv(SAMPLE).slice(0, 30))
    td = torque_data(exp)
    fit_rigid_body(td)
    hyps = {h.label + str(len(h.params)): h for h in mechanical_hypotheses(robot)}
    kept_h, effect_h = hyps["pressure_sensor_offset@shoulder.a1"], hyps["viscous_friction@elbow1"]
    kept = kept_h.regressor(exp, td).copy()
    kept[:, 1, 0] = 1e-12 * np.abs(kept[:, 0, 0]).max() * np.sin(np.arange(kept.shape[0]))
    base_extra = stack_terms(None, kept, kept_h)
    base = fit_rigid_body(td, *base_extra)
    extra, names, bounds = stack_terms(base_extra, effect_h.regressor(exp, td), effect_h)
    assert coupled_joints(extra, td.valid, 1).tolist() == [1]
    whole, local = fit_rigid_body(td, extra, names, bounds), fit_effect(td, extra, names, bounds, base, 1)
    assert np.allclose(whole.values, local.values, rtol=1e-6, atol=1e-9)
    assert abs(whole.rss - local.rss) <= 1e-8 * whole.rss


def test_coupled_joints_follow_the_kept_terms():
    from identification.doctor.valve_arm.joint_fit import coupled_joints

    extra = np.zeros((5, 4, 3))
    valid = np.ones(5, bool)
    extra[:, 1:3, 0] = 1.0    # a kept term acting at joints 1 and 2 (an angle offset's gravity torque)
    extra[:, 3, 1] = 1.0      # a kept term at joint 3 alone
    extra[:, 2, 2] = 1.0      # the effect, at joint 2
    assert coupled_joints(extra, valid, 2).tolist() == [1, 2]
    extra[:, :, 2] = 0.0      # an effect the data never reach changes joint 0's fit alone
    assert coupled_joints(extra, valid, 2).tolist() == [0]
    extra[:, 3, 2] = 1.0
    assert coupled_joints(extra, valid, 2).tolist() == [3]


def test_end_stop_grid_two_fold_rss_equals_whole_fits():
    from identification.doctor.valve_arm import profiled as H
    from identification.doctor.valve_arm.mechanics import fit_rigid_body
    from identification.doctor.valve_arm.torque_balance import torque_data

    robot = load_robot("arm2")
    exp = prepare(robot, read_csv(SAMPLE).slice(0, 30))
    td = torque_data(exp)
    fit_rigid_body(td)
    folds = H.stop_folds(td)
    for j in range(2):
        at_j = folds_at_joint(td, j, folds)
        for stop in (-0.4, 0.0, 0.4):
            reg = td.mask(H.stop_regressors(exp, j, stop, 1))
            whole = 0.0
            for fit_on, test_on in td.two_fold():
                f = fit_rigid_body(fit_on, reg, ["k", "b"], (np.zeros(2), np.full(2, np.inf)))
                A = np.concatenate([td.regressors[test_on.valid], reg[test_on.valid]], axis=2)
                whole += float(np.sum((td.residual[test_on.valid] - np.einsum("njp,p->nj", A, f.values)) ** 2))
            assert abs(two_fold_rss_at(j, reg, H.STOP_BOUNDS, at_j, td.valid) - whole) <= 1e-8 * whole


def test_a_stop_one_folds_blocks_never_touch_leaves_that_fold_at_the_base():
    """A bumper pressed only inside the second fold's 2 s blocks: the first fold cannot fit it
    (least squares would leave k and b at a start of its own choosing), so that fold's test
    residual is the base fit's; the other fold's is the fit's as usual."""
    from identification.doctor.valve_arm import profiled as H
    from identification.doctor.valve_arm.mechanics import fit_rigid_body
    from identification.doctor.valve_arm.torque_balance import torque_data

    robot = load_robot("arm2")
    exp = prepare(robot, read_csv(SAMPLE).slice(0, 30))
    td = torque_data(exp)
    fit_rigid_body(td)
    folds = H.stop_folds(td)
    first, _ = td.two_fold()[0]
    reg = td.mask(H.stop_regressors(exp, 0, 0.0, 1))
    reg[first.valid] = 0.0          # contact only in the second fold's blocks
    rss = two_fold_rss_at(0, reg, H.STOP_BOUNDS, folds_at_joint(td, 0, folds), td.valid)
    (_, _, _, base_res_first_test), (fit_on, test_on, _, _) = folds
    f = fit_rigid_body(fit_on, reg, ["k", "b"], (np.zeros(2), np.full(2, np.inf)))
    A = np.concatenate([td.regressors[test_on.valid], reg[test_on.valid]], axis=2)
    expected = float(np.sum(base_res_first_test ** 2)) + float(
        np.sum((td.residual[test_on.valid] - np.einsum("njp,p->nj", A, f.values)) ** 2))
    assert abs(rss - expected) <= 1e-8 * expected


def _scored_at(joint: int, gain: float, family: str = "angle_sensor_offset", form: str = "offset_and_scale"):
    from identification.doctor.valve_arm.hypotheses import Hypothesis
    from identification.doctor.valve_arm.screening import Scored

    h = Hypothesis(family, {"joint": f"j{joint}"}, "mechanical", [("offset_rad", 0.0, -0.2, 0.2, 0.0)],
                   joint=joint, form=form)
    before = np.ones(38)
    after = before.copy()
    after[joint] = np.sqrt(1.0 - gain)
    return Scored(h, 0.0, heldout_before=before, heldout_after=after)


def test_a_torque_balance_finding_must_stand_out_of_its_family_at_the_other_joints():
    """38 joints of a clean humanoid spread an angle offset-with-gain's held-out gains widely
    (humanoid38 --fast seed 703: median -0.07, up to 0.52 at a shoulder pitch): none of them
    stands out.  A true effect lifts its own joint above the
    spread, and another family's candidates are judged against their own family.  With
    arm2's two joints there is no spread to estimate: every candidate goes on to the keep rule."""
    from identification.doctor.valve_arm.search import standing_out

    rng = np.random.default_rng(3)
    clean = np.concatenate([rng.normal(-0.07, 0.25, 36), [0.43, 0.52]])
    kept = {s.hyp.joint for s in standing_out([_scored_at(j, g) for j, g in enumerate(clean)])}
    assert not {36, 37} & kept
    lifted = np.where(np.arange(38) == 20, 0.7, rng.normal(0.0, 0.05, 38))
    damped = np.where(np.arange(38) == 5, 0.3, rng.normal(0.0, 0.01, 38))
    friction = [_scored_at(j, g, "viscous_friction", "") for j, g in enumerate(damped)]
    kept = standing_out([_scored_at(j, g) for j, g in enumerate(lifted)] + friction)
    assert [s.hyp.joint for s in kept if s.hyp.family == "angle_sensor_offset"] == [20]
    assert [s.hyp.joint for s in kept if s.hyp.family == "viscous_friction"] == [5]
    arm2 = [_scored_at(0, 0.05), _scored_at(1, 0.3)]
    assert standing_out(arm2) == arm2


def test_a_cylinder_replayed_alone_equals_its_columns_of_the_whole_replay():
    """pneumatic.replay(chambers=...): a cylinder's chambers stepped alone give the same numbers
    as in the replay of all four, with a piston leak pairing them, a heat-transfer chamber, a
    valve leak and a sensor offset elsewhere; a supply that droops with the summed flow joins
    every chamber, and the replay refuses to split it."""
    import pytest

    from identification.doctor.valve_arm.pneumatic import cylinder_chambers, replay
    from identification.doctor.valve_arm.screening import chamber_rms

    robot = load_robot("arm2")
    exp = prepare(robot, read_csv(SAMPLE).slice(0, 8))
    win = Windows.tile(len(exp.t), 30)
    mods = PneumaticMods.nominal(4).copy(
        piston_leak_m2=np.array([0.0, 2e-8]), valve_leak_m2=np.array([1e-8, 0.0, 0.0, 3e-8]),
        heat_w_k=np.array([np.nan, np.nan, 0.05, np.nan]), sensor_offset_pa=np.array([0.0, 2e3, -1e3, 0.0]),
        dead_volume_scale=np.array([1.0, 1.1, 0.9, 1.2]))
    whole, meas = replay(exp, win, mods)
    for cylinder in ([0, 1], [2, 3]):
        alone, meas_alone = replay(exp, win, mods, cylinder_chambers([cylinder[1]]))
        assert np.array_equal(alone, whole[..., cylinder]) and np.array_equal(meas_alone, meas[..., cylinder])
    rms = chamber_rms(exp, win, mods)
    others = np.full(4, -1.0)
    part = chamber_rms(exp, win, mods, np.array([2, 3]), others)
    assert np.array_equal(part[2:], rms[2:]) and np.array_equal(part[:2], others[:2])
    with pytest.raises(ValueError, match="replay them all"):
        replay(exp, win, mods.copy(supply_droop_pa_per_kg_s=1e7, supply_droop_tau_s=0.1), np.array([0, 1]))
