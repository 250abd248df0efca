"""The generalization benchmark's metrics on hand-made case rows (exact values), and its --fast
run end to end (metrics.json's keys, seeds and ranges)."""
import json

import pytest

from scenarios._generalization_metrics import (calibration, case_kind, family_metrics, generalization_metrics,
                                               strict_effect_right, strict_location_right)

SHOULDER, ELBOW = {"joint": "shoulder"}, {"joint": "elbow"}
ELBOW_A = {"actuator": "elbow", "chamber": "a"}
SUPPLY = {"supply": "all"}


def finding(effect, where, inclusion=0.5, before=None, after=None, alternatives=(), places=()):
    return {"effect": effect, "where": where, "inclusion_probability": inclusion,
            "alternatives": list(alternatives), "alternative_places": list(places),
            "heldout_nrmse_in_regime": {"before": before, "after": after} if before is not None else None}


def row(effects, findings=(), unexplained=(), lenient=(False, False), seconds=10.0):
    fams = [f for f, _ in effects]
    return {"kind": case_kind(fams), "families": fams or ["none"],
            "effects": [{"family": f, "where": w} for f, w in effects], "findings": list(findings),
            "unexplained": list(unexplained), "lenient_effect_ok": lenient[0], "lenient_location_ok": lenient[1],
            "seconds": seconds, "generate_seconds": 2 * seconds}


UNEXPLAINED = {"where": ELBOW_A, "regime": "exhaust", "share_of_residual": 0.4}
RIGHT_SINGLE = row([("valve_lag", ELBOW_A)], [finding("valve_lag", ELBOW_A, 0.95, 1.0, 0.4)], lenient=(True, True))
# the right family named second: strictly wrong, although the first finding's place is right
WRONG_FIRST = row([("coulomb_friction", SHOULDER)],
                  [finding("stiction", SHOULDER, 0.92, 1.0, 0.5), finding("coulomb_friction", SHOULDER, 0.5)],
                  lenient=(True, True))
SWAPPED_PAIR = row([("supply_droop", SUPPLY), ("valve_leak", ELBOW_A)],
                   [finding("valve_leak", ELBOW_A, 0.97, 1.0, 0.2), finding("supply_droop", SUPPLY, 0.91, 1.0, 0.8)],
                   lenient=(True, False))
SILENT = row([("valve_lag", ELBOW_A)])
OUTSIDE_FOUND = row([("outside_vocabulary", ELBOW_A)], [finding("external_leak", ELBOW_A, 0.93, 1.0, 0.9)],
                    [UNEXPLAINED])
OUTSIDE_UNEXPLAINED = row([("outside_vocabulary", ELBOW)], unexplained=[UNEXPLAINED])
NULL_UNEXPLAINED = row([], unexplained=[UNEXPLAINED])
NULL_CLEAN = row([])
ROWS = [RIGHT_SINGLE, WRONG_FIRST, SWAPPED_PAIR, SILENT, OUTSIDE_FOUND, OUTSIDE_UNEXPLAINED, NULL_UNEXPLAINED,
        NULL_CLEAN]


def test_case_kinds():
    assert [r["kind"] for r in ROWS] == ["single", "single", "pair", "single", "outside", "outside", "null", "null"]


def test_strict_effect_takes_the_first_finding_only_and_pairs_in_either_order():
    assert strict_effect_right(RIGHT_SINGLE) and strict_location_right(RIGHT_SINGLE)
    assert not strict_effect_right(WRONG_FIRST)
    assert strict_location_right(WRONG_FIRST)  # the place named first is the hidden one
    assert strict_effect_right(SWAPPED_PAIR) and strict_location_right(SWAPPED_PAIR)
    assert not strict_effect_right(SILENT) and not strict_location_right(SILENT)


def test_a_pair_named_right_at_swapped_places_is_strictly_misplaced():
    elbow_b = {"actuator": "elbow", "chamber": "b"}
    r = row([("valve_leak", ELBOW_A), ("valve_lag", elbow_b)],
            [finding("valve_lag", ELBOW_A), finding("valve_leak", elbow_b)])
    assert strict_effect_right(r) and not strict_location_right(r)


