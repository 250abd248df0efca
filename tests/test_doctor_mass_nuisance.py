"""A constant force fitted beside its joint's subtree masses (identification/doctor/valve_arm/
mass_nuisance.py): partialling the nuisance out gives the joint fit's value and cluster-robust
error (Frisch-Waugh-Lovell), a force error the mass explains loses its significance, and one it
does not explain keeps it."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from identification.doctor.valve_arm.mass_nuisance import partialled, subtree_bodies, with_subtree_masses
from identification.doctor.valve_arm.output_error_fit import gauss_newton_step
from identification.doctor.valve_arm.output_error_screen import joint_data
from identification.doctor.valve_arm.replay import MechMods


def _windows(rng, W=120, H=20):
    """A gravity-like nuisance (a level per window, slowly varying) and a constant force's
    sensitivity that resembles it (the replays' answer to both grows over a window)."""
    t = np.linspace(0, 1, H)[None]
    level = 1.0 + 0.3 * rng.normal(size=(W, 1))
    nuisance = level * t
    force = (1.0 + 0.05 * rng.normal(size=(W, 1))) * t + 0.02 * rng.normal(size=(W, H))
    return force, nuisance, rng.normal(0, 0.05, (W, 1)) * t + rng.normal(0, 0.01, (W, H))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2 ** 31), theta=st.floats(-2, 2), mass=st.floats(-2, 2))
def test_partialling_out_gives_the_joint_fits_value_and_error(seed, theta, mass):
    rng = np.random.default_rng(seed)
    force, nuisance, noise = _windows(rng)
    r = theta * force + mass * nuisance + noise
    joint = gauss_newton_step(np.stack([force, nuisance], axis=-1), r)
    a, rr = partialled(force, nuisance, r)
    alone = gauss_newton_step(a[..., None], rr)
    assert alone[0][0] == pytest.approx(joint[0][0], rel=1e-9, abs=1e-12)
    assert alone[1][0] == pytest.approx(joint[1][0], rel=1e-9, abs=1e-12)
    # a fit of k parameters: each column partialled on its own, the residual once
    cols, r2 = partialled(np.stack([force, 2.0 * force + nuisance], axis=-1), nuisance, r)
    np.testing.assert_allclose(cols[..., 0], a, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(cols[..., 1], partialled(2.0 * force + nuisance, nuisance, r)[0], rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(r2, rr)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2 ** 31), theta=st.floats(-2, 2), m1=st.floats(-2, 2), m2=st.floats(-2, 2))
def test_several_bodies_partialled_at_once_give_the_joint_fits_value_and_error(seed, theta, m1, m2):
    """Each body of a subtree its own nuisance (mass_nuisance.body_sensitivities): two bodies
    whose masses are off by different shares, partialled out together, give the joint fit's
    value and error, and the offset left beside them."""
    rng = np.random.default_rng(seed)
    force, nuisance, noise = _windows(rng)
    other = nuisance * np.linspace(0.5, 1.5, force.shape[1])[None] + 0.01 * rng.normal(size=force.shape)
    r = theta * force + m1 * nuisance + m2 * other + noise
    joint = gauss_newton_step(np.stack([force, nuisance, other], axis=-1), r)
    a, rr = partialled(force, np.stack([nuisance, other], axis=-1), r)
    alone = gauss_newton_step(a[..., None], rr)
    assert alone[0][0] == pytest.approx(joint[0][0], rel=1e-8, abs=1e-10)
    assert alone[1][0] == pytest.approx(joint[1][0], rel=1e-8, abs=1e-10)


def test_a_force_error_the_mass_explains_loses_its_significance_and_a_true_one_keeps_it():
    rng = np.random.default_rng(3)
    force, nuisance, noise = _windows(rng)
    from_mass = 0.5 * nuisance + noise          # the body's mass error, no offset
    naive = gauss_newton_step(force[..., None], from_mass)
    beside = gauss_newton_step(*_as_fit(joint_data(force, from_mass, nuisance)))
    assert abs(naive[0][0] / naive[1][0]) > 8          # alone, a "significant" offset ...
    assert abs(beside[0][0] / beside[1][0]) < 4        # ... which the mass beside it takes up
    true = 0.5 * force + 0.1 * nuisance + noise
    beside = gauss_newton_step(*_as_fit(joint_data(force, true, nuisance)))
    assert beside[0][0] == pytest.approx(0.5, rel=0.2) and abs(beside[0][0] / beside[1][0]) > 8


def _as_fit(data):
    s, r = data
    return s[..., None], r


