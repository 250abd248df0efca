"""The arm doctor on concealed effects at random places of humanoid38 (issue 17, item 3): 76
chambers on 38 joints, each case a recording to fit and a held-out one under the calibrated
PIDF, with hidden effects drawn from a seed (scenarios/_humanoid_cases.py: family, place,
magnitude), +-3 % errors in the nominal valve areas, dead volumes and masses, and sensor
noise.  The doctor (identification/doctor/valve_arm) is given the nominal humanoid38 and the
two recordings; its answers are compared with the truth.

Plan (full): every family the registry can place on humanoid38 twice, 4 null cases and 3
pairs, 60 s + 30 s recordings, seeds from ``PNEUMASIM_HUMANOID_SEED``: unset, the development
base 7000; a number, that base; "fresh", a base drawn from the operating system's entropy when
the run starts (kept in seed.json for a resumed run; ``seed_source`` in metrics.json).
``--fast`` (CI): issue 17's example, a valve leaking near null (4e-8 m^2 at ``left_elbow``
chamber a, not concealed), on the left arm (humanoid38's 16 chambers of
_humanoid_cases.SUBSETS, the other joints locked), 20 s + 10 s, a fixed seed, and the left
arm's timing case, a null case whose findings and ``unexplained`` entries are counted
(``subset_null_entries.left_arm``).  A case of the whole robot takes the doctor four minutes on
a slow 2-core machine, more than CI's 15 minutes leave: the whole robot's cases of 20 s + 10 s
(the same example, a concealed leak (seed 702), a null (701) and a viscous friction (703)) are
slow tests.

Metrics: the strict ones of scenarios/_generalization_metrics.py (``strict_effect_accuracy``,
``strict_location_accuracy``: the first finding's place is exactly the hidden chamber or
joint, ``null_false_discovery_rate``, ``silent_miss_rate``, per family), the lenient ones of
the development sets, ``seconds_per_case`` (the doctor alone), ``generate_seconds_per_case``,
and ``peak_memory_mib`` (the largest of the cases' peaks: each case's resident high-water mark
in a worker process started for it, as a user runs one doctor per process -- recordings and
doctor together -- so that cases.json names the case that peaked).  doctor_time.png: the
doctor's seconds against the number of chambers: arm2 (4, a null case of the same lengths),
parts of humanoid38 with its other joints locked at the home pose (pneumatics.robot_subset: the
left arm 16, both arms 32, the upper body 48 chambers; a null case each, fixed seeds, its own
calibrated PIDF) and humanoid38 (76, every case).

Cases run through :func:`workflow.sweep.sweep` (``PNEUMASIM_WORKERS=N``), each in a fresh worker
process (``fresh_workers``: a warm worker keeps what its earlier cases left resident, which a
case's peak would count; ``PNEUMASIM_FRESH_WORKERS=0`` keeps the workers); finished cases are
kept in ``<out>/sweep/cases/`` (a rerun resumes).  Outputs: metrics.json, cases.json,
cases/<case>/report.json and truth.json.
"""
from __future__ import annotations

import resource
import time

import numpy as np

from pneumatics.io import atomic_write_json
from workflow.sweep import options_from_env, raise_on_failure, sweep

from ._benchmark import judge, print_cases, remember_seed_base, seed_base_from_env
from ._generalization_metrics import case_kind, generalization_metrics
from .common import main

SUMMARY = "arm doctor on concealed effects at random places of humanoid38: strict metrics, time"
RESUMABLE = True

SEED_ENV = "PNEUMASIM_HUMANOID_SEED"
#: two-effect cases: a chamber effect with a joint effect, a sensor with a valve, two joints' kinds
PAIRS = (["valve_leak", "coulomb_friction"], ["pressure_sensor_offset", "valve_hysteresis"],
         ["viscous_friction", "piston_leak"])
ARM2_CHAMBERS, HUMANOID_CHAMBERS = 4, 76
#: the parts of humanoid38 (_humanoid_cases.SUBSETS) timed on a null case for the plot; --fast: the first
TIMED_SUBSETS = ("left_arm", "arms", "upper_body")


DEVELOPMENT_SEED_BASE = 7000