def test_a_place_named_only_as_an_alternative_is_strictly_wrong():
    r = row([("pressure_sensor_offset", ELBOW_A)],
            [finding("pressure_sensor_offset", {"actuator": "elbow", "chamber": "b"}, places=[ELBOW_A])])
    assert strict_effect_right(r) and not strict_location_right(r)


def test_every_metric_of_the_hand_made_rows():
    m = generalization_metrics(ROWS, ["valve_lag", "coulomb_friction", "backlash"],
                               same=lambda a, b: a == b or {a, b} == {"coulomb_friction", "stiction"})
    # effect cases: right single, wrong first-named, swapped pair, silent
    assert m["strict_effect_accuracy"] == 0.5
    assert m["strict_location_accuracy"] == 0.75
    assert m["pair_strict_effect_accuracy"] == 1.0
    assert m["lenient_effect_accuracy"] == 0.75 and m["lenient_location_accuracy"] == 0.5
    assert m["outside_reported_unexplained"] == 0.5
    assert m["silent_miss_rate"] == pytest.approx(1 / 6)  # over the 6 non-null cases, outside included
    assert m["null_false_discovery_rate"] == 0.5  # an unexplained entry on a null case counts
    # in-regime reductions 0.6, 0.5, 0.8, 0.2, 0.1 (the finding without one left out)
    assert m["median_heldout_nrmse_reduction_in_regime"] == pytest.approx(0.5)
    assert m["findings_with_in_regime_nrmse"] == 5
    # inclusion >= 0.9: right single, stiction (wrong), both of the pair, external_leak (outside: wrong)
    assert m["calibration_count"] == 5
    assert m["calibration_of_inclusion"] == pytest.approx(3 / 5)
    assert m["calibration_of_inclusion_lenient"] == pytest.approx(4 / 5)  # stiction for Coulomb counts
    assert m["strict_effect_accuracy.valve_lag"] == 0.5 and m["strict_effect_accuracy.coulomb_friction"] == 0.0
    assert "strict_effect_accuracy.backlash" not in m  # no case of it
    assert m["min_family_accuracy"] == 0.0
    assert m["seconds_per_case"] == 10.0 and m["generate_seconds_per_case"] == 20.0
    assert (m["cases"], m["single_cases"], m["pair_cases"], m["null_cases"], m["outside_cases"]) == (8, 3, 1, 2, 2)
    # per place kind of the outside effect: the chamber one was named (wrong), the joint one reported
    assert (m["outside_cases.chamber"], m["outside_reported_unexplained.chamber"]) == (1, 0.0)
    assert (m["outside_cases.joint"], m["outside_reported_unexplained.joint"]) == (1, 1.0)
    assert m["doctor_errors"] == 0 and "concealed_fraction" not in m  # the rows do not say


def test_a_doctor_error_is_a_silent_miss_and_counted():
    failed = {**row([("valve_lag", ELBOW_A)]), "doctor_error": "ValueError: x", "concealed": True}
    m = generalization_metrics([failed, {**RIGHT_SINGLE, "concealed": False}], ["valve_lag"])
    assert m["doctor_errors"] == 1 and m["silent_miss_rate"] == 0.5 and m["strict_effect_accuracy"] == 0.5
    assert m["concealed_fraction"] == 0.5


def test_a_case_the_generator_failed_is_invalid_left_out_and_listed():
    invalid = {"kind": "single", "families": ["line_dynamics"], "seed": 7, "generator_error": "GeneratorError: x",
               "effects": [], "findings": [], "unexplained": [], "seconds": None, "generate_seconds": 1.0}
    m = generalization_metrics([invalid, RIGHT_SINGLE, SILENT], ["valve_lag", "line_dynamics"])
    assert m["cases"] == 2 and m["generator_errors"] == 1 and m["generator_error_seeds"] == "7"
    assert m["strict_effect_accuracy"] == 0.5 and m["silent_miss_rate"] == 0.5
    assert "strict_effect_accuracy.line_dynamics" not in m  # no valid case of that family


