"""The doctor on fresh cases of the random-form generator: arm2 recordings made by the
independent variant simulator (:mod:`scenarios._variantsim`, no pneumasim code) whose hidden
effects take a functional form drawn at random per case, at a random place, concealed as the
development sets are; every family of the vocabulary four times, null cases, pairs that
interact (a supply effect beside a chamber effect, a mechanical beside a pneumatic one) and
effects outside the vocabulary (at a chamber, a joint and the supply), which the doctor
must report as ``unexplained``.

Honest evaluation: without a given seed, the base seed is drawn from the operating system's
entropy when the run starts, so every full run is an evaluation on seeds nobody has looked
at (``seed_source`` "fresh"; case lines are then not printed); ``PNEUMASIM_GENERALIZATION_SEED=N``
gives the base seed of a development run ("given").  Case ``i`` of the plan uses seed
``seed_base + i``.  ``--fast`` (in CI) runs four cases (a null, a single, a pair, an outside effect) of FAST_SECONDS + FAST_HELDOUT_SECONDS on fixed seeds.

Metrics: strict first (the first-named effect, the single place named), the lenient judge of
the development sets as a second column; definitions in :mod:`scenarios._generalization_metrics`
(strict_effect_accuracy, strict_location_accuracy, lenient_effect_accuracy,
min_family_accuracy, outside_reported_unexplained, silent_miss_rate,
null_false_discovery_rate, median_heldout_nrmse_reduction_in_regime,
calibration_of_inclusion, seconds_per_case: the doctor's time, not the generator's), plus
seed_base, seeds, seed_source and a strict confusion matrix.  Each case's recordings, truth
and the doctor's report.json / report.md stay in ``<out>/cases/case_<seed>/``; cases.json has
one row per case.  Resumable: an interrupted run resumed into the same ``--out`` keeps its
seeds (``seed.json`` in the unfinished folder) and its finished cases.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from identification.doctor.valve_arm.diagnose import diagnose
from identification.doctor.valve_arm.report import write as write_report
from pneumatics.effects import VOCABULARY
from pneumatics.errors import ConfigError, PneumasimError
from pneumatics.io import atomic_write_json
from pneumatics.recording import read_csv
from pneumatics.robot import load_robot
from workflow.sweep import options_from_env, raise_on_failure, sweep

from ._benchmark import confusion_matrix, fresh_seed_base, plot_confusion, remember_seed_base, stored_seed_base
from ._generalization_metrics import OUTSIDE, case_kind, generalization_metrics, strict_effect_right, strict_location_right
from ._variantsim.cases import GeneratorError, make_case
from .common import main
from .doctor_blind_benchmark import judge, same_family

SUMMARY = "mismatch finder on fresh random-form cases (strict scores, outside-vocabulary effects, calibration)"
#: its sweep's finished cases are kept when a run is interrupted; a rerun into the same --out
#: resumes them (pneumatics.io.OutputFolder, resumable), with the seeds it drew (seed.json)
RESUMABLE = True

#: the vocabulary without force_sensor_offset: arm2 has no force sensor
FAMILIES = tuple(f for f in VOCABULARY if f != "force_sensor_offset")
SINGLES_PER_FAMILY = 4
NULLS = 6
OUTSIDES = 6
#: supply beside chamber effects; mechanical beside pneumatic ones
PAIRS = (("supply_droop", "valve_leak"), ("supply_droop", "valve_lag"), ("coulomb_friction", "valve_hysteresis"),
         ("piston_leak", "angle_sensor_offset"), ("stiction", "external_leak"), ("backlash", "heat_transfer"),
         ("end_stop", "line_dynamics"), ("viscous_friction", "pressure_sensor_offset"))
FAST_PLAN = ([], ["pressure_sensor_offset"], ["supply_droop", "valve_hysteresis"], [OUTSIDE])
FAST_SEED_BASE = 16000
#: the --fast cases' recordings [s]: a check that every part of the run works and writes its
#: metrics (its answers are not asserted), kept short for CI's 15 minutes
FAST_SECONDS, FAST_HELDOUT_SECONDS = 10.0, 5.0
SEED_ENV = "PNEUMASIM_GENERALIZATION_SEED"


def plan(fast: bool, seed_base: int) -> tuple[list[dict], float, float]:
    """Every case's hidden ``families`` and ``forms`` (None: the generator draws them), main
    and held-out recording seconds.  Full: every family SINGLES_PER_FAMILY times (one round
    of all families after the other), the nulls, the pairs, the outside-vocabulary effects
    (at a chamber, a joint and the supply, :func:`outside_forms`)."""
    if fast:
        return [{"families": list(f), "forms": None} for f in FAST_PLAN], FAST_SECONDS, FAST_HELDOUT_SECONDS
    cases = [[fam] for _ in range(SINGLES_PER_FAMILY) for fam in FAMILIES]
    cases += [[] for _ in range(NULLS)] + [list(p) for p in PAIRS]
    cases = [{"families": fams, "forms": None} for fams in cases]
    cases += [{"families": [OUTSIDE], "forms": None if form is None else [form]}
              for form in outside_forms(np.random.default_rng(seed_base))]
    return cases, 60.0, 30.0


def outside_forms(rng: np.random.Generator) -> list[str | None]:
    """OUTSIDES outside-vocabulary forms spread evenly over the place kinds chamber, joint and
    supply, two different forms of each kind drawn with ``rng`` where the generator's form
    registry (``_variantsim.forms.FORMS``: family -> forms with ``name`` and place ``kind``)
    has them; None each (the generator draws form and place) without one."""
    try:
        from ._variantsim.forms import FORMS
    except ImportError:
        return [None] * OUTSIDES
    kinds = ("chamber", "joint", "supply")
    by_kind = {k: [f.name for f in FORMS.get(OUTSIDE, []) if f.kind == k] for k in kinds}
    out = []
    for i in range(OUTSIDES):
        names = by_kind[kinds[i % len(kinds)]]
        if not names:
            out.append(None)
            continue
        pick = names[int(rng.integers(len(names)))]
        if len(names) > 1:  # the next draw at this kind takes another form
            names.remove(pick)
        out.append(pick)
    return out


def choose_seed_base(out: Path, fast: bool) -> tuple[int, str]:
    """(base seed, "given" | "fresh"): the environment's ``PNEUMASIM_GENERALIZATION_SEED``; else
    the seed an unfinished run into this folder drew (``seed.json``, no metrics.json yet); else
    the fixed --fast base; else a fresh one from the operating system's entropy."""
    given = os.environ.get(SEED_ENV)
    if given is not None:
        try:
            return int(given), "given"
        except ValueError:
            raise ConfigError(f"{SEED_ENV}={given!r}: expected a whole number (the base seed)") from None
    if fast:
        return FAST_SEED_BASE, "given"
    return stored_seed_base(out) or (fresh_seed_base(), "fresh")


