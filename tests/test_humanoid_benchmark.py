"""The humanoid38 doctor benchmark (issue 17, item 3): its case maker and its --fast run."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pneumatics.effects.family import place_names
from pneumatics.robot import load_robot
from scenarios._humanoid_cases import PARAM_ERROR, draw_on_humanoid, humanoid_families, perturbed_humanoid


def test_parameter_errors_reach_every_actuator_and_body_within_3_percent():
    nominal = load_robot("humanoid38")
    robot, factors = perturbed_humanoid(np.random.default_rng(5))
    area = lambda r: np.array([a.valve_a.supply_area_max_m2 for a in r.fluid.actuators])  # noqa: E731
    dead = lambda r: np.array([a.dead_volume_b_m3 for a in r.fluid.actuators])  # noqa: E731
    for get in (area, dead):
        ratio = get(robot) / get(nominal)
        assert np.all(np.abs(ratio - 1) <= PARAM_ERROR) and np.std(ratio) > 0.005  # each its own error
    massive = [i for i in range(1, nominal.model.nbody) if nominal.model.body_mass[i] > 0]
    assert len(factors) == len(massive) > 30
    assert np.allclose(robot.model.body_mass[massive] / nominal.model.body_mass[massive], list(factors.values()))


def test_every_family_draws_a_place_of_humanoid38():
    robot = load_robot("humanoid38")
    fams = humanoid_families()
    assert {"valve_leak", "coulomb_friction", "pressure_sensor_offset", "supply_droop"} <= set(fams)
    rng = np.random.default_rng(0)
    for name in fams:
        fam, place, _ = draw_on_humanoid(name, rng, robot)
        assert place in place_names(robot, fam.place_kind)


def test_a_backlash_is_drawn_only_where_a_joint_transmission_actuator_can_carry_its_play():
    """humanoid38's 13 cylinders on pins pull spatial tendons: backlash_model has no drive hinge
    to split there (a fresh benchmark case failed so); its other 25 joints are turned directly.  A
    first draw at one of those stands as it was; one at a cylinder on pins is drawn again."""
    from pneumatics.effects.backlash import backlash_model
    from pneumatics.effects.registry import get_family
    from pneumatics.errors import PneumasimError

    robot = load_robot("humanoid38")
    possible = get_family("backlash").places(robot)
    assert "left_hip_pitch" not in possible and "jaw" in possible and len(possible) == 25
    joints = robot.joint_names
    for seed in range(40):
        first = joints[int(np.random.default_rng(seed).integers(0, len(joints)))]
        _, place, _ = draw_on_humanoid("backlash", np.random.default_rng(seed), robot)
        assert place in possible
        if first in possible:
            assert place == first
    backlash_model(robot, {possible[0]: 0.01})  # builds
    with pytest.raises(PneumasimError, match="joint-transmission"):
        backlash_model(robot, {"left_hip_pitch": 0.01})


def test_a_given_effect_at_a_place_the_robot_lacks_is_refused_by_name():
    """make_case's stated effects (the --fast case's) name a place of the robot, or the error
    lists the valid ones, before anything is simulated."""
    from pneumatics.errors import UnknownNameError
    from scenarios._humanoid_cases import make_case

    given = [{"family": "valve_leak", "place": "left_elbow.c", "parameters": {"leak_area_m2": 4e-8}}]
    refused = r"valve_leak place on humanoid38\[left_arm\] 'left_elbow.c'.*valid: .*left_elbow.a"
    with pytest.raises(UnknownNameError, match=refused):
        make_case(1, [], 2.0, 2.0, subset="left_arm", given=given)


@pytest.mark.heavy
def test_fast_humanoid38_benchmark(tmp_path, monkeypatch):
    """--fast (issue 17: in CI): the issue's example, a valve leaking near null at left_elbow
    chamber a, on the left arm (16 chambers), 20 s + 10 s, and the timing cases of the left arm
    alone (a null case) and of arm2, in this process.  The leaking chamber is named first, and
    the left arm's clean recording gets no finding and no ``unexplained`` entry."""
    from scenarios.common import run_scenario

    monkeypatch.setenv("PNEUMASIM_BACKEND", "inline")
    m = run_scenario("doctor_benchmark_humanoid38", tmp_path, fast=True, quiet=True)
    assert m["cases"] == 1 and m["single_cases"] == 1
    assert m["silent_miss_rate"] == 0.0 and m["strict_effect_accuracy"] == 1.0
    assert m["strict_location_accuracy"] == 1.0
    assert m["seconds_per_case"] > 0 and m["arm2_doctor_seconds"] > 0
    assert m["subset_chambers.left_arm"] == 16 and m["subset_doctor_seconds.left_arm"] > 0
    assert m["subset_null_entries.left_arm"] == 0
    assert 100 < m["peak_memory_mib"] < 4096  # the issue's budget: 4 GiB
    rows = json.loads((tmp_path / "cases.json").read_text())
    assert [(r["families"], r["subset"], r["chambers"]) for r in rows] == [(["valve_leak"], "left_arm", 16)]
    leak = rows[0]
    assert leak["effects"][0]["where"] == {"actuator": "left_elbow", "chamber": "a"}
    assert leak["effects"][0]["parameters"] == {"valve_leak_m2": 4e-8} and leak["effects"][0]["scale"] == 1.0
    assert leak["findings"][0]["effect"] == "valve_leak"
    assert leak["findings"][0]["where"] == leak["effects"][0]["where"]
    assert (tmp_path / "cases" / leak["case"] / "report.json").is_file()
    assert (tmp_path / "doctor_time.png").stat().st_size > 5_000