def test_a_generator_failure_becomes_an_invalid_row_not_a_failed_run(tmp_path, monkeypatch):
    import scenarios.doctor_generalization_benchmark as bench
    from scenarios._variantsim.cases import GeneratorError

    def unstable(*args, **kwargs):
        raise GeneratorError("variant case x (seed 5, ['two_volume_line']): the main recording has non-finite values")
    monkeypatch.setattr(bench, "make_case", unstable)
    r = bench.generalization_case({"index": 0, "seed": 5, "families": ["line_dynamics"], "forms": None,
                                   "seconds": 1.0, "heldout_seconds": 1.0, "out": str(tmp_path)})
    assert r["generator_error"].startswith("variant case x") and r["findings"] == [] and r["kind"] == "single"


def test_min_family_accuracy_is_the_worst_family():
    rows = [RIGHT_SINGLE, SILENT, row([("coulomb_friction", SHOULDER)], [finding("coulomb_friction", SHOULDER)])]
    m = family_metrics(rows, ["valve_lag", "coulomb_friction"])
    assert m == {"strict_effect_accuracy.valve_lag": 0.5, "strict_location_accuracy.valve_lag": 0.5,
                 "strict_effect_accuracy.coulomb_friction": 1.0, "strict_location_accuracy.coulomb_friction": 1.0,
                 "min_family_accuracy": 0.5}


def test_inclusion_calibration_counts_only_confident_findings():
    rows = [row([("valve_lag", ELBOW_A)], [finding("valve_lag", ELBOW_A, 0.9), finding("valve_leak", ELBOW_A, 0.89)]),
            row([("backlash", ELBOW)], [finding("backlash", SHOULDER, 0.99)])]
    assert calibration(rows) == (0.5, 2)  # the 0.89 one is not counted; backlash at the wrong joint is wrong
    assert calibration([NULL_CLEAN]) == (None, 0)


def test_empty_denominators_are_left_out_not_invented():
    m = generalization_metrics([NULL_CLEAN], ["valve_lag"])
    assert m["null_false_discovery_rate"] == 0.0 and m["outside_cases"] == 0 and m["calibration_count"] == 0
    for key in ("strict_effect_accuracy", "outside_reported_unexplained", "calibration_of_inclusion",
                "min_family_accuracy", "median_heldout_nrmse_reduction_in_regime", "silent_miss_rate"):
        assert key not in m


REQUIRED = ("strict_effect_accuracy", "strict_location_accuracy", "lenient_effect_accuracy", "min_family_accuracy",
            "outside_reported_unexplained", "silent_miss_rate", "null_false_discovery_rate",
            "median_heldout_nrmse_reduction_in_regime")


def _generator_draws_outside() -> bool:
    from scenarios._generalization_metrics import OUTSIDE
    from scenarios.doctor_generalization_benchmark import generator_unknown

    return not generator_unknown([OUTSIDE])


@pytest.mark.skipif(not _generator_draws_outside(), reason="the variant generator does not draw outside_vocabulary yet")
@pytest.mark.heavy
def test_generalization_benchmark_fast(tmp_path, monkeypatch):
    """The --fast benchmark (null, pressure sensor offset, supply droop + valve hysteresis, an
    outside-vocabulary effect; 10 s + 5 s each) in this process: every required metric, the
    fixed seeds, ratios in [0, 1]."""
    from scenarios.common import run_scenario
    from scenarios.doctor_generalization_benchmark import FAST_PLAN, FAST_SEED_BASE, SEED_ENV

    monkeypatch.setenv("PNEUMASIM_BACKEND", "inline")
    monkeypatch.delenv(SEED_ENV, raising=False)
    run_scenario("doctor_generalization_benchmark", tmp_path, fast=True, quiet=True)
    m = json.loads((tmp_path / "metrics.json").read_text())
    for key in REQUIRED + ("seconds_per_case", "calibration_count", "seed_base", "seeds", "seed_source"):
        assert key in m, key
    if m["calibration_count"]:
        assert 0.0 <= m["calibration_of_inclusion"] <= 1.0
    for key in REQUIRED:
        assert key == "median_heldout_nrmse_reduction_in_regime" or 0.0 <= m[key] <= 1.0, (key, m[key])
    assert m["median_heldout_nrmse_reduction_in_regime"] <= 1.0
    assert m["cases"] == len(FAST_PLAN) and m["outside_cases"] == 1 and m["null_cases"] == 1
    assert (m["seed_base"], m["seed_source"]) == (FAST_SEED_BASE, "given")
    assert m["seeds"] == f"{FAST_SEED_BASE}..{FAST_SEED_BASE + len(FAST_PLAN) - 1}"
    rows = json.loads((tmp_path / "cases.json").read_text())
    assert [r["seed"] for r in rows] == list(range(FAST_SEED_BASE, FAST_SEED_BASE + len(FAST_PLAN)))
    for r in rows:  # the recordings, truth and report stay in the case's folder
        folder = tmp_path / "cases" / r["case"]
        assert (folder / "report.json").is_file() and (folder / f"{r['case']}.truth.json").is_file()
    assert (tmp_path / "confusion_matrix.png").is_file()