def generator_unknown(names) -> list[str]:
    """The family names the variant generator cannot draw (asked through its own draw), so
    that a run fails before it starts instead of case by case; empty when its API cannot be
    asked (make_case then decides per case)."""
    from ._variantsim import cases as generator

    unknown = []
    for name in dict.fromkeys(names):
        try:
            generator.draw_effects(np.random.default_rng(0), [name])
        except (ValueError, KeyError):
            unknown.append(name)
        except (TypeError, AttributeError):
            return []
    return unknown


def _unknown_error(names, detail: str = "") -> PneumasimError:
    return PneumasimError(f"doctor_generalization_benchmark: the variant generator (scenarios._variantsim) cannot "
                          f"make {', '.join(repr(n) for n in names)}{detail}; this benchmark needs the random-form "
                          f"generator, which draws every vocabulary family but force_sensor_offset and "
                          f"{OUTSIDE!r}")


def _make(folder: Path, case: dict) -> dict:
    # forms only when chosen: a generator without form choice takes no ``forms``
    forms = {"forms": case["forms"]} if case.get("forms") else {}
    try:
        return make_case(folder, case["seed"], case["families"], seconds=case["seconds"],
                         heldout_seconds=case["heldout_seconds"], name=folder.name, **forms)
    except ValueError as e:
        if "unknown" in str(e):
            raise _unknown_error(case["families"], f" ({e})") from None
        raise


def _effect_row(e: dict) -> dict:
    """A truth effect as the row keeps it: today's generator has no "form"/"source" (its
    "kind" is the form)."""
    return {"family": e["family"], "where": e["where"], "form": e.get("form", e.get("kind")),
            "source": e.get("source"), "place_kind": next(iter(e["where"]), None)}


def _finding_row(f: dict) -> dict:
    keys = ("effect", "form", "where", "regime", "alternatives", "alternative_places", "inclusion_probability",
            "heldout_nrmse", "heldout_nrmse_in_regime")
    return {k: f.get(k) for k in keys}


def _diagnose(truth: dict, folder: Path) -> tuple[dict, str | None]:
    """The doctor on the case's CSV files, its report written beside them.  A doctor that
    fails on a case has named nothing there: the case counts as missed (and the error is kept
    in its row) instead of stopping an evaluation run whose seeds must not be drawn again."""
    try:
        report = diagnose(load_robot("arm2"), [read_csv(truth["recordings"]["main"])],
                          [read_csv(truth["recordings"]["heldout"])])
        write_report(report, folder, robot=None, rerun=False)
        return report, None
    except Exception as e:  # noqa: BLE001 - any failure of the doctor is a miss of this case
        return {"verdict": "doctor_error", "findings": [], "unexplained": []}, f"{type(e).__name__}: {e}"


