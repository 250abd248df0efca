"""What the recordings could show at the chambers (chamber_limits.chamber_detection_limits): a
chamber effect well over the size the doctor states for its chamber is named there, one well
under it is not."""
from __future__ import annotations

import numpy as np
import pytest


def _run(robot, effects):
    from identification.doctor.valve_arm.diagnose import _calibrated_run
    from scenarios._cases import _record

    recs = _record(robot, effects, 41, 20.0, 10.0)
    run, _ = _calibrated_run(robot, [recs["main"]], [recs["heldout"]], lambda m: None)
    return run


@pytest.fixture(scope="module")
def arm2_limits():
    from identification.doctor.valve_arm.chamber_limits import chamber_detection_limits
    from pneumatics.effects.effect_set import EffectSet
    from pneumatics.robot import load_robot

    robot = load_robot("arm2")
    return robot, chamber_detection_limits(_run(robot, EffectSet()))


def test_every_chamber_gets_a_finite_positive_limit_per_family(arm2_limits):
    _, limits = arm2_limits
    assert {"valve_leak", "external_leak", "valve_hysteresis", "piston_leak", "supply_droop"} <= set(limits)
    assert set(limits["external_leak"]["detection_limit"]) == {"shoulder.a", "shoulder.b", "elbow.a", "elbow.b"}
    assert limits["external_leak"]["parameter"] == "leak_area_m2"
    assert set(limits["piston_leak"]["detection_limit"]) == {"shoulder", "elbow"}
    for fam in limits.values():
        v = np.array(list(fam["detection_limit"].values()))
        assert np.all(np.isfinite(v)) and np.all(v > 0)


@pytest.mark.parametrize("times, named", [(0.25, False), (4.0, True)])
def test_an_external_leak_over_its_stated_limit_is_named_and_one_under_it_is_not(arm2_limits, times, named):
    """The limit stated on a recording without the leak, then the same recording (seed, noise)
    with a leak of a quarter or four times that size at elbow.a: the pneumatic search names the
    larger there and keeps nothing for the smaller."""
    from identification.doctor.valve_arm import search
    from pneumatics.effects.effect_set import EffectSet

    robot, limits = arm2_limits
    size = times * limits["external_leak"]["detection_limit"]["elbow.a"]
    run = _run(robot, EffectSet(external_leak_m2={"elbow.a": size}))
    search.search_pneumatic(run, lambda m: None)
    found = [(f.family, f.where) for f in run.findings]
    assert (("external_leak", {"actuator": "elbow", "chamber": "a"}) in found) is named, found
    if not named:
        assert not found
    # the report keeps every fitted candidate's held-out gain and verdict
    records = run.pneumatic_candidates
    assert records and all(r["verdict"].startswith(("named", "refused: ", "passed")) for r in records)
    for r in records:
        if r["verdict"].startswith("refused: held-out gain"):
            assert r["heldout_gain"] < search.PNEU_KEEP
    leak = [r for r in records if r["verdict"] == "named" and r["chambers"] == ["elbow.a"]]
    assert bool(leak) is named
    if named:
        assert leak[0]["hypothesis"].startswith("external_leak") and leak[0]["heldout_gain"] >= search.PNEU_KEEP
        assert leak[0]["params"]["leak_area_m2"]["value"] == pytest.approx(size, rel=0.3)


def test_what_the_calibration_can_mimic_is_taken_off_an_effects_signature():
    """A signature that is 2 x the exhaust area's plus a part no calibration parameter has keeps
    that part alone; one the calibration spans entirely keeps nothing; windows with a NaN are
    left out."""
    from identification.doctor.valve_arm.chamber_limits import off_calibration

    rng = np.random.default_rng(3)
    cal = rng.normal(size=(3, 40, 30))
    own = rng.normal(size=(40, 30))
    own -= np.einsum("kwh,k->wh", cal, np.linalg.lstsq(cal.reshape(3, -1).T, own.ravel(), rcond=None)[0])
    left = off_calibration(2.0 * cal[1] + own, cal)
    assert left == pytest.approx(own.ravel(), abs=1e-9)
    assert np.linalg.norm(off_calibration(cal[0] - 0.5 * cal[2], cal)) == pytest.approx(0.0, abs=1e-9)
    s = 2.0 * cal[1] + own
    s[5, 3] = np.nan
    assert off_calibration(s, cal).size == 39 * 30
