"""The supply flow at the measured pressures kept per chamber (supply_shares.SupplyShares)
against its whole recomputation (receiver.measured_supply_flow_reference): whatever sequence of
changes to the chamber model, the commands or the supply pressure, the kept sum is the
recomputed one."""
from __future__ import annotations

import functools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st


@functools.lru_cache(maxsize=1)
def _experiment():
    """A prepared 6 s recording of arm2 (4 chambers) under its PIDF."""
    from identification.doctor.valve_arm.data import prepare
    from pneumatics.effects.effect_set import EffectSet
    from pneumatics.robot import load_robot
    from scenarios._cases import _record

    robot = load_robot("arm2")
    return prepare(robot, _record(robot, EffectSet(), 5, 6.0, 2.0)["main"])


#: (field, change) of one step: a per-chamber field scaled or set at one chamber, the shared
#: leak width, one chamber's commands shifted, or the supply pressure
_FIELDS = ("supply_scale", "exhaust_scale", "dead_volume_scale", "valve_leak_m2", "valve_leak_exhaust_m2",
           "valve_underlap_m2", "sensor_offset_pa", "sensor_drift_pa", "valve_leak_width_v", "u", "supply_pa")
_steps = st.lists(st.tuples(st.sampled_from(_FIELDS), st.integers(0, 3), st.floats(-1.0, 1.0)), min_size=1, max_size=6)


def _changed(mods, u, supply_pa, field, c, x):
    """(mods, u, supply_pa) after one step."""
    n = mods.supply_scale.size
    if field == "u":
        u = u.copy()
        u[:, c] += 0.3 * x
    elif field == "supply_pa":
        supply_pa = supply_pa * (1.0 + 0.05 * x)
    elif field == "valve_leak_width_v":
        mods = mods.copy(valve_leak_width_v=mods.valve_leak_width_v * (1.0 + 0.5 * x))
    else:
        scale = {"sensor_offset_pa": 3e3, "sensor_drift_pa": 3e3, "valve_leak_m2": 2e-8,
                 "valve_leak_exhaust_m2": 2e-8, "valve_underlap_m2": 2e-8}.get(field)
        v = getattr(mods, field)
        v = (np.zeros(n) if scale else np.ones(n)) if v is None else np.array(v, float)
        v[c] = scale * x if scale else v[c] * (1.0 + 0.1 * x)
        extra = {"sensor_drift_tau_s": np.full(n, 20.0)} if field == "sensor_drift_pa" else {}
        mods = mods.copy(**{field: v}, **extra)
    return mods, u, supply_pa


@settings(max_examples=25, deadline=None)
@given(_steps)
def test_the_kept_shares_sum_to_the_recomputed_supply_flow(steps):
    from identification.doctor.valve_arm.pneumatic import ChamberModel, effective_commands
    from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
    from identification.doctor.valve_arm.receiver import measured_supply_flow_reference
    from identification.doctor.valve_arm.supply_shares import SupplyShares

    exp = _experiment()
    mods = PneumaticMods.nominal(exp.robot.tables.n_chambers)
    u, supply_pa = effective_commands(exp, mods), float(exp.robot.tables.supply_pa)
    shares = SupplyShares()
    for field, c, x in [("supply_scale", 0, 0.0), *steps]:
        mods, u, supply_pa = _changed(mods, u, supply_pa, field, c, x)
        model = ChamberModel(exp.robot, mods, 1)
        kept = shares.total(exp, model, u, supply_pa)
        whole = measured_supply_flow_reference(exp, model, u, supply_pa)
        np.testing.assert_allclose(kept, whole, rtol=1e-12, atol=1e-18)
        assert np.all(kept >= 0) and np.any(kept > 0)


def test_a_change_at_one_chamber_recomputes_that_chamber_alone(monkeypatch):
    from identification.doctor.valve_arm import supply_shares
    from identification.doctor.valve_arm.pneumatic import ChamberModel, effective_commands
    from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods

    exp = _experiment()
    mods = PneumaticMods.nominal(exp.robot.tables.n_chambers)
    u, supply_pa = effective_commands(exp, mods), float(exp.robot.tables.supply_pa)
    asked = []
    real = supply_shares.chamber_supply_flows
    monkeypatch.setattr(supply_shares, "chamber_supply_flows", lambda *a: asked.append(list(a[-1])) or real(*a))
    shares = supply_shares.SupplyShares()
    shares.total(exp, ChamberModel(exp.robot, mods, 1), u, supply_pa)
    scale = mods.supply_scale.copy()
    scale[2] *= 1.01
    shares.total(exp, ChamberModel(exp.robot, mods.copy(supply_scale=scale), 1), u, supply_pa)
    # the exhaust side and the volumes do not draw from the supply: nothing to recompute
    shares.total(exp, ChamberModel(exp.robot, mods.copy(supply_scale=scale, exhaust_scale=scale), 1), u, supply_pa)
    assert asked == [[0, 1, 2, 3], [2]]


def test_under_a_held_receiver_path_a_cylinder_replays_alone_as_in_the_whole_replay():
    """A compressor's receiver whose path the model holds gives every window its supply
    pressure whatever the chambers draw: a cylinder's chambers replayed alone are the whole
    replay's columns, and so a candidate refits its own cylinders only.  Without the path held
    (the receiver integrated from every chamber's flow) the replay refuses to split."""
    import pytest

    from identification.doctor.valve_arm.pneumatic import Windows, chambers_independent, replay
    from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
    from identification.doctor.valve_arm.receiver import experiment_key
    from identification.doctor.valve_arm.screening import own_cylinders
    from identification.doctor.valve_arm.hypotheses import pneumatic_hypotheses

    exp = _experiment()
    C = exp.robot.tables.n_chambers
    receiver = dict(supply_receiver_m3=1e-3, supply_compressor_kg_s=4e-4, supply_band_pa=3e4,
                    supply_cut_out_pa=float(exp.robot.tables.supply_pa), supply_leak_kg_s_pa=3e-11)
    path = float(exp.robot.tables.supply_pa) - 2e4 * (1.0 + np.sin(2 * np.pi * exp.fine_t / 3.0))
    held = PneumaticMods.nominal(C).copy(**receiver, receiver_paths={experiment_key(exp): path})
    unheld = PneumaticMods.nominal(C).copy(**receiver)
    assert chambers_independent(held, (exp,)) and not chambers_independent(unheld, (exp,))
    assert not chambers_independent(held, ())  # no experiment named: no path known to be held
    win = Windows(np.arange(10, 500, 30), 30)
    whole, _ = replay(exp, win, held)
    alone, _ = replay(exp, win, held, np.array([2, 3]))
    np.testing.assert_array_equal(alone, whole[..., 2:4])
    assert not np.allclose(whole, replay(exp, win, PneumaticMods.nominal(C))[0])  # the path moved the supply
    with pytest.raises(ValueError):
        replay(exp, win, unheld, np.array([2, 3]))
    leak = next(h for h in pneumatic_hypotheses(exp.robot) if h.label == "valve_leak@elbow.a")
    assert list(own_cylinders(leak, held, C, (exp,))) == [2, 3]
    assert own_cylinders(leak, unheld, C, (exp,)) is None
