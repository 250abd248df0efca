"""The generalization benchmark's metrics: pure functions over one row per case, so that they
can be checked on hand-made rows without running the doctor.

A row (what :mod:`scenarios.doctor_generalization_benchmark` writes into cases.json):
``kind`` ("null" | "single" | "pair" | "outside", :func:`case_kind`), ``families`` (the hidden
families, ["none"] for a null case), ``effects`` (the truth's [{"family", "where", ...}]),
``findings`` (the doctor's, in its order: [{"effect", "where", "alternatives",
"alternative_places", "inclusion_probability", "heldout_nrmse_in_regime"}]), ``unexplained``
(the doctor's unexplained entries), ``lenient_effect_ok`` / ``lenient_location_ok`` (the
development sets' judge), ``seconds`` (the doctor's time) and ``generate_seconds``.

Definitions (primary metrics are strict; the lenient ones are the second column):

* strict effect right: the FIRST finding's effect is the hidden family (a pair: the first
  two findings' effects are the two hidden families, in either order); alternatives and
  friction-family leniency do not count; later findings are neither credited nor charged.
* strict location right: the first finding's ``where`` equals the hidden effect's ``where``
  exactly (a pair: the first two findings' places are the two hidden places, in either order,
  each at its own family's place when both families are named right), whatever family it
  names; ``alternative_places`` do not count.
* strict_effect_accuracy, strict_location_accuracy: over ALL effect cases whose families are
  in the vocabulary (single and pair cases; a case with no finding counts as wrong), not only
  over the cases named right.  ``strict_effect_accuracy.<family>`` and
  ``strict_location_accuracy.<family>``: over that family's single cases;
  min_family_accuracy: the smallest ``strict_effect_accuracy.<family>``.
* lenient_effect_accuracy / lenient_location_accuracy: the development sets' judge (every
  hidden family named, a stated alternative and coulomb_friction/stiction counting, no
  finding of a family not hidden; a place listed in alternative_places counting), over the
  same cases.
* outside_reported_unexplained: outside-vocabulary cases with an ``unexplained`` entry and
  no finding, over all outside cases; ``outside_reported_unexplained.<kind>``: per place
  kind of the outside effect (chamber, joint, supply, actuator), with ``outside_cases.<kind>``.
* silent_miss_rate: cases with neither a finding nor an ``unexplained`` entry, over every
  non-null case (outside ones included).
* null_false_discovery_rate: null cases with any finding OR any ``unexplained`` entry.
* median_heldout_nrmse_reduction_in_regime: 1 - after / before of every finding's
  ``heldout_nrmse_in_regime``, every case (null and outside cases too).
* calibration_of_inclusion: among all findings with inclusion_probability >= 0.9, the
  fraction that is right (its effect is a hidden family exactly and its ``where`` that
  effect's place exactly); ``calibration_count`` is how many there were;
  calibration_of_inclusion_lenient counts alternatives, alternative places and the friction
  leniency (``same``).

Cases the generator failed to make (``generator_error`` in their row: a recording its
integrator left non-finite) are invalid: left out of every metric, counted in
``generator_errors`` and listed in ``generator_error_seeds`` (comma-separated).

doctor_errors counts the cases where the doctor failed (they count as cases with no finding
and no unexplained entry); concealed_fraction is the fraction of non-null cases the generator
concealed as it aims to (the rows' ``concealed``, where known).

A ratio whose denominator is empty (e.g. no outside case) is left out of the metrics; the
counts (``*_cases``, ``calibration_count``) are always there.
"""
from __future__ import annotations

import json

import numpy as np

OUTSIDE = "outside_vocabulary"
#: inclusion probability above which a finding is counted in calibration_of_inclusion
CONFIDENT = 0.9


def case_kind(families: list[str]) -> str:
    """"null" (no hidden effect), "outside" (an effect outside the vocabulary among them),
    "single" or "pair"."""
    fams = [f for f in families if f != "none"]
    if not fams:
        return "null"
    if OUTSIDE in fams:
        return "outside"
    return "single" if len(fams) == 1 else "pair"


def place_kind(where: dict) -> str:
    """"chamber", "actuator", "joint" or "supply": the kind of place a ``where`` names."""
    return "chamber" if "chamber" in where else next(k for k in ("supply", "joint", "actuator") if k in where)


def _key(where: dict) -> str:
    return json.dumps(where, sort_keys=True)


def _same_multiset(a: list, b: list) -> bool:
    return len(a) == len(b) and sorted(a) == sorted(b)


def strict_effect_right(row: dict) -> bool:
    """The first finding (a pair: the first two) names exactly the hidden families."""
    hidden = [e["family"] for e in row["effects"]]
    named = [f["effect"] for f in row["findings"][:len(hidden)]]
    return _same_multiset(named, hidden)


def strict_location_right(row: dict) -> bool:
    """The first finding's place (a pair: the first two places) is exactly the hidden place;
    a pair named right must also put each family at its own place (not the two swapped)."""
    n = len(row["effects"])
    if strict_effect_right(row):
        hidden = [e["family"] + _key(e["where"]) for e in row["effects"]]
        named = [f["effect"] + _key(f["where"]) for f in row["findings"][:n]]
    else:
        hidden = [_key(e["where"]) for e in row["effects"]]
        named = [_key(f["where"]) for f in row["findings"][:n]]
    return _same_multiset(named, hidden)