def _whole_robot_case(seed: int, families: list, **given) -> dict:
    from scenarios.doctor_benchmark_humanoid38 import FAST_HELDOUT_SECONDS, FAST_SECONDS, humanoid_case

    row = humanoid_case({"seed": seed, "families": families, "seconds": FAST_SECONDS,
                         "heldout_seconds": FAST_HELDOUT_SECONDS, **given})
    assert row["chambers"] == 76
    return row


@pytest.mark.slow
def test_the_issues_example_on_all_76_chambers_is_named_there():
    """The issue's example on the whole robot (out of --fast for CI's time: four minutes of
    doctor on a slow machine): the leak at left_elbow chamber a is named first, there."""
    from scenarios.doctor_benchmark_humanoid38 import ISSUE_EXAMPLE

    row = _whole_robot_case(702, ["valve_leak"], given=ISSUE_EXAMPLE)
    first = row["findings"][0]
    assert (first["effect"], first["where"]) == ("valve_leak", {"actuator": "left_elbow", "chamber": "a"})


@pytest.mark.slow
def test_a_concealed_leak_at_one_of_76_chambers_is_named_there():
    """A concealed valve leak drawn at one of the 76 chambers (seed 702, 20 s + 10 s) is named
    first, at that chamber."""
    row = _whole_robot_case(702, ["valve_leak"])
    first = row["findings"][0]
    assert (first["effect"], first["where"]) == ("valve_leak", row["effects"][0]["where"])


@pytest.mark.slow
def test_a_clean_recording_of_all_76_chambers_gets_no_finding():
    """The null case of the whole robot (seed 701, 20 s + 10 s; out of --fast for CI's time):
    +-3 % parameter errors and sensor noise alone give no finding and no ``unexplained`` entry."""
    row = _whole_robot_case(701, [])
    assert row["findings"] == [] and row["unexplained"] == []


@pytest.mark.slow
def test_a_viscous_friction_at_one_of_38_joints_is_named_there():
    """The joint effect's fast case (seed 703, 20 s + 10 s; out of --fast for CI's time): a
    viscous friction hidden at one joint is named first, at that joint."""
    row = _whole_robot_case(703, ["viscous_friction"])
    first = row["findings"][0]
    assert (first["effect"], first["where"]) == ("viscous_friction", row["effects"][0]["where"])


def test_metrics_from_hand_made_rows_are_strict_and_keep_the_timing_cases():
    """A right chamber case, a joint case named at the wrong joint, a null case with a finding."""
    from scenarios.doctor_benchmark_humanoid38 import metrics

    def row(seed, effects, findings, unexplained=()):
        return {"seed": seed, "kind": "single" if effects else "null",
                "families": [e["family"] for e in effects] or ["none"], "effects": effects,
                "findings": findings, "unexplained": list(unexplained), "lenient_effect_ok": bool(findings),
                "lenient_location_ok": bool(findings), "seconds": 100.0, "generate_seconds": 5.0,
                "peak_memory_mib": 900.0}

    leak = {"family": "valve_leak", "where": {"actuator": "left_elbow", "chamber": "a"}}
    visc = {"family": "viscous_friction", "where": {"joint": "right_knee"}}
    rows = [row(1, [leak], [{"effect": "valve_leak", "where": leak["where"]}]),
            row(2, [visc], [{"effect": "viscous_friction", "where": {"joint": "left_knee"}}]),
            row(3, [], [{"effect": "supply_droop", "where": {"supply": "all"}}])]
    arm = {"subset": "left_arm", "chambers": 16, "seconds": 30.0, "peak_memory_mib": 1500.0,
           "findings": [], "unexplained": [{"where": {"joint": "left_elbow"}}]}
    m = metrics(rows, ["valve_leak", "viscous_friction"], {"seconds": 8.0, "peak_memory_mib": 1200.0}, [arm])
    assert m["strict_effect_accuracy"] == 1.0 and m["strict_location_accuracy"] == 0.5
    assert m["null_false_discovery_rate"] == 1.0 and m["silent_miss_rate"] == 0.0
    assert m["strict_location_accuracy.viscous_friction"] == 0.0
    assert m["peak_memory_mib"] == 1500.0 and m["arm2_doctor_seconds"] == 8.0 and m["seeds"] == "1,2,3"
    assert m["subset_doctor_seconds.left_arm"] == 30.0 and m["subset_chambers.left_arm"] == 16
    assert m["subset_null_entries.left_arm"] == 1  # the part's null case reported something


