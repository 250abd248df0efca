"""The jet-pipe doctor on concealed effects (issue 4: "and of the jetpipe actuator"): recordings
of the actuator on its stopper under force control, each with one hidden effect drawn from a
seed (family, place, magnitude; scenarios/_jetpipe_cases.py), +-3 % errors in the calibrated
nominal parameters and sensor noise, plus null cases and cases with two effects of different
families (concealed together), scored as scenarios/doctor_blind_benchmark.py scores arm2's.  The doctor
(identification/doctor/jetpipe/diagnose.py) sees only the CSV files; its answers are compared with
the truth.

Metrics: effect_accuracy (effect cases whose named families are exactly the hidden ones, an
isolability alternative counting), two_effect_accuracy (the same over the two-effect cases
alone), location_accuracy (where, for every hidden effect, among cases with the families
right; a place the doctor lists as not separable counts), median_heldout_nrmse_reduction (on
each finding's channel, whole held-out file), median_heldout_nrmse_reduction_in_regime (the
same inside the regime bin where the finding's improvement concentrates),
null_false_discovery_rate (null cases with any finding or unexplained residual),
seconds_per_case (the doctor alone), concealed_fraction, median_inclusion_probability.

Cases run through :func:`workflow.sweep.sweep` (``PNEUMASIM_WORKERS=N``, ``PNEUMASIM_BACKEND``);
finished cases are kept in ``<out>/sweep/cases/`` (a rerun resumes).
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from identification.doctor.jetpipe.diagnose import diagnose_jetpipe
from pneumatics.io import atomic_write_json
from pneumatics.recording import read_csv
from workflow.sweep import options_from_env, raise_on_failure, sweep

from ._benchmark import common_metrics, confusion_matrix, nrmse_reductions, plot_confusion, print_cases
from ._benchmark import judge as judge_effects
from ._jetpipe_cases import FAMILIES, make_case
from .common import main

SUMMARY = "jet-pipe mismatch finder on concealed effects: confusion matrix, accuracy, false discoveries"
#: its sweep's finished cases are kept when a run is interrupted; a rerun into the same --out
#: resumes them (pneumatics.io.OutputFolder, resumable)
RESUMABLE = True


#: two-effect cases: families that act on different things (a sensor and a flow, the valve and
#: the supply, the valve's memory and a transducer)
PAIRS = (["external_leak", "force_sensor_offset"], ["valve_lag", "supply_droop"],
         ["valve_hysteresis", "pressure_sensor_offset"])


def plan(fast: bool):
    """[(seed, [families])], main seconds, held-out seconds."""
    if fast:
        return [(201, []), (202, ["force_sensor_offset"]), (203, ["external_leak"])], 5.0, 3.0
    cases, seed = [], 2000
    for fam in FAMILIES:
        for _ in range(3):
            cases.append((seed, [fam]))
            seed += 1
    cases += [(seed + k, []) for k in range(3)]
    seed += 3
    cases += [(seed + k, list(pair)) for k, pair in enumerate(PAIRS)]
    return cases, 20.0, 10.0


def judge(truth: dict, report: dict) -> dict:
    """Every hidden family named (or listed as a not-separable alternative) at its place, and no
    finding of a family that was not hidden; a null case: no finding and nothing unexplained."""
    named = [f["effect"] for f in report["findings"]]
    if not truth["effects"]:
        return {"family_ok": not report["findings"] and not report["unexplained"], "location_ok": True, "named": named}
    return judge_effects(truth["effects"], report)


def blind_case(case: dict) -> dict:
    """One case (in any sweep worker): make the recordings, run the doctor on the CSVs, judge."""
    seed, fams = case["seed"], case["families"]
    with tempfile.TemporaryDirectory(prefix="blind_jetpipe_") as work:
        truth = make_case(Path(work), seed, fams or None, seconds=case["seconds"], heldout_seconds=case["heldout_seconds"])
        t0 = time.perf_counter()
        report = diagnose_jetpipe("jetpipe", [read_csv(truth["recordings"]["main"])],
                                  [read_csv(truth["recordings"]["heldout"])])
        secs = time.perf_counter() - t0
    report.pop("_plot", None)
    j = judge(truth, report)
    red, red_reg = nrmse_reductions(report["findings"]), nrmse_reductions(report["findings"], "heldout_nrmse_in_regime")
    return {"seed": seed, "families": fams or ["none"], "where": [e["where"] for e in truth["effects"]],
            "truth": truth["effects"], "verdict": report["verdict"], "named": j["named"],
            "findings": [{k: f[k] for k in ("effect", "where", "parameters", "alternatives", "alternative_places",
                                            "regime", "inclusion_probability")} for f in report["findings"]],
            "family_ok": j["family_ok"], "location_ok": j["location_ok"], "nrmse_reduction": red,
            "nrmse_reduction_in_regime": red_reg, "seconds": secs,
            "min_r2_nominal": min(truth["r2_nominal_heldout"].values()),
            "unexplained": [u["where"] for u in report["unexplained"]]}


def run(ctx):
    cases, seconds, held_s = plan(ctx.fast)
    results = sweep(blind_case, [{"seed": s, "families": f, "seconds": seconds, "heldout_seconds": held_s}
                                 for s, f in cases], out=ctx.out / "sweep", **options_from_env())
    raise_on_failure(results, "doctor_blind_benchmark_jetpipe")
    rows = [r.result for r in results]
    print_cases(rows)
    atomic_write_json(ctx.out / "cases.json", rows)
    _confusion(rows, ctx)
    incl = [f["inclusion_probability"] for r in rows for f in r["findings"]]
    return {
        **common_metrics(rows, "min_r2_nominal"),
        "median_inclusion_probability": float(np.median(incl)) if incl else float("nan"),
    }


def _confusion(rows, ctx):
    fams = list(FAMILIES) + ["none"]
    cols = fams + ["unexplained"]
    # a finding that lists a hidden family as a not-separable alternative counts for it; a case
    # with no finding but unexplained residual is shown in the unexplained column
    named = [[next((t for t in r["families"] if t in [f["effect"], *f["alternatives"]]), f["effect"])
              for f in r["findings"]] or (["unexplained"] if r["unexplained"] else []) for r in rows]
    mat = confusion_matrix([{"families": r["families"], "named": n} for r, n in zip(rows, named)], fams, cols)
    plot_confusion(ctx, mat, fams, cols, "jet-pipe doctor blind benchmark: confusion matrix\n"
                   "(an extra finding beside a right one counts in its row too)")


if __name__ == "__main__":
    main(__name__)
