"""The doctor on effects in forms it was not written against: recordings of arm2 made by an
independent simulator (:mod:`scenarios._variantsim`, written from arm2.md and paper 002
only, no pneumasim code) whose hidden effects take other functional forms than pneumasim's
effect library (LuGre and Karnopp friction, Bouc-Wen valve hysteresis, a second-order spool,
laminar leaks, a two-volume line, flow-dependent heat transfer, a regulator reservoir, a
compliant dead zone, ...).  Concealed as the published truthsim cases are; one case per
family and seed, null cases (+-10 % parameter errors) and two-effect cases.

Metrics (as doctor_blind_benchmark, through :mod:`scenarios._benchmark`): effect_accuracy,
location_accuracy, median_heldout_nrmse_reduction, null_false_discovery_rate,
seconds_per_case, concealed_fraction; per family ``effect_ok.<family>`` and
``location_ok.<family>`` (fraction of that family's single-effect cases); a confusion matrix.
Each case's recordings, truth, and the doctor's report.json / report.md stay in
``<out>/cases/<case>/``.  ``PNEUMASIM_VARIANT_SEEDS=N`` runs N seeds per family (default 1).
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from identification.doctor.valve_arm.diagnose import diagnose
from identification.doctor.valve_arm.report import write as write_report
from pneumatics.io import atomic_write_json
from pneumatics.recording import read_csv
from pneumatics.robot import load_robot
from workflow.sweep import options_from_env, raise_on_failure, sweep

from ._benchmark import common_metrics, confusion_matrix, nrmse_reductions, plot_confusion, print_cases
from ._variantsim.cases import make_case
from ._variantsim.effects import FAMILIES
from .common import main
from .doctor_blind_benchmark import judge, same_family

SUMMARY = "mismatch finder on effects in other functional forms (independent variant simulator)"
#: its sweep's finished cases are kept when a run is interrupted; a rerun into the same --out
#: resumes them (pneumatics.io.OutputFolder, resumable)
RESUMABLE = True

PAIRS = (["coulomb_friction", "valve_hysteresis"], ["piston_leak", "angle_sensor_offset"])


def plan(fast: bool):
    if fast:
        return [(7101, []), (7102, ["coulomb_friction"]), (7103, ["valve_hysteresis"])], 30.0, 15.0
    # the first seed of every family, the nulls and the pairs come first, so that a run with
    # more seeds into the same --out resumes the cases of a run with fewer
    seeds = int(os.environ.get("PNEUMASIM_VARIANT_SEEDS", "1"))
    cases = [(7000 + i, [fam]) for i, fam in enumerate(FAMILIES)]
    n = 7000 + len(FAMILIES)
    cases += [(n, []), (n + 1, [])] + [(n + 2 + i, list(p)) for i, p in enumerate(PAIRS)]
    for rep in range(1, seeds):
        cases += [(7000 + 100 * rep + i, [fam]) for i, fam in enumerate(FAMILIES)]
    return cases, 60.0, 30.0


def variant_case(case: dict) -> dict:
    """Make one case's recordings (into its folder), run the doctor on the CSV files exactly
    as doctor_blind_benchmark does, keep its report beside the truth, judge it."""
    seed, fams = case["seed"], case["families"]
    name = f"variant_{seed}_{'+'.join(fams) or 'null'}"
    folder = Path(case["out"]) / name
    t0 = time.perf_counter()
    truth = make_case(folder, seed, fams, seconds=case["seconds"], heldout_seconds=case["heldout_seconds"], name=name)
    gen_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    report = diagnose(load_robot("arm2"), [read_csv(truth["recordings"]["main"])],
                      [read_csv(truth["recordings"]["heldout"])])
    secs = time.perf_counter() - t0
    write_report(report, folder, robot=None, rerun=False)
    report.pop("_replays", None)
    j = judge(truth, report)
    j_strict = judge(truth, report, strict=True)
    red, red_reg = nrmse_reductions(report["findings"]), nrmse_reductions(report["findings"], "heldout_nrmse_in_regime")
    c = truth["concealment"]
    return {"seed": seed, "case": name, "folder": f"cases/{name}", "families": fams or ["none"],  # in --out
            "forms": [e["kind"] for e in truth["effects"]], "where": [e["where"] for e in truth["effects"]],
            "scale": c.get("scale", 1.0), "generator_min_r2": c.get("min_r2"),
            "generator_max_regime_snr": c.get("max_regime_rms_over_noise"),
            "verdict": report["verdict"], "named": j["named"],
            "named_where": [f["where"] for f in report["findings"]],
            "alternatives": [f.get("alternatives", []) for f in report["findings"]],
            "family_ok": j["family_ok"], "family_ok_strict": j_strict["family_ok"],
            "location_ok": j["location_ok"], "location_ok_strict": j_strict["location_ok"],
            "nrmse_reduction": red, "nrmse_reduction_in_regime": red_reg, "seconds": secs, "generate_seconds": gen_s,
            "min_r2_calibrated": min(report["baseline"]["heldout_r2"].values()),
            "unexplained": [{"where": u["where"], "regime": u["regime"]} for u in report["unexplained"]]}


def run(ctx):
    cases, seconds, held_s = plan(ctx.fast)
    results = sweep(variant_case, [{"seed": s, "families": f, "seconds": seconds, "heldout_seconds": held_s,
                                    "out": str(ctx.out / "cases")} for s, f in cases],
                    out=ctx.out / "sweep", **options_from_env())
    raise_on_failure(results, "doctor_variant_benchmark")
    rows = [r.result for r in results]
    print_cases(rows)
    for r in rows:
        where = ["/".join(str(v) for v in w.values()) for w in r["where"]]
        named = [f"{n}@{'/'.join(str(v) for v in w.values())}" for n, w in zip(r["named"], r["named_where"])]
        red = ", ".join(f"{x:.2f}" for x in r["nrmse_reduction"])
        print(f"    {r['case']}: hidden {r['forms']} at {where} scale {r['scale']:.3g}; named {named or '-'}; "
              f"family {'ok' if r['family_ok'] else 'WRONG'}, location {'ok' if r['location_ok'] else 'wrong'}; "
              f"nrmse reduction [{red}]; unexplained {r['unexplained'] or '-'}")
    atomic_write_json(ctx.out / "cases.json", rows)
    _confusion(rows, ctx)
    effect_rows = [r for r in rows if r["families"] != ["none"]]
    fam_ok = [r for r in effect_rows if r["family_ok"]]
    metrics = {
        **common_metrics(rows, "min_r2_calibrated"),
        "effect_accuracy_strict": sum(r["family_ok_strict"] for r in effect_rows) / max(len(effect_rows), 1),
        "location_accuracy_strict": sum(r["location_ok_strict"] for r in fam_ok) / max(len(fam_ok), 1),
        "generate_seconds_per_case": float(np.mean([r["generate_seconds"] for r in rows])),
    }
    for fam in FAMILIES:
        single = [r for r in effect_rows if r["families"] == [fam]]
        if single:
            metrics[f"effect_ok.{fam}"] = float(np.mean([r["family_ok"] for r in single]))
            metrics[f"location_ok.{fam}"] = float(np.mean([r["location_ok"] for r in single]))
    return metrics


def _confusion(rows, ctx):
    fams = list(FAMILIES) + ["none"]
    cols = fams + ["other"]
    mat = confusion_matrix(rows, fams, cols, lambda n, t: same_family(n, t, False))
    plot_confusion(ctx, mat, fams, cols, "doctor on the variant simulator (other functional forms): confusion matrix\n"
                   "(an extra finding beside a right one counts in its row too)")


if __name__ == "__main__":
    main(__name__)