def test_a_case_measures_its_own_memory_peak_not_what_its_worker_needed_before():
    """A warm worker's earlier case needed 400 MiB more than this one: the case's peak (the
    high-water mark reset when it starts) is of this case, where the process's peak before the
    reset held the earlier one.  In a fresh interpreter: what earlier tests left in this process
    (freed memory the allocator keeps resident) is not the worker this test describes."""
    if not os.path.exists("/proc/self/clear_refs"):
        pytest.skip("no /proc: the case's peak is the process's")
    code = """
import numpy as np
from scenarios.doctor_benchmark_humanoid38 import _case_peak_mib, _start_case_peak
big = np.ones(400 * 2 ** 20 // 8)        # every page written: resident
before = _case_peak_mib()
resident = before - big.nbytes / 2 ** 20
del big
_start_case_peak()
small = np.ones(2 ** 20)                 # 8 MiB, held while the peak is read
case = _case_peak_mib()
del small
print(before, case, resident)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).resolve().parents[1])
    before, case, resident = map(float, out.stdout.split())
    assert before - case > 300
    assert case >= resident - 50


def test_a_silent_case_is_counted_under_the_detection_limit_only_where_the_doctor_stated_one_above_it():
    """The doctor's stated limit at the hidden effect's place against the effect's true size: a
    Coulomb friction under it, a viscous friction over it, a valve leak at a chamber with no
    stated limit; the smallest of the joints' and the chambers' limits where both state one."""
    from scenarios.doctor_benchmark_humanoid38 import below_limit_metrics, effect_against_limit

    screen = {"coulomb_friction": {"parameter": "coulomb_nm", "detection_limit": {"right_knee": 0.3}},
              "viscous_friction": {"parameter": "viscous_nm_s_per_rad", "detection_limit": {"jaw": 0.01}},
              "pressure_sensor_offset": {"parameter": "offset_pa", "detection_limit": {"left_elbow": 3000.0}}}
    chambers = {"valve_leak": {"parameter": "leak_area_m2", "detection_limit": {"jaw.b": 2e-9, "jaw.a": None}},
                "pressure_sensor_offset": {"parameter": "offset_pa", "detection_limit": {"left_elbow.b": 2500.0}}}
    diagnostics = {"output_error_screen": screen, "chamber_detection_limit": chambers}
    coulomb = {"family": "coulomb_friction", "where": {"joint": "right_knee"}, "parameters": {"friction": {"coulomb_nm": -0.02}}}
    viscous = {"family": "viscous_friction", "where": {"joint": "jaw"}, "parameters": {"friction": {"viscous_nm_s": 0.03}}}
    offset = {"family": "pressure_sensor_offset", "where": {"actuator": "left_elbow", "chamber": "b"},
              "parameters": {"pressure_offset_pa": -5000.0}}
    leak = {"family": "valve_leak", "where": {"actuator": "jaw", "chamber": "a"}, "parameters": {"valve_leak_m2": 1e-8}}
    small_leak = {"family": "valve_leak", "where": {"actuator": "jaw", "chamber": "b"}, "parameters": {"valve_leak_m2": 1e-9}}
    assert effect_against_limit(coulomb, diagnostics) == {"family": "coulomb_friction", "size": 0.02, "limit": 0.3}
    # the joints' limit is stated on the cylinder's chamber a; the chambers' on b itself: the smaller
    assert effect_against_limit(offset, {"output_error_screen": screen})["limit"] == 3000.0
    assert effect_against_limit(offset, diagnostics)["limit"] == 2500.0
    assert effect_against_limit(leak, diagnostics)["limit"] is None          # none stated at jaw.a
    assert effect_against_limit(small_leak, diagnostics) == {"family": "valve_leak", "size": 1e-9, "limit": 2e-9}
    assert effect_against_limit(coulomb, {})["limit"] is None               # the screen did not run
    # a stiction is told from a Coulomb friction by its breakaway excess: that against the
    # screen's limit of the excess at its joint, none where the screen stated none
    stiction = {"family": "stiction", "where": {"joint": "right_knee"},
                "parameters": {"friction": {"coulomb_nm": 0.02, "stiction_extra_nm": 0.05, "stribeck_rad_s": 0.08}}}
    assert effect_against_limit(stiction, diagnostics)["limit"] is None
    with_excess = {**screen, "stiction": {"parameter": "breakaway_extra_nm", "detection_limit": {"right_knee": 0.4}}}
    assert effect_against_limit(stiction, {"output_error_screen": with_excess}) == {
        "family": "stiction", "size": 0.05, "limit": 0.4}

    def row(effect, findings=()):
        return {"effects": [effect], "findings": list(findings), "unexplained": [],
                "detection": [effect_against_limit(effect, diagnostics)]}

    named_at_b = {"effect": "pressure_sensor_offset", "where": {"actuator": "left_elbow", "chamber": "b"}}
    named_at_a = {"effect": "pressure_sensor_offset", "where": {"actuator": "left_elbow", "chamber": "a"}}
    rows = [row(coulomb), row(viscous), row(leak), row(small_leak), row(offset, [named_at_b]),
            {"effects": [], "findings": [], "unexplained": [], "detection": []}]
    m = below_limit_metrics(rows)
    # over their limits: the viscous friction (silent) and the offset (named at its chamber)
    assert m == {"effects_with_stated_detection_limit": 4, "effects_under_stated_detection_limit": 2,
                 "effects_under_stated_detection_limit_named_at_place": 0,
                 "effects_over_stated_detection_limit_named_at_place": 1,
                 "silent_cases_under_stated_detection_limit": 2, "silent_cases": 4}
    # named at the other chamber, the offset is not named at its place
    rows[4] = row(offset, [named_at_a])
    assert below_limit_metrics(rows)["effects_over_stated_detection_limit_named_at_place"] == 0


def test_a_fresh_humanoid_run_draws_its_base_and_a_resumed_one_keeps_it(tmp_path, monkeypatch):
    """PNEUMASIM_HUMANOID_SEED: unset, the development base 7000; "fresh", a 9-digit base from
    the operating system's entropy, read back from seed.json while the run has no metrics.json."""
    from scenarios._benchmark import remember_seed_base, seed_base_from_env
    from scenarios.doctor_benchmark_humanoid38 import DEVELOPMENT_SEED_BASE, SEED_ENV, plan

    monkeypatch.delenv(SEED_ENV, raising=False)
    assert seed_base_from_env(SEED_ENV, DEVELOPMENT_SEED_BASE, tmp_path) == (7000, "development")
    monkeypatch.setenv(SEED_ENV, "fresh")
    base, source = seed_base_from_env(SEED_ENV, DEVELOPMENT_SEED_BASE, tmp_path)
    assert source == "fresh" and 100_000_000 <= base < 1_000_000_000
    remember_seed_base(tmp_path, base, source)
    assert seed_base_from_env(SEED_ENV, DEVELOPMENT_SEED_BASE, tmp_path) == (base, "fresh")  # resumed
    (tmp_path / "metrics.json").write_text("{}")  # finished: the next run draws anew
    assert seed_base_from_env(SEED_ENV, DEVELOPMENT_SEED_BASE, tmp_path)[0] != base
    assert plan(False, base)[0][0][0] == base