def generalization_case(case: dict) -> dict:
    """Make one case's recordings into its folder, run the doctor on the CSV files, keep its
    report beside the truth, return the case's row (scenarios._generalization_metrics)."""
    folder = Path(case["out"]) / f"case_{case['seed']}"
    t0 = time.perf_counter()
    try:
        truth = _make(folder, case)
    except GeneratorError as e:  # the generator's failure, not the doctor's: an invalid case
        return {"index": case["index"], "seed": case["seed"], "case": folder.name, "kind": case_kind(case["families"]),
                "families": case["families"] or ["none"], "generator_error": str(e), "effects": [], "findings": [],
                "unexplained": [], "seconds": None, "generate_seconds": time.perf_counter() - t0}
    gen_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    report, error = _diagnose(truth, folder)
    secs = time.perf_counter() - t0
    lenient = judge(truth, report)
    c = truth.get("concealment", {})
    seen = truth.get("heldout_visibility") or {}  # the same measure on the held-out recording
    return {"index": case["index"], "seed": case["seed"], "case": folder.name, "folder": f"cases/{folder.name}",  # in --out
            "kind": case_kind(case["families"]), "families": case["families"] or ["none"],
            "generator": truth.get("generator"), "effects": [_effect_row(e) for e in truth["effects"]],
            "scale": c.get("scale", 1.0), "effect_scales": c.get("effect_scales"),
            "generator_min_r2": c.get("min_r2"), "concealed": c.get("concealed"),
            "heldout_min_r2": seen.get("min_r2"), "heldout_regime_fraction": seen.get("regime_fraction"),
            "verdict": report["verdict"], "doctor_error": error,
            "findings": [_finding_row(f) for f in report["findings"]],
            "unexplained": [{"where": u.get("where"), "regime": u.get("regime"),
                             "share_of_residual": u.get("share_of_residual")} for u in report["unexplained"]],
            "lenient_effect_ok": lenient["family_ok"], "lenient_location_ok": lenient["location_ok"],
            "seconds": secs, "generate_seconds": gen_s}


def run(ctx):
    base, source = choose_seed_base(ctx.out, ctx.fast)
    cases, seconds, held_s = plan(ctx.fast, base)
    unknown = generator_unknown(f for c in cases for f in c["families"])
    if unknown:
        raise _unknown_error(unknown)
    remember_seed_base(ctx.out, base, source)
    print(f"doctor_generalization_benchmark: {len(cases)} cases, seeds {base}..{base + len(cases) - 1} ({source})")
    results = sweep(generalization_case, [{**c, "index": i, "seed": base + i, "seconds": seconds,
                                           "heldout_seconds": held_s, "out": str(ctx.out / "cases")}
                                          for i, c in enumerate(cases)],
                    out=ctx.out / "sweep", **options_from_env())
    raise_on_failure(results, "doctor_generalization_benchmark")
    rows = [r.result for r in results]
    atomic_write_json(ctx.out / "cases.json", rows)
    if source == "given":  # an evaluation run's cases are not looked at one by one
        _print_cases(rows)
    _confusion(rows, ctx, source)
    metrics = generalization_metrics(rows, list(FAMILIES), lambda a, b: same_family(a, b, False))
    return {**metrics, "seed_base": base, "seeds": f"{base}..{base + len(rows) - 1}", "seed_source": source,
            "generator": ",".join(sorted({str(r["generator"]) for r in rows if not r.get("generator_error")}))}


def _print_cases(rows: list[dict]) -> None:
    for r in rows:
        if r.get("generator_error"):
            print(f"  {r['case']}: invalid, the generator failed: {r['generator_error']}")
            continue
        hidden = [f"{e['family']}({e['form']})@{'/'.join(str(v) for v in e['where'].values())}" for e in r["effects"]]
        named = [f"{f['effect']}@{'/'.join(str(v) for v in f['where'].values())}" for f in r["findings"]]
        judged = (f"strict effect {'ok' if strict_effect_right(r) else 'WRONG'}, "
                  f"location {'ok' if strict_location_right(r) else 'wrong'}") if r["kind"] in ("single", "pair") else r["kind"]
        print(f"  {r['case']}: hidden {hidden or '-'}; named {named or '-'}; unexplained {len(r['unexplained'])}; "
              f"{judged} ({r['seconds']:.0f} s)")


def _confusion(rows: list[dict], ctx, source: str) -> None:
    """Strict: a name counts only for the family it is; no finding but an unexplained entry
    goes on the "unexplained" column.  The title says whether the seeds were fresh (``source``,
    choose_seed_base's) or given (development seeds, --fast's among them)."""
    hidden = list(FAMILIES) + [OUTSIDE, "none"]
    cols = list(FAMILIES) + ["none", "unexplained", "other"]
    named = [{"families": r["families"],
              "named": [f["effect"] for f in r["findings"]] or (["unexplained"] if r["unexplained"] else [])}
             for r in rows if not r.get("generator_error")]
    mat = confusion_matrix(named, hidden, cols)
    seeds = "fresh" if source == "fresh" else "development (given seeds)"
    plot_confusion(ctx, mat, hidden, cols, f"doctor on random-form cases, {seeds}: strict confusion matrix\n"
                   "(an extra finding beside a right one counts in its row too)")


if __name__ == "__main__":
    main(__name__)