def test_seed_base_given_fresh_or_resumed(tmp_path, monkeypatch):
    """A given seed is used as given; none: a fresh 9-digit one from the OS each run, except
    that an unfinished run into the same folder (seed.json, no metrics.json) keeps its own."""
    from pneumatics.errors import ConfigError
    from scenarios._benchmark import FRESH_SEEDS
    from scenarios.doctor_generalization_benchmark import FAST_SEED_BASE, SEED_ENV, choose_seed_base

    monkeypatch.setenv(SEED_ENV, "123")
    assert choose_seed_base(tmp_path, fast=False) == (123, "given")
    monkeypatch.setenv(SEED_ENV, "12x")
    with pytest.raises(ConfigError, match="PNEUMASIM_GENERALIZATION_SEED='12x'"):
        choose_seed_base(tmp_path, fast=False)
    monkeypatch.delenv(SEED_ENV)
    assert choose_seed_base(tmp_path, fast=True) == (FAST_SEED_BASE, "given")
    draws = [choose_seed_base(tmp_path, fast=False) for _ in range(3)]
    assert all(s == "fresh" and FRESH_SEEDS[0] <= b < FRESH_SEEDS[1] for b, s in draws)
    assert len({b for b, _ in draws}) == 3
    (tmp_path / "seed.json").write_text(json.dumps({"seed_base": 555000111, "seed_source": "fresh"}))
    assert choose_seed_base(tmp_path, fast=False) == (555000111, "fresh")  # resumed
    (tmp_path / "metrics.json").write_text("{}")  # that run finished: the next one is fresh again
    assert choose_seed_base(tmp_path, fast=False)[0] != 555000111


def test_the_full_plan_is_80_cases_of_the_issue():
    from collections import Counter

    from scenarios.doctor_generalization_benchmark import FAMILIES, plan

    cases, seconds, heldout = plan(False, 123)
    kinds = Counter(case_kind(c["families"]) for c in cases)
    assert (len(cases), seconds, heldout) == (80, 60.0, 30.0)
    assert kinds == {"single": 60, "null": 6, "pair": 8, "outside": 6}
    assert len(FAMILIES) == 15 and "force_sensor_offset" not in FAMILIES and "end_stop" in FAMILIES
    assert Counter(c["families"][0] for c in cases if case_kind(c["families"]) == "single") == {f: 4 for f in FAMILIES}
    pairs = [set(c["families"]) for c in cases if case_kind(c["families"]) == "pair"]
    assert {"supply_droop", "valve_leak"} in pairs and all(len(p) == 2 for p in pairs)
    fast, s, h = plan(True, 0)
    assert len(fast) == 4 and (s, h) == (10.0, 5.0)


def test_outside_forms_spread_over_chamber_joint_and_supply(monkeypatch):
    """With a form registry, two outside forms at each place kind, different where it has two."""
    import sys
    import types
    from collections import namedtuple

    import numpy as np

    from scenarios.doctor_generalization_benchmark import outside_forms

    F = namedtuple("F", "name kind")
    fake = types.ModuleType("scenarios._variantsim.forms")
    fake.FORMS = {"outside_vocabulary": [F("wall", "chamber"), F("port", "chamber"), F("hose", "joint"),
                                         F("cog", "joint"), F("ripple", "supply")],
                  "valve_lag": [F("first_order", "chamber")]}
    monkeypatch.setitem(sys.modules, "scenarios._variantsim.forms", fake)
    forms = outside_forms(np.random.default_rng(5))
    assert set(forms[0::3]) == {"wall", "port"} and set(forms[1::3]) == {"hose", "cog"}
    assert forms[2::3] == ["ripple", "ripple"]