def test_a_recording_the_doctor_would_refuse_is_made_again_with_the_effect_halved(monkeypatch):
    """MuJoCo's soft joint limit can let a joint pass far beyond its range where a real stop
    holds; the doctor refuses such a recording (recording_checks), so the case maker halves the
    hidden effect and records again; a null case that does it is an error naming the column."""
    import scenarios._humanoid_cases as hc
    import scenarios.humanoid38_tracking as tracking
    from pneumatics.errors import RecordingError
    from pneumatics.recording import Recording

    robot = load_robot("humanoid38")
    calls = []

    def fake_track(robot_, cfg, ref, lin, seconds, seed, effects):
        calls.append(seed)
        t = np.arange(0.0, 1.0, 0.01)
        cols = {f"q.{n}": np.zeros_like(t) for n in robot.joint_names}
        if len(calls) <= 4:  # the first two attempts (main and held-out each) push the ankle past its stop
            cols["q.right_ankle_roll"] = np.linspace(-0.7, 0.3, t.size)
        return Recording(t, cols, {}, "fake")

    monkeypatch.setattr(hc, "controller", lambda subset=None: (None, None, [None, None]))
    monkeypatch.setattr(tracking, "track", fake_track)
    _, _, truth = hc.make_case(11, ["viscous_friction"], 1.0, 1.0)
    assert len(calls) == 6
    assert hc.CONCEAL_SCALE[0] / 4 <= truth["scale"] <= hc.CONCEAL_SCALE[1] / 4  # halved twice
    calls.clear()
    with pytest.raises(RecordingError, match=r"humanoid38 case 12: .*q\.right_ankle_roll"):
        hc.make_case(12, [], 1.0, 1.0)