#: the --fast cases' recordings [s]
FAST_SECONDS, FAST_HELDOUT_SECONDS = 20.0, 10.0
#: issue 17's example (a valve leaking near null at left_elbow chamber a; make_case's ``given``)
ISSUE_EXAMPLE = [{"family": "valve_leak", "place": "left_elbow.a", "parameters": {"leak_area_m2": 4e-8}}]
#: the --fast effect case: that example on the left arm alone
FAST_CASE = {"subset": "left_arm", "given": ISSUE_EXAMPLE}


def plan(fast: bool, seed: int = DEVELOPMENT_SEED_BASE) -> tuple[list, float, float]:
    """[(seed, [families])], main seconds, held-out seconds (full plan from base ``seed``; the
    --fast case takes FAST_CASE's part and effect)."""
    if fast:
        return [(702, ["valve_leak"])], FAST_SECONDS, FAST_HELDOUT_SECONDS
    from ._humanoid_cases import humanoid_families

    cases = []
    for fam in humanoid_families():
        cases += [(seed, [fam]), (seed + 1, [fam])]
        seed += 2
    cases += [(seed + k, []) for k in range(4)]
    seed += 4
    cases += [(seed + k, list(pair)) for k, pair in enumerate(PAIRS)]
    return cases, 60.0, 30.0


