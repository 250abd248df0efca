"""Torque data of a pressure-corrected recording derived from the first (torque_balance.with_pressures):
the same as made afresh, since the force law is linear in the pressures and nothing else depends
on them; a different motion is refused."""
import dataclasses

import numpy as np
import pytest


@pytest.fixture(scope="module")
def arm2_exp():
    from identification.doctor.valve_arm.data import prepare
    from pneumatics.effects.effect_set import EffectSet
    from pneumatics.robot import load_robot
    from scenarios._cases import _record

    robot = load_robot("arm2")
    recs = _record(robot, EffectSet(pressure_offset_pa={"elbow.a": 5000.0}), 5, 10.0, 5.0)
    return prepare(robot, recs["main"])


def test_corrected_pressures_give_the_torque_data_made_afresh(arm2_exp):
    from identification.doctor.valve_arm.torque_balance import torque_data, with_pressures
    from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
    from identification.doctor.valve_arm.sensor_offsets import apply_offset, corrected

    exp = arm2_exp
    C = exp.robot.tables.n_chambers
    mods = apply_offset(PneumaticMods.nominal(C), 2, 5000.0, C, drift_pa=800.0, time_constant_s=20.0)
    exp_c = corrected(exp, mods)
    fresh = torque_data(exp_c, held_nominal="held by the test")
    derived = with_pressures(torque_data(exp), exp, exp_c, held_nominal="held by the test")
    assert derived is not None and derived.held_nominal == fresh.held_nominal
    assert not np.allclose(derived.tau_act, torque_data(exp).tau_act)       # the correction moved them
    for f in dataclasses.fields(fresh):
        a, b = getattr(fresh, f.name), getattr(derived, f.name)
        if isinstance(a, np.ndarray):
            np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-9, err_msg=f.name)
        elif f.name != "_reach":
            assert a == b, f.name


def test_another_motion_or_a_calibrated_copy_is_made_afresh(arm2_exp):
    from identification.doctor.valve_arm.mechanics import calibrate_rigid_body
    from identification.doctor.valve_arm.torque_balance import torque_data, with_pressures

    exp = arm2_exp
    td = torque_data(exp)
    moved = dataclasses.replace(exp, q_s=exp.q_s + 0.01)
    assert with_pressures(td, exp, moved) is None
    calibrate_rigid_body(td)
    assert with_pressures(td, exp, exp) is None
