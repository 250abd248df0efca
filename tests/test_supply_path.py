"""A shared supply's pressure held on its path (identification/doctor/valve_arm/supply_path.py):
the replays it gives against the supply's own laws, and a candidate fitted at its own cylinder
under a drooping supply against the same fit with every chamber replayed and refitted."""
from __future__ import annotations

import functools

import numpy as np
import pytest

DROOP_PA_PER_KG_S = 8e7   # the supply_droop family's draw on arm2 (about 9 kPa at its mean draw)
LEAK_M2 = 4e-8


@functools.lru_cache(maxsize=1)
def _experiments():
    """(fitted, held-out) prepared recordings of arm2 (20 s + 8 s) with a drooping supply and a
    valve leak at elbow.a."""
    from identification.doctor.valve_arm.data import prepare
    from pneumatics.effects.effect_set import EffectSet
    from pneumatics.robot import load_robot
    from scenarios._cases import _record

    robot = load_robot("arm2")
    effects = EffectSet(supply_droop_pa_per_kg_s=DROOP_PA_PER_KG_S, valve_leak_m2={"elbow.a": LEAK_M2})
    recs = _record(robot, effects, 7, 20.0, 8.0)
    return prepare(robot, recs["main"]), prepare(robot, recs["heldout"])


def _droop_mods(C):
    from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods

    return PneumaticMods.nominal(C).copy(supply_droop_pa_per_kg_s=DROOP_PA_PER_KG_S)


@pytest.mark.parametrize("tau_s", [0.0, 0.3])
def test_the_held_path_replays_the_chambers_as_the_drooping_supply_does(tau_s):
    """Held on its path at the measured pressures, the supply gives the replays what its law
    gives them within a small part of what the droop itself does, and the chambers replay
    alone as they do together."""
    from identification.doctor.valve_arm.pneumatic import Windows, chambers_independent, replay
    from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
    from identification.doctor.valve_arm.supply_path import SUPPLY_FIELDS, supply_path, with_held_supply, with_supply_of

    exp, _ = _experiments()
    C = exp.robot.tables.n_chambers
    droop = _droop_mods(C).copy(supply_droop_tau_s=tau_s)
    held = with_held_supply(droop, (exp,))
    assert chambers_independent(held, (exp,)) and not chambers_independent(droop, (exp,))
    path = supply_path(exp, droop)
    supply = float(exp.robot.tables.supply_pa)
    assert path.shape == exp.fine_t.shape and np.all(path < supply) and np.all(np.isfinite(path))
    assert 2e3 < np.mean(supply - path) < 3e4           # about 9 kPa at the arm's mean draw
    win = Windows(np.arange(10, 1800, 40), 40)
    by_law, _ = replay(exp, win, droop)
    by_path, _ = replay(exp, win, held)
    without, _ = replay(exp, win, PneumaticMods.nominal(C))
    assert np.sqrt(np.mean((by_path - by_law) ** 2)) < 0.05 * np.sqrt(np.mean((without - by_law) ** 2))
    np.testing.assert_array_equal(replay(exp, win, held, np.array([2, 3]))[0], by_path[..., 2:4])
    back = with_supply_of(held, droop)
    assert all(np.all(getattr(back, f) == getattr(droop, f)) for f in SUPPLY_FIELDS if f != "supply_paths")
    assert back.supply_paths is None
    stiff = PneumaticMods.nominal(C)
    assert with_held_supply(stiff, (exp,)) is stiff      # independent chambers: nothing to hold


def test_a_leak_fitted_at_its_cylinder_under_the_held_supply_matches_the_fit_of_every_chamber(monkeypatch):
    """The obviously-correct reference: the same valve leak fitted with every chamber replayed
    under the droop's law and refitted beside it.  Held on its path, the supply lets the fit
    refit the elbow's two chambers alone, to the same leak; the fitted model gets the droop back."""
    from identification.doctor.valve_arm import screening
    from identification.doctor.valve_arm.calibrate import pressure_sigma
    from identification.doctor.valve_arm.hypotheses import pneumatic_hypotheses
    from identification.doctor.valve_arm.pneumatic import Windows
    from identification.doctor.valve_arm.rules import HORIZON

    exp, held = _experiments()
    C = exp.robot.tables.n_chambers
    mods = _droop_mods(C)
    win = Windows.tile(len(exp.t), HORIZON, stride=2 * HORIZON)
    leak = next(h for h in pneumatic_hypotheses(exp.robot) if h.label == "valve_leak@elbow.a" and not h.form)
    fast = screening.fit_pneumatic(screening.Scored(leak, 0.0), exp, win, mods, pressure_sigma(exp), held)
    assert list(fast.refitted) == [2, 3]
    assert fast.mods.supply_droop_pa_per_kg_s == DROOP_PA_PER_KG_S and fast.mods.supply_paths is None
    monkeypatch.setattr(screening, "with_held_supply", lambda m, exps: m)   # every chamber under the law
    whole = screening.fit_pneumatic(screening.Scored(leak, 0.0), exp, win, mods, pressure_sigma(exp), held)
    assert whole.refitted is None
    value = lambda s: s.fit.values[-1]  # noqa: E731
    assert value(fast) == pytest.approx(value(whole), rel=0.05)
    assert value(fast) == pytest.approx(LEAK_M2, rel=0.3)


def test_candidate_fits_hold_the_supply_once_per_model_and_fit_as_alone(monkeypatch):
    """CandidateFits computes the held path once for the candidates fitted against one model,
    and each fit is the one fit_pneumatic makes on its own."""
    from identification.doctor.valve_arm import screening
    from identification.doctor.valve_arm.calibrate import pressure_sigma
    from identification.doctor.valve_arm.hypotheses import pneumatic_hypotheses
    from identification.doctor.valve_arm.pneumatic import Windows
    from identification.doctor.valve_arm.rules import HORIZON

    exp, held = _experiments()
    mods = _droop_mods(exp.robot.tables.n_chambers)
    win = Windows.tile(len(exp.t), HORIZON, stride=2 * HORIZON)
    labels = ("valve_leak@elbow.a", "external_leak@shoulder.b")
    hyps = [next(h for h in pneumatic_hypotheses(exp.robot) if h.label == label and not h.form) for label in labels]
    alone = [screening.fit_pneumatic(screening.Scored(h, 0.0), exp, win, mods, pressure_sigma(exp), held) for h in hyps]
    calls = []
    original = screening.with_held_supply
    monkeypatch.setattr(screening, "with_held_supply", lambda m, exps: calls.append(1) or original(m, exps))
    fits = screening.CandidateFits()
    together = [screening.Scored(h, 0.0) for h in hyps]
    for s in together:
        fits.fit(s, exp, win, mods, pressure_sigma(exp), held)
    assert len(calls) == 1
    for a, b in zip(alone, together):
        np.testing.assert_array_equal(a.fit.values, b.fit.values)
        assert list(a.refitted) == list(b.refitted)
