"""Which pneumatic hypotheses the doctor's search fits in full: the score test's best ones
(worth_fitting) and, beside a leak, the other leak family at the same chamber (rivals); and
which supply hypothesis pays as a supply does (shared_by_chambers)."""
from types import SimpleNamespace

import numpy as np

from identification.doctor.valve_arm.acceptance import rivals, shared_by_chambers, worth_fitting


def _scored(family, chambers, gain, params=("area",)):
    label = f"{family}@{chambers}"
    hyp = SimpleNamespace(family=family, chambers=list(chambers), label=label, params=list(params))
    return SimpleNamespace(hyp=hyp, predicted_gain=gain)


def test_a_leak_is_fitted_beside_the_other_leak_family_at_its_chamber():
    """An external leak the calibration half took up scores low (0.02 beside the valve leak's
    0.07); it is fitted anyway, once (its best-scored form), and only at the valve leak's chamber."""
    valve = _scored("valve_leak", [2], 0.07, ("supply", "exhaust"))
    lag = _scored("valve_lag", [2], 0.11)
    scored = [lag, valve, _scored("external_leak", [2], 0.02), _scored("external_leak", [3], 0.015),
              _scored("valve_leak", [2], 0.001)]
    top = worth_fitting([s for s in scored if s.predicted_gain >= 0.02])
    assert scored[2] not in top
    extra = rivals(top, scored)
    assert extra == [scored[2]]


def test_rivals_add_nothing_already_fitted_or_unrelated():
    ext = _scored("external_leak", [0], 0.3)
    valve = _scored("valve_leak", [0], 0.25)
    assert rivals([ext, valve], [ext, valve]) == []
    lag = _scored("valve_lag", [1], 0.2)
    assert rivals([lag], [lag, _scored("external_leak", [1], 0.1)]) == []


def _supply(gains):
    """A fitted supply hypothesis whose held-out mean square per chamber changed by ``gains``."""
    before = np.ones(len(gains))
    return SimpleNamespace(heldout_before=before, heldout_after=np.sqrt(1.0 - np.asarray(gains)))


def test_a_supply_pays_in_the_chambers_it_feeds_not_in_one():
    assert shared_by_chambers(_supply([0.62, 0.67, 0.61, 0.65]))       # a regulator's droop
    assert shared_by_chambers(_supply([0.08, 0.21, 0.35, 0.51]))       # all but one by 0.1
    # a line's tube at one chamber, taken up by a droop that makes the others worse
    assert not shared_by_chambers(_supply([-0.28, 0.58, -0.48, -1.7]))
    assert not shared_by_chambers(_supply([0.0, 0.0, 0.0, 0.36]))      # one chamber alone
    assert not shared_by_chambers(_supply([0.3, 0.3, -0.2, -0.2]))     # as many made worse


def test_a_valve_leak_through_either_land_passes_the_keep_rule():
    """The two-land valve leak is there when either land leaks (a laminar underlap fitted by
    orifices: the exhaust land's area 16 standard errors from zero, the supply land's 3.7); a
    form whose every parameter must be significant still asks each."""
    from identification.doctor.valve_arm.hypotheses import pneumatic_hypotheses
    from identification.doctor.valve_arm.rules import keeps
    from pneumatics.robot import load_robot

    hyps = [h for h in pneumatic_hypotheses(load_robot("arm2")) if h.label == "valve_leak@shoulder.b"]
    two = next(h for h in hyps if len(h.params) == 2)
    assert keeps(two, [5.43e-10, 2.34e-9], [1.46e-10, 1.48e-10])
    assert not keeps(two, [5.43e-10, 2.34e-10], [1.46e-10, 1.48e-10])    # neither land
    drift = SimpleNamespace(keep_mask=lambda: np.array([False, True]), any_tested=False)
    assert keeps(drift, [0.0, 8e3], [1e3, 1e3]) and not keeps(drift, [8e3, 0.0], [1e3, 1e3])
    both = SimpleNamespace(keep_mask=lambda: np.array([True, True]), any_tested=False)
    assert not keeps(both, [5.43e-10, 2.34e-9], [1.46e-10, 1.48e-10])


def test_a_chamber_whose_held_out_replay_stands_out_has_its_best_other_family_fitted():
    """acceptance.standing_out_candidates: the chamber replaying 1.5 times the median held out gets
    its best-scored hypothesis of a family not chosen there yet, whatever its score; chambers
    near the median, and one a finding explains, get none."""
    from types import SimpleNamespace

    import numpy as np

    from identification.doctor.valve_arm.hypothesis import Hypothesis
    from identification.doctor.valve_arm.screening import Scored
    from identification.doctor.valve_arm.acceptance import standing_out_candidates

    def scored(family, c, gain):
        return Scored(Hypothesis(family, {"actuator": "x", "chamber": str(c)}, "pneumatic", [("p", 0, 0, 1, 1)], [c]),
                      gain)
    offset2, leak2, lag2, leak0 = scored("pressure_sensor_offset", 2, 0.03), scored("valve_leak", 2, 0.018), \
        scored("valve_lag", 2, 0.001), scored("valve_leak", 0, 0.019)
    ranked = [offset2, leak0, leak2, lag2]
    rms = np.array([680.0, 796.0, 1151.0, 724.0])
    run = SimpleNamespace(findings=[])
    assert standing_out_candidates(run, rms, ranked, [offset2]) == [leak2]
    assert standing_out_candidates(run, rms, ranked, []) == [offset2]
    run.findings = [SimpleNamespace(scored=SimpleNamespace(hyp=SimpleNamespace(chambers=[2])))]
    assert standing_out_candidates(run, rms, ranked, []) == []
    assert standing_out_candidates(SimpleNamespace(findings=[]), np.full(4, 700.0), ranked, []) == []
