"""A pneumatic candidate's fit taken over from an earlier round (screening.CandidateFits): the
search must decide exactly as when every candidate is fitted afresh, with fewer fits."""
from __future__ import annotations

import numpy as np
import pytest


def _searched(reuse: bool):
    """arm2's pneumatic search on 20 s + 10 s recordings with an external leak at elbow.a whose
    first kept finding is refused once, its hypothesis alone ruled out (as where the torque
    balance contradicts a sensor offset), so a second round fits the other candidates against
    the same chamber model; returns (findings, the labels fit_pneumatic was called on)."""
    with pytest.MonkeyPatch.context() as mp:
        return _search_refusing_once(mp, reuse)


def _search_refusing_once(monkeypatch, reuse):
    from identification.doctor.valve_arm import screening, search
    from identification.doctor.valve_arm.diagnose import _calibrated_run
    from pneumatics.effects.effect_set import EffectSet
    from pneumatics.robot import load_robot
    from scenarios._cases import _record

    monkeypatch.setattr(screening, "REUSE_FITS", reuse)
    calls = []
    real_fit = screening.fit_pneumatic
    monkeypatch.setattr(screening, "fit_pneumatic", lambda s, *a: calls.append(s.hyp.label) or real_fit(s, *a))
    refused = []
    monkeypatch.setattr(search, "partial_projection", lambda run, f: not refused and not refused.append(f.scored.hyp.label))
    monkeypatch.setattr(search, "close_place", lambda run, f, scored: run.tried.add(f.scored.hyp.label))
    robot = load_robot("arm2")
    recs = _record(robot, EffectSet(external_leak_m2={"elbow.a": 6e-8}), 41, 20.0, 10.0)
    run, _ = _calibrated_run(robot, [recs["main"]], [recs["heldout"]], lambda m: None)
    search.search_pneumatic(run, lambda m: None)
    assert refused, "the search kept nothing to refuse: the test no longer makes a second round"
    return run.findings, calls


def test_fits_taken_over_from_a_round_that_kept_nothing_decide_as_fresh_ones():
    fresh, fresh_calls = _searched(reuse=False)
    reused, reused_calls = _searched(reuse=True)
    assert [(f.family, f.where) for f in reused] == [(f.family, f.where) for f in fresh]
    assert fresh, "the second round kept nothing: the test compares no decision"
    for a, b in zip(fresh, reused):
        assert a.heldout_gain == pytest.approx(b.heldout_gain, rel=1e-12)
        assert {k: v["value"] for k, v in a.params.items()} == {k: v["value"] for k, v in b.params.items()}
    # the round after the refusal fitted its candidates against the model of the round before
    assert len(reused_calls) < len(fresh_calls)
    assert set(reused_calls) == set(fresh_calls)  # each hypothesis still fitted, once


def test_a_fit_is_taken_over_only_for_the_same_hypothesis_against_the_same_model():
    from identification.doctor.valve_arm.hypotheses import pneumatic_hypotheses
    from identification.doctor.valve_arm.screening import CandidateFits, Scored, hypothesis_key
    from pneumatics.robot import load_robot

    hyps = pneumatic_hypotheses(load_robot("arm2"))
    # two forms of one family at one place share a label, not a key
    offsets = [h for h in hyps if h.label == "pressure_sensor_offset@elbow.b"]
    assert len(offsets) == 2 and hypothesis_key(offsets[0]) != hypothesis_key(offsets[1])
    fits, model, other = CandidateFits(), object(), object()
    fits.mods, fits.done = model, {hypothesis_key(offsets[0]): ("fit", "mods", None)}
    s = Scored(offsets[0], 0.1)
    assert fits.fit(s, None, None, model, 1.0) and (s.fit, s.mods) == ("fit", "mods")
    # a second form, or the same form against another model object, is fitted afresh
    # (fit_pneumatic on None data raises: it was asked to fit)
    with pytest.raises(Exception):
        fits.fit(Scored(offsets[1], 0.1), None, None, model, 1.0)
    with pytest.raises(Exception):
        fits.fit(Scored(offsets[0], 0.1), None, None, other, 1.0)
    assert not fits.done  # the other model's fits replaced the first's
    assert np.isfinite(s.predicted_gain)