def finding_right(finding: dict, effects: list[dict], same=None) -> bool:
    """A finding is right when its effect is one of the hidden families and its place is that
    effect's place (strict: ``same`` None, exact names and place; else ``same(named, hidden)``
    with the finding's alternatives and alternative_places counting)."""
    if same is None:
        return any(finding["effect"] == e["family"] and finding["where"] == e["where"] for e in effects)
    names = [finding["effect"], *finding.get("alternatives", [])]
    places = [finding["where"], *finding.get("alternative_places", [])]
    return any(any(same(n, e["family"]) for n in names) and e["where"] in places for e in effects)


def nrmse_reduction_in_regime(finding: dict) -> float | None:
    """1 - after / before of the finding's held-out NRMSE inside its regime (None: not given)."""
    n = finding.get("heldout_nrmse_in_regime")
    if not n or not n.get("before") or n.get("after") is None:
        return None
    return 1.0 - n["after"] / n["before"]


def _mean(values: list) -> float | None:
    """The mean (of flags: the fraction true); None for no values (left out of the metrics)."""
    return float(np.mean(values)) if values else None


def calibration(rows: list[dict], same=None) -> tuple[float | None, int]:
    """(fraction right, count) of the findings with inclusion_probability >= CONFIDENT."""
    sure = [(f, r["effects"]) for r in rows for f in r["findings"]
            if (f.get("inclusion_probability") or 0.0) >= CONFIDENT]
    return _mean([finding_right(f, eff, same) for f, eff in sure]), len(sure)


def family_metrics(rows: list[dict], families: list[str]) -> dict:
    """strict_effect_accuracy.<family> / strict_location_accuracy.<family> over each family's
    single cases, and min_family_accuracy (families without a case left out)."""
    out = {}
    for fam in families:
        single = [r for r in rows if r["kind"] == "single" and r["effects"][0]["family"] == fam]
        if single:
            out[f"strict_effect_accuracy.{fam}"] = _mean([strict_effect_right(r) for r in single])
            out[f"strict_location_accuracy.{fam}"] = _mean([strict_location_right(r) for r in single])
    per_family = [v for k, v in out.items() if k.startswith("strict_effect_accuracy.")]
    if per_family:
        out["min_family_accuracy"] = min(per_family)
    return out


def outside_metrics(rows: list[dict]) -> dict:
    """outside_reported_unexplained over all outside cases and per place kind of the effect
    outside the vocabulary (``outside_reported_unexplained.<kind>``, ``outside_cases.<kind>``)."""
    outside = [r for r in rows if r["kind"] == "outside"]
    reported = lambda r: bool(r["unexplained"]) and not r["findings"]  # noqa: E731
    out = {"outside_reported_unexplained": _mean([reported(r) for r in outside])}
    kinds = {}
    for r in outside:
        for e in r["effects"]:
            if e["family"] == OUTSIDE:
                kinds.setdefault(place_kind(e["where"]), []).append(reported(r))
    for kind, flags in sorted(kinds.items()):
        out[f"outside_cases.{kind}"] = len(flags)
        out[f"outside_reported_unexplained.{kind}"] = _mean(flags)
    return out


def generalization_metrics(rows: list[dict], families: list[str], same=None) -> dict:
    """Every metric of the module docstring from the case rows; ``families``: the vocabulary
    families of the plan (for the per-family values); ``same``: the lenient family match."""
    invalid = [r for r in rows if r.get("generator_error")]
    rows = [r for r in rows if not r.get("generator_error")]
    by = {k: [r for r in rows if r["kind"] == k] for k in ("null", "single", "pair", "outside")}
    effect = by["single"] + by["pair"]
    non_null = effect + by["outside"]
    reductions = [x for r in rows for f in r["findings"] if (x := nrmse_reduction_in_regime(f)) is not None]
    cal, n_cal = calibration(rows)
    cal_lenient, _ = calibration(rows, same or (lambda a, b: a == b))
    m = {
        "cases": len(rows), "single_cases": len(by["single"]), "pair_cases": len(by["pair"]),
        "null_cases": len(by["null"]), "outside_cases": len(by["outside"]),
        "strict_effect_accuracy": _mean([strict_effect_right(r) for r in effect]),
        "strict_location_accuracy": _mean([strict_location_right(r) for r in effect]),
        "pair_strict_effect_accuracy": _mean([strict_effect_right(r) for r in by["pair"]]),
        "lenient_effect_accuracy": _mean([bool(r["lenient_effect_ok"]) for r in effect]),
        "lenient_location_accuracy": _mean([bool(r["lenient_location_ok"]) for r in effect]),
        **outside_metrics(rows),
        "silent_miss_rate": _mean([not r["findings"] and not r["unexplained"] for r in non_null]),
        "null_false_discovery_rate": _mean([bool(r["findings"] or r["unexplained"]) for r in by["null"]]),
        "median_heldout_nrmse_reduction_in_regime": float(np.median(reductions)) if reductions else None,
        "findings_with_in_regime_nrmse": len(reductions),
        "calibration_of_inclusion": cal, "calibration_of_inclusion_lenient": cal_lenient, "calibration_count": n_cal,
        "doctor_errors": sum(bool(r.get("doctor_error")) for r in rows),
        "generator_errors": len(invalid), "generator_error_seeds": ",".join(str(r["seed"]) for r in invalid),
        "concealed_fraction": _mean([bool(r["concealed"]) for r in non_null if r.get("concealed") is not None]),
        "seconds_per_case": _mean([r["seconds"] for r in rows]),
        "generate_seconds_per_case": _mean([r["generate_seconds"] for r in rows]),
        **family_metrics(rows, families),
    }
    return {k: v for k, v in m.items() if v is not None}