def test_windows_with_a_missing_replay_are_left_out_and_a_silent_nuisance_changes_nothing():
    rng = np.random.default_rng(4)
    force, nuisance, noise = _windows(rng)
    r = force * 0.3 + noise
    nuisance[5, 3] = np.nan
    s, rr = joint_data(force, r, nuisance)
    assert s.shape == (force.shape[0] - 1, force.shape[1]) and np.all(np.isfinite(s))
    s0, r0 = joint_data(force, r, np.zeros_like(force))
    assert np.array_equal(s0, force) and np.array_equal(r0, r)


def test_a_joints_subtree_is_the_bodies_it_moves():
    from pneumatics.robot import load_robot

    robot = load_robot("arm2")
    m = robot.model
    shoulder, elbow = (subtree_bodies(m, n) for n in robot.joint_names)
    assert set(elbow) < set(shoulder) and elbow
    assert all(m.body_mass[m.body(b).id] > 0 for b in shoulder)
    mm = with_subtree_masses(MechMods(), m, robot.joint_names, [1], 0.03)
    assert mm.mass_scale == {b: 0.03 for b in elbow} and MechMods().mass_scale == {}


def test_the_bodies_sensitivities_add_up_to_the_subtrees():
    """Small mass changes superpose: the replayed angle's answer to each body of the elbow's
    subtree, summed, is its answer to the whole subtree's (mass_sensitivity)."""
    from types import SimpleNamespace

    from controllers.pid import ARM2_PIDF
    from controllers.reference import hand_moved
    from identification.doctor.valve_arm.angle_replay import pressure_driven_angles
    from identification.doctor.valve_arm.data import prepare
    from identification.doctor.valve_arm.mass_nuisance import body_sensitivities, mass_sensitivity
    from identification.doctor.valve_arm.output_error_fit import window_rows
    from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
    from pneumatics.robot import load_robot
    from pneumatics.runner import run
    from pneumatics.sim import Simulation

    robot = load_robot("arm2")
    ref = hand_moved(robot.joint_names, robot.joint_range(), 6.0, seed=5)
    sim = Simulation(robot)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=4.5e5)
    exp = prepare(robot, run(sim, ARM2_PIDF.build(ref, robot.tables.valve[:, 0]), 6.0, seed=5))
    doctor = SimpleNamespace(robot=robot, mods=PneumaticMods.nominal(robot.tables.n_chambers))
    rows, j = window_rows(exp, 1), 0
    base = pressure_driven_angles(exp, doctor.mods, MechMods())[rows]
    each = body_sensitivities(exp, doctor, MechMods(), base, j, 1, rows)
    whole = mass_sensitivity(exp, doctor, MechMods(), base, [j], 1, rows)[..., j]
    assert each.shape == (*rows.shape, len(subtree_bodies(robot.model, robot.joint_names[j])))
    # measured 2.0 %: the 3 % probes answer nearly, not exactly, linearly
    assert np.linalg.norm(each.sum(axis=-1) - whole) < 0.05 * np.linalg.norm(whole)


def test_a_large_subtree_is_grouped_with_its_first_bodies_alone():
    """humanoid38's waist_yaw moves 25 bodies: the candidate's nuisances are its first three
    bodies down the tree alone and the rest as one (mass_nuisance.body_groups); an ankle's three
    bodies stay apart."""
    from identification.doctor.valve_arm.mass_nuisance import MAX_BODY_GROUPS, body_groups
    from pneumatics.robot import load_robot

    m = load_robot("humanoid38").model
    waist = body_groups(m, "waist_yaw")
    assert len(waist) == MAX_BODY_GROUPS and all(len(g) == 1 for g in waist[:-1])
    assert sum(waist, []) == subtree_bodies(m, "waist_yaw") and len(waist[-1]) > 10
    assert waist[0] == [m.body(int(m.joint("waist_yaw").bodyid[0])).name]
    assert body_groups(m, "left_ankle_pitch") == [[b] for b in subtree_bodies(m, "left_ankle_pitch")]


def test_no_windows_left_partial_nothing_and_fit_nothing():
    """A joint whose replays left no window (all NaN: its family not screened there, every
    replay failed) is partialled as it is and gives no fit, not an error (a fresh humanoid38
    case with a supply droop stopped the doctor at the screen, 2026-12-07)."""
    empty = np.zeros((0, 20))
    for nuisance in (empty, np.zeros((0, 20, 3))):
        a, r = partialled(empty, nuisance, empty)
        assert a.shape == r.shape == (0, 20)
    nan = np.full((30, 20), np.nan)
    s, r = joint_data(nan, nan, nan)
    assert s.shape[0] == r.shape[0] == 0
    assert gauss_newton_step(s[:, :, None], r) is None
