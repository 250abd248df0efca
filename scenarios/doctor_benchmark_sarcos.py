"""The hydraulic doctor on concealed effects of the SARCOS elbow (issue 17, item 4): recordings
of the free forearm under a position loop, each with hidden effects drawn from a seed
(scenarios/_sarcos_cases.py: family, place, magnitude), +-3 % errors in the nominal
parameters and sensor noise, plus null cases and pairs of effects of different families.  The
doctor (identification/doctor/hydraulic) sees only the CSV files; its answers are compared with
the truth.  By default a development set (base seed 3000: seeds looked at while the doctor was
developed); ``PNEUMASIM_SARCOS_SEED=N`` gives another base seed, and ``PNEUMASIM_SARCOS_SEED=fresh``
draws one from the operating system's entropy when the run starts, an evaluation on seeds
nobody has looked at (``seed_source`` "fresh" in metrics.json).

Strict metrics (no not-separable alternative counts):

* ``strict_effect_accuracy``: effect cases whose *first-named* family is a hidden one, every
  hidden family named as a finding and no other family named;
* ``strict_location_accuracy``: among those, every hidden effect found at its exact place;
* ``null_false_discovery_rate``: null cases with any finding or unexplained residual;
* ``silent_miss_rate``: effect cases with neither a finding nor an unexplained residual;
* ``median_heldout_nrmse_reduction`` (each finding's channel), ``seconds_per_case`` (the
  doctor alone), ``accuracy.<family>`` (strict, per hidden family), ``seeds``, ``seed_base``,
  ``seed_source`` ("development", "given" or "fresh").

Cases run through :func:`workflow.sweep.sweep` (``PNEUMASIM_WORKERS=N``); finished cases are
kept in ``<out>/sweep/cases/`` (a rerun resumes).
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from identification.doctor.hydraulic.diagnose import diagnose_hydraulic
from pneumatics.io import atomic_write_json
from pneumatics.recording import read_csv
from workflow.sweep import options_from_env, raise_on_failure, sweep

from ._benchmark import (confusion_matrix, nrmse_reductions, plot_confusion, print_cases, remember_seed_base,
                         seed_base_from_env)
from ._sarcos_cases import FAMILIES, make_case
from .common import main

SUMMARY = "hydraulic elbow mismatch finder on concealed effects: strict accuracy, false discoveries"
RESUMABLE = True

#: two-effect cases: families acting on different things (the valve and the vane's friction,
#: the supply and a transducer)
PAIRS = (["valve_hysteresis", "coulomb_friction"], ["supply_droop", "force_sensor_offset"])


#: braced recordings of every case (paper 001 §3.2.2: the load locked by the steel brace), to
#: fit and held out [s]: the experiment that shows the chambers' volumes and the shaft's stiffness
BRACED_SECONDS, BRACED_HELDOUT_SECONDS = 4.0, 3.0

SEED_ENV = "PNEUMASIM_SARCOS_SEED"
DEVELOPMENT_SEED_BASE = 3000


def seed_base(out=None) -> tuple[int, str]:
    """(base seed, "development" | "given" | "fresh") from ``PNEUMASIM_SARCOS_SEED``."""
    return seed_base_from_env(SEED_ENV, DEVELOPMENT_SEED_BASE, out)


def plan(fast: bool, base: int = DEVELOPMENT_SEED_BASE):
    """[(seed, [families])], main seconds, held-out seconds."""
    if fast:
        return [(301, []), (302, ["coulomb_friction"]), (303, ["pressure_sensor_offset"])], 8.0, 6.0
    cases, seed = [], base
    for fam in FAMILIES:
        for _ in range(2):
            cases.append((seed, [fam]))
            seed += 1
    cases += [(seed + k, []) for k in range(3)]
    seed += 3
    cases += [(seed + k, list(pair)) for k, pair in enumerate(PAIRS)]
    return cases, 8.0, 6.0


def judge(truth: dict, report: dict) -> dict:
    """Strict: the first finding's family hidden, every hidden family named as a finding (its
    place exactly the hidden one for location), no other family; a null case: nothing reported."""
    named = [f["effect"] for f in report["findings"]]
    hidden = [e["family"] for e in truth["effects"]]
    if not hidden:
        ok = not report["findings"] and not report["unexplained"]
        return {"family_ok": ok, "location_ok": ok, "named": named}
    family_ok = bool(named) and named[0] in hidden and set(hidden) <= set(named) and set(named) <= set(hidden)
    location_ok = all(any(f["effect"] == e["family"] and f["where"] == e["where"] for f in report["findings"])
                      for e in truth["effects"])
    return {"family_ok": family_ok, "location_ok": family_ok and location_ok, "named": named}


def blind_case(case: dict) -> dict:
    """One case (in any sweep worker): make the recordings, run the doctor on the CSVs, judge."""
    seed, fams = case["seed"], case["families"]
    with tempfile.TemporaryDirectory(prefix="sarcos_case_") as work:
        truth = make_case(Path(work), seed, fams or None, seconds=case["seconds"],
                          heldout_seconds=case["heldout_seconds"],
                          braced_seconds=BRACED_SECONDS, braced_heldout_seconds=BRACED_HELDOUT_SECONDS)
        files = truth["recordings"]
        t0 = time.perf_counter()
        report = diagnose_hydraulic("sarcos_elbow", [read_csv(files["main"]), read_csv(files["main_braced"])],
                                    [read_csv(files["heldout"]), read_csv(files["heldout_braced"])])
        secs = time.perf_counter() - t0
    report.pop("_plot", None)
    j = judge(truth, report)
    return {"seed": seed, "families": fams or ["none"], "truth": truth["effects"], "verdict": report["verdict"],
            "named": j["named"], "findings": [{k: f[k] for k in ("effect", "where", "parameters", "alternatives",
                                                                  "regime", "heldout_j")} for f in report["findings"]],
            "family_ok": j["family_ok"], "location_ok": j["location_ok"],
            "nrmse_reduction": nrmse_reductions(report["findings"]), "seconds": secs,
            "r2_nominal": truth["r2_nominal_heldout"], "unexplained": [u["where"] for u in report["unexplained"]]}


def metrics(rows: list[dict]) -> dict:
    effect_rows = [r for r in rows if r["families"] != ["none"]]
    null_rows = [r for r in rows if r["families"] == ["none"]]
    ok = [r for r in effect_rows if r["family_ok"]]
    reductions = [x for r in effect_rows for x in r["nrmse_reduction"]]
    out = {
        "cases": len(rows), "effect_cases": len(effect_rows), "null_cases": len(null_rows),
        "strict_effect_accuracy": len(ok) / max(len(effect_rows), 1),
        "strict_location_accuracy": sum(r["location_ok"] for r in ok) / max(len(ok), 1),
        "null_false_discovery_rate": sum(not r["family_ok"] for r in null_rows) / max(len(null_rows), 1),
        "silent_miss_rate": sum(not r["named"] and not r["unexplained"] for r in effect_rows) / max(len(effect_rows), 1),
        "median_heldout_nrmse_reduction": float(np.median(reductions)) if reductions else 0.0,
        "seconds_per_case": float(np.mean([r["seconds"] for r in rows])),
        "concealed_fraction": float(np.mean([min(r["r2_nominal"].values()) >= 0.9 for r in effect_rows])) if effect_rows else 1.0,
        "seeds": ",".join(str(r["seed"]) for r in rows),
    }
    for fam in FAMILIES:
        mine = [r for r in effect_rows if fam in r["families"]]
        if mine:
            out[f"accuracy.{fam}"] = sum(r["family_ok"] for r in mine) / len(mine)
    return out


def run(ctx):
    base, source = (301, "development") if ctx.fast else seed_base(ctx.out)
    remember_seed_base(ctx.out, base, source)
    cases, seconds, held_s = plan(ctx.fast, base)
    results = sweep(blind_case, [{"seed": s, "families": f, "seconds": seconds, "heldout_seconds": held_s}
                                 for s, f in cases], out=ctx.out / "sweep", **options_from_env())
    raise_on_failure(results, "doctor_benchmark_sarcos")
    rows = [r.result for r in results]
    if source != "fresh":  # a fresh run is reported as it comes, not case by case
        print_cases(rows)
    atomic_write_json(ctx.out / "cases.json", rows)
    fams = list(FAMILIES) + ["none"]
    cols = fams + ["unexplained"]
    named = [{"families": r["families"], "named": r["named"] or (["unexplained"] if r["unexplained"] else [])}
             for r in rows]
    plot_confusion(ctx, confusion_matrix(named, fams, cols), fams, cols,
                   "hydraulic elbow doctor benchmark: confusion matrix (strict)")
    return {**metrics(rows), "seed_base": base, "seed_source": source}


if __name__ == "__main__":
    main(__name__)