def _peak_mib() -> float:
    """The process's peak resident memory [MiB] (on Linux since the last _start_case_peak)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def _start_case_peak() -> None:
    """Start a case's own memory peak: Linux resets the process's resident high-water mark
    (VmHWM) when "5" is written to /proc/self/clear_refs (proc(5), since Linux 4.0); elsewhere
    nothing (then :func:`_case_peak_mib` falls back to the process's peak)."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass


def _case_peak_mib() -> float:
    """The peak resident memory since :func:`_start_case_peak` [MiB]: what one case needed in
    its worker (imports and JIT caches included; in a kept worker also whatever earlier cases
    left resident, which the benchmark's fresh workers avoid); the
    process's whole peak where /proc/self/status is not there."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024.0   # kB
    except OSError:
        pass
    return _peak_mib()


def humanoid_case(case: dict) -> dict:
    """One case (in any sweep worker): make the recordings, run the doctor, judge.  The case is
    of the whole robot or of its part ``case["subset"]`` (a key of _humanoid_cases.SUBSETS), its
    effects drawn from the seed or ``case["given"]`` (make_case)."""
    from identification.doctor.valve_arm.diagnose import diagnose

    from ._humanoid_cases import make_case, nominal_humanoid

    subset = case.get("subset")
    _start_case_peak()
    t0 = time.perf_counter()
    main_rec, held, truth = make_case(case["seed"], case["families"], case["seconds"], case["heldout_seconds"],
                                      subset=subset, given=case.get("given"))
    generate_s = time.perf_counter() - t0
    robot = nominal_humanoid(subset)
    t0 = time.perf_counter()
    report = diagnose(robot, [main_rec], [held])
    seconds = time.perf_counter() - t0
    for private in [k for k in report if k.startswith("_")]:  # replays and the fitted model: not JSON
        report.pop(private)
    lenient = judge(truth["effects"], report)
    detection = [effect_against_limit(e, report["diagnostics"]) for e in truth["effects"]]
    return {"case": f"case_{case['seed']}", "seed": case["seed"], "kind": case_kind(truth["families"]),
            "families": truth["families"], "effects": truth["effects"], "truth": truth,
            "verdict": report["verdict"], "named": [f["effect"] for f in report["findings"]],
            "findings": [_finding(f) for f in report["findings"]], "unexplained": report["unexplained"],
            "lenient_effect_ok": lenient["family_ok"], "lenient_location_ok": lenient["location_ok"],
            "detection": detection, "seconds": seconds, "generate_seconds": generate_s,
            "peak_memory_mib": _case_peak_mib(),
            "chambers": robot.tables.n_chambers, "subset": subset, "report": report}


#: a hidden effect's size as the doctor states its detection limits: family -> (its size from the
#: truth's parameters, [(the report's table of limits, the family whose limit it is set against)]);
#: the smallest limit any of them stated at the effect's place.  The output-error screen's limits
#: at the joints (``output_error_screen``, by joint or actuator: a pressure-sensor offset's is
#: stated on its cylinder's chamber a, the force it fakes, and used for either chamber) and the
#: pneumatic keep rule's at the chambers (``chamber_detection_limit``, chamber_limits.py, by
#: hypothesis.place_of).  A stiction's breakaway excess, what names it and not a Coulomb
#: friction, against the screen's limit of that excess (output_error_screen.breakaway_only): the
#: excess acts below the Stribeck velocity alone, and set against the Coulomb friction's limit
#: as a level of F_c + excess it was called over its limit where the recording could not show it
#: (a 0.03 N m excess moves humanoid38's replayed angles a fifteenth as much as a 0.03 N m
#: Coulomb level, development seed 7100).
JOINTS, CHAMBERS = "output_error_screen", "chamber_detection_limit"
TRUTH_SIZE = {
    "coulomb_friction": (lambda p: p["friction"]["coulomb_nm"], [(JOINTS, "coulomb_friction")]),
    "viscous_friction": (lambda p: p["friction"]["viscous_nm_s"], [(JOINTS, "viscous_friction")]),
    "stiction": (lambda p: p["friction"]["stiction_extra_nm"], [(JOINTS, "stiction")]),
    "angle_sensor_offset": (lambda p: p["angle_offset_rad"], [(JOINTS, "angle_sensor_offset")]),
    "pressure_sensor_offset": (lambda p: p["pressure_offset_pa"],
                               [(JOINTS, "pressure_sensor_offset"), (CHAMBERS, "pressure_sensor_offset")]),
    "valve_leak": (lambda p: p["valve_leak_m2"], [(CHAMBERS, "valve_leak")]),
    "external_leak": (lambda p: p["external_leak_m2"], [(CHAMBERS, "external_leak")]),
    "piston_leak": (lambda p: p["piston_leak_m2"], [(CHAMBERS, "piston_leak")]),
    "valve_hysteresis": (lambda p: p["valve_hysteresis_v"], [(CHAMBERS, "valve_hysteresis")]),
    "valve_lag": (lambda p: p["valve_lag_s"], [(CHAMBERS, "valve_lag")]),
    "line_dynamics": (lambda p: p["line_dynamics"]["delay_s"], [(CHAMBERS, "line_dynamics")]),
    "heat_transfer": (lambda p: p["heat_transfer"]["conductance_w_k"], [(CHAMBERS, "heat_transfer")]),
    "backlash": (lambda p: p["backlash"]["gap_rad"], [(CHAMBERS, "backlash")]),
    "supply_droop": (lambda p: p["supply_droop_pa_per_kg_s"] if not (p.get("supply_droop_pa_per_kg2_s2") or
                                                                     p.get("supply_droop_tau_s")) else None,
                     [(CHAMBERS, "supply_droop")]),
}
"""(a size of None: the effect is in another form than the one the limit is stated for -- a
supply whose droop is quadratic or low-passed; a stiction's size is its breakaway excess, what
tells it from a Coulomb friction, against the screen's limit of that excess)"""


def effect_against_limit(effect: dict, diagnostics: dict) -> dict:
    """{family, size, limit}: a hidden effect's size and the smallest one the doctor said these
    recordings could show at its place (TRUTH_SIZE's tables in the report's ``diagnostics``);
    limit None where the doctor stated none (a family it states none for, or the table was not
    made: the output-error screen does not run where the rigid body's calibration was kept)."""
    from identification.doctor.valve_arm.hypothesis import place_of

    fam, where = effect["family"], effect["where"]
    size_of, routes = TRUTH_SIZE.get(fam, (None, []))
    stated = []
    for table, screened in routes:
        limits = diagnostics.get(table, {}).get(screened, {}).get("detection_limit", {})
        key = (where.get("joint") or where.get("actuator")) if table == JOINTS else place_of(where)
        if limits.get(key) is not None and np.isfinite(limits[key]):
            stated.append(float(limits[key]))
    size = size_of(effect["parameters"]) if stated else None
    if size is None:
        return {"family": fam, "size": None, "limit": None}
    return {"family": fam, "size": abs(float(size)), "limit": min(stated)}


def below_limit_metrics(rows: list[dict]) -> dict:
    """How many effect cases the doctor could not have named on its own statement: silent cases
    every effect of which lies under the detection limit the doctor stated at its place, and
    effects with a stated limit that were under it; and whether the limits predict what it
    names: of the effects over their stated limit and of those under it, how many a finding
    names at their place (its family at its exact place, in any position).  An explanation
    beside the strict metrics, not a correction of them."""
    cases = [r for r in rows if r["effects"]]
    stated = [(d, finding_at(e, r["findings"])) for r in cases
              for e, d in zip(r["effects"], r.get("detection", [])) if d["limit"] is not None]
    silent = [r for r in cases if not r["findings"] and not r["unexplained"]]
    under = [r for r in silent if r.get("detection") and all(d["limit"] is not None and d["size"] < d["limit"]
                                                            for d in r["detection"])]
    over = [named for d, named in stated if d["size"] >= d["limit"]]
    below = [named for d, named in stated if d["size"] < d["limit"]]
    return {"effects_with_stated_detection_limit": len(stated),
            "effects_under_stated_detection_limit": len(below),
            "effects_under_stated_detection_limit_named_at_place": sum(below),
            "effects_over_stated_detection_limit_named_at_place": sum(over),
            "silent_cases_under_stated_detection_limit": len(under), "silent_cases": len(silent)}


def finding_at(effect: dict, findings: list[dict]) -> bool:
    """Whether one of ``findings`` names ``effect``'s family at its exact place."""
    return any(f["effect"] == effect["family"] and f["where"] == effect["where"] for f in findings)


def _finding(f: dict) -> dict:
    keys = ("effect", "where", "parameters", "alternatives", "alternative_places", "inclusion_probability",
            "heldout_nrmse", "heldout_nrmse_in_regime")
    return {k: f[k] for k in keys if k in f}


def arm2_timing_case(case: dict) -> dict:
    """The doctor's seconds on an arm2 null case of the same lengths (the plot's 4-chamber point)."""
    import tempfile
    from pathlib import Path

    from identification.doctor.valve_arm.diagnose import diagnose
    from pneumatics.recording import read_csv
    from pneumatics.robot import load_robot

    from ._cases import make_case

    _start_case_peak()
    with tempfile.TemporaryDirectory(prefix="arm2_timing_") as work:
        truth = make_case(Path(work), case["seed"], [], seconds=case["seconds"],
                          heldout_seconds=case["heldout_seconds"])
        recs = {part: read_csv(path) for part, path in truth["recordings"].items()}
        t0 = time.perf_counter()
        diagnose(load_robot("arm2"), [recs["main"]], [recs["heldout"]])
        seconds = time.perf_counter() - t0
    return {"chambers": ARM2_CHAMBERS, "seconds": seconds, "peak_memory_mib": _case_peak_mib()}


def subset_timing_case(case: dict) -> dict:
    """The doctor's seconds on a null case of a part of humanoid38 (``case["subset"]``, a key of
    _humanoid_cases.SUBSETS: the other joints locked), of the same lengths: the plot's points
    between arm2 and the whole robot."""
    row = humanoid_case({**case, "families": []})
    return {k: row[k] for k in ("subset", "chambers", "seconds", "peak_memory_mib", "findings", "unexplained")}


def sweep_case(case: dict) -> dict:
    """The sweep's function: a humanoid38 case, a subset's or the arm2 timing case."""
    if case.get("arm2_timing"):
        return arm2_timing_case(case)
    return humanoid_case(case) if "families" in case else subset_timing_case(case)


def metrics(rows: list[dict], families: list[str], arm2: dict, parts: list[dict]) -> dict:
    m = generalization_metrics(rows, families)
    m["peak_memory_mib"] = max([r["peak_memory_mib"] for r in rows + parts] + [arm2["peak_memory_mib"]])
    m["arm2_doctor_seconds"] = arm2["seconds"]
    for p in parts:  # flat keys, as the per-family metrics
        m[f"subset_doctor_seconds.{p['subset']}"] = p["seconds"]
        m[f"subset_chambers.{p['subset']}"] = p["chambers"]
        # a part's timing case is a null case too: what it reports is a false discovery
        m[f"subset_null_entries.{p['subset']}"] = len(p["findings"]) + len(p["unexplained"])
    m.update(below_limit_metrics(rows))
    m["seeds"] = ",".join(str(r["seed"]) for r in rows)
    return m


def write_cases(ctx, rows: list[dict]) -> None:
    """cases/<case>/report.json and truth.json; cases.json without the reports."""
    for r in rows:
        folder = ctx.out / "cases" / r["case"]
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write_json(folder / "report.json", r["report"])
        atomic_write_json(folder / "truth.json", r["truth"])
    atomic_write_json(ctx.out / "cases.json", [{k: v for k, v in r.items() if k not in ("report", "truth")}
                                               for r in rows])


def plot_doctor_time(ctx, rows: list[dict], arm2: dict, parts: list[dict], seconds: float, heldout_s: float) -> None:
    """doctor_time.png: the doctor's seconds against the number of chambers (log-log): arm2's
    null case, the null cases of parts of humanoid38, and every humanoid38 case."""
    from .common import plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    hum = [r["seconds"] for r in rows if r["chambers"] == HUMANOID_CHAMBERS]
    if hum:
        cases = f"{len(hum)} case" + ("" if len(hum) == 1 else "s")
        ax.scatter([HUMANOID_CHAMBERS] * len(hum), hum, label=f"humanoid38 ({cases})", color="C0")
    on_parts = [r for r in rows if r["chambers"] != HUMANOID_CHAMBERS]  # --fast: its effect case
    if on_parts:
        ax.scatter([r["chambers"] for r in on_parts], [r["seconds"] for r in on_parts], color="C0", marker="^",
                   label="effect cases on a part of humanoid38")
    ax.scatter([ARM2_CHAMBERS], [arm2["seconds"]], label="arm2 (a null case)", color="C1")
    for p in parts:
        ax.scatter([p["chambers"]], [p["seconds"]], color="C2", marker="s")
        ax.annotate(p["subset"], (p["chambers"], p["seconds"]), textcoords="offset points", xytext=(4, -10), fontsize=7)
    if parts:
        ax.scatter([], [], color="C2", marker="s", label="parts of humanoid38, the rest locked (a null case each)")
    points = sorted([(ARM2_CHAMBERS, arm2["seconds"])] + [(p["chambers"], p["seconds"]) for p in parts]
                    + ([(HUMANOID_CHAMBERS, float(np.median(hum)))] if hum else []))
    ax.plot(*zip(*points), "k:", lw=1)
    ticks = sorted({c for c, _ in points})
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xticks(ticks, [str(c) for c in ticks])
    times = [t for _, t in points] + [r["seconds"] for r in rows]
    yticks = [t for t in (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000)
              if min(times) / 2 <= t <= max(times) * 2]
    ax.set_yticks(yticks, [f"{t:g}" for t in yticks])
    ax.minorticks_off()
    ax.set_xlabel("chambers")
    ax.set_ylabel("doctor time [s]")
    ax.set_title(f"doctor time against the chambers diagnosed, {seconds:.0f} s + {heldout_s:.0f} s recordings", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    ctx.savefig(fig, "doctor_time.png")


def run(ctx):
    base, source = (702, "development") if ctx.fast else seed_base_from_env(SEED_ENV, DEVELOPMENT_SEED_BASE, ctx.out)
    remember_seed_base(ctx.out, base, source)
    cases, seconds, held_s = plan(ctx.fast, base)
    extra = FAST_CASE if ctx.fast else {}
    specs = [{"seed": s, "families": f, "seconds": seconds, "heldout_seconds": held_s, **extra} for s, f in cases]
    timed = TIMED_SUBSETS[:1] if ctx.fast else TIMED_SUBSETS
    specs += [{"subset": p, "seed": 2 + k, "seconds": seconds, "heldout_seconds": held_s} for k, p in enumerate(timed)]
    specs.append({"arm2_timing": True, "seed": 1, "seconds": seconds, "heldout_seconds": held_s})
    opts = options_from_env()
    opts.setdefault("fresh_workers", opts.get("backend") != "inline")  # a case's peak memory its own
    results = sweep(sweep_case, specs, out=ctx.out / "sweep", **opts)
    raise_on_failure(results, "doctor_benchmark_humanoid38")
    done = [r.result for r in results]
    rows, parts, arm2 = done[:len(cases)], done[len(cases):-1], done[-1]
    if source != "fresh":  # a fresh run is reported as it comes, not case by case
        print_cases(rows)
    write_cases(ctx, rows)
    plot_doctor_time(ctx, rows, arm2, parts, seconds, held_s)
    families = sorted({f for _, fams in cases for f in fams})
    return {**metrics(rows, families, arm2, parts), "seed_base": base, "seed_source": source}


if __name__ == "__main__":
    main(__name__)
