"""The doctor on real bench measurements (TU Delft thesis data, CC0; issue 7).

Imports every sealed-chamber log and every cylinder-friction log of
``shared/real/3d-printed-pneumatic-actuator`` with the shipped mapping files
(``pneumatics/import_maps``), runs the bench doctor on each (fit on the first 70 %, predict
the last 30 %), and per seal on the four pressures together (how friction grows with
pressure).  Writes ``table.csv``/``table.md`` (one row per file: the effect named, fitted
parameters with standard errors, held-out NRMSE before/after, the verdict where the data
cannot tell), one doctor report per file under ``reports/``, and summary plots.  Next to the
doctor's numbers stands what the thesis authors computed by hand: friction = force - p A.
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from identification.doctor.bench.diagnose import diagnose_bench, velocity
from identification.doctor.bench.report import write
from pneumatics.errors import PneumasimError
from pneumatics.importer import import_file
from pneumatics.io import atomic_write_text

from .common import main, plt

SUMMARY = "bench doctor on real chamber-leak and cylinder-friction measurements (thesis data)"
DATA = Path(__file__).resolve().parents[1].parent / "shared" / "real" / "3d-printed-pneumatic-actuator"
SEAL_BORE_M = {"Circle": 0.025, "O-ring257": 0.0257, "X-ring257": 0.0257}   # thesis README
FAST_CHAMBER = ("Prusa", "Ultimaker_020")
FAST_FRICTION = ("X-ring257_3bar",)


def _files(kind: str, fast: bool):
    folder = DATA / kind
    if not folder.is_dir():
        raise PneumasimError(f"{folder}: thesis data not found (expected ../shared beside the repository)")
    files = sorted(folder.glob("*.csv"))
    if fast:
        keep = FAST_CHAMBER if kind == "chamber" else FAST_FRICTION
        files = [f for f in files if f.stem in keep]
    return files


def _fmt(p: dict | None) -> str:
    return "" if p is None else f"{p['value']:.4g} ± {p['stderr']:.2g}"


def _thesis_friction(rec, bore_m: float) -> tuple[float, float]:
    """The authors' friction = force - p A, averaged while q grows and while it falls [N]."""
    fr = rec["force.rod"] - (rec["p_a.rod"] - 101325.0) * math.pi * bore_m ** 2 / 4
    v = velocity(rec.time, rec["q.rod"])
    return float(np.mean(fr[v > 2e-3])), float(np.mean(fr[v < -2e-3]))


def run(ctx):
    rows, chamber_rows, friction_rows = [], [], []
    for f in _files("chamber", ctx.fast):
        rec = import_file(f, "zillen_chamber")
        rep = diagnose_bench("bench_chamber", [rec])
        write(rep, ctx.out / "reports" / f"chamber_{f.stem}", plots=not ctx.fast)
        find = {x["effect"]: x for x in rep["findings"]}
        par = {k: v for x in rep["findings"] for k, v in x["parameters"].items()}
        b, a = rep["baseline"]["heldout_nrmse"]["p_a.chamber"], rep["after"]["heldout_nrmse"]["p_a.chamber"]
        row = {"file": f"chamber/{f.name}", "effect": "+".join(find) or "none",
               "isolable": "yes" if rep["isolable"] else "no",
               "parameters": "; ".join(f"{k} = {_fmt(v)}" for k, v in par.items()),
               "heldout_nrmse_before": b, "heldout_nrmse_after": a, "verdict": rep["verdict_detail"]}
        rows.append(row)
        chamber_rows.append((f.stem, rep, par))
    seals: dict[str, list] = {}
    for f in _files("friction", ctx.fast):
        seal, _bar = f.stem.rsplit("_", 1)
        bore = SEAL_BORE_M[seal]
        rec = import_file(f, "zillen_friction", meta={"bore_m": bore})
        rep = diagnose_bench("bench_cylinder", [rec])
        write(rep, ctx.out / "reports" / f"friction_{f.stem}", plots=not ctx.fast)
        par = {k: v for x in rep["findings"] for k, v in x["parameters"].items()}
        up, down = _thesis_friction(rec, bore)
        b, a = rep["baseline"]["heldout_nrmse"]["force.rod"], rep["after"]["heldout_nrmse"]["force.rod"]
        gauge_bar = float(np.median(rec["p_a.rod"] - 101325.0) / 1e5)
        rows.append({"file": f"friction/{f.name}", "effect": "+".join(dict.fromkeys(x["effect"] for x in rep["findings"])) or "none",
                     "isolable": "yes" if rep["isolable"] else "no",
                     "parameters": "; ".join(f"{k} = {_fmt(v)}" for k, v in par.items()),
                     "heldout_nrmse_before": b, "heldout_nrmse_after": a, "verdict": rep["verdict_detail"],
                     "thesis_friction_q_up_n": up, "thesis_friction_q_down_n": down})
        friction_rows.append((seal, gauge_bar, rep, par, up, down))
        seals.setdefault(seal, []).append(rec)
    growth = {}
    for seal, recs in seals.items():
        if len(recs) < 2:
            continue
        rep = diagnose_bench("bench_cylinder", recs)
        write(rep, ctx.out / "reports" / f"friction_{seal}_all_pressures")
        par = {k: v for x in rep["findings"] for k, v in x["parameters"].items()}
        growth[seal] = (rep, par)
        b, a = rep["baseline"]["heldout_nrmse"]["force.rod"], rep["after"]["heldout_nrmse"]["force.rod"]
        rows.append({"file": f"friction/{seal}_*bar.csv (together)",
                     "effect": "+".join(dict.fromkeys(x["effect"] for x in rep["findings"])) or "none",
                     "isolable": "yes" if rep["isolable"] else "no",
                     "parameters": "; ".join(f"{k} = {_fmt(v)}" for k, v in par.items()),
                     "heldout_nrmse_before": b, "heldout_nrmse_after": a, "verdict": rep["verdict_detail"]})
    _write_table(ctx, rows)
    _plot_chambers(ctx, chamber_rows)
    if friction_rows:
        _plot_friction(ctx, friction_rows)
    per_file = rows[: len(chamber_rows) + len(friction_rows)]
    named = [r for r in per_file if r["effect"] != "none"]
    red = [1.0 - r["heldout_nrmse_after"] / r["heldout_nrmse_before"] for r in per_file]
    metrics = {"chamber_files": len(chamber_rows), "friction_files": len(friction_rows),
               "named_fraction": len(named) / max(len(per_file), 1),
               "median_heldout_nrmse_reduction": float(np.median(red)),
               "not_isolable_files": sum(r["isolable"] == "no" for r in per_file)}
    for stem, rep, par in chamber_rows:
        for k in ("leak_time_constant_s", "thermal_time_constant_s"):
            if k in par:
                metrics[f"{stem}_{k}"] = par[k]["value"]
    for seal, (rep, par) in growth.items():
        for k in ("coulomb_n", "coulomb_n_per_bar", "offset_n", "offset_n_per_bar"):
            if k in par:
                metrics[f"{seal}_{k}"] = par[k]["value"]
    return metrics


COLUMNS = ["file", "effect", "isolable", "parameters", "heldout_nrmse_before", "heldout_nrmse_after",
           "thesis_friction_q_up_n", "thesis_friction_q_down_n", "verdict"]


def _write_table(ctx, rows):
    buf = io.StringIO()
    w = csv.DictWriter(buf, COLUMNS, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.4g}" if isinstance(v, float) else v) for k, v in r.items()})
    atomic_write_text(ctx.out / "table.csv", buf.getvalue())
    md = [("| file | effect named | isolable | parameters (± standard error) | held-out NRMSE before → after | "
          "thesis F − pA, q up / down [N] | verdict |"), "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        th = (f"{r['thesis_friction_q_up_n']:.2f} / {r['thesis_friction_q_down_n']:.2f}"
              if "thesis_friction_q_up_n" in r else "")
        md.append(f"| {r['file']} | {r['effect']} | {r['isolable']} | {r['parameters']} | "
                  f"{r['heldout_nrmse_before']:.3f} → {r['heldout_nrmse_after']:.3f} | {th} | {r['verdict']} |")
    atomic_write_text(ctx.out / "table.md", "\n".join(md) + "\n")
    ctx.written += [ctx.out / "table.csv", ctx.out / "table.md"]


def _plot_chambers(ctx, chamber_rows):
    if not chamber_rows:
        return
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    names = [s for s, _, _ in chamber_rows]
    x = np.arange(len(names))
    before = [r["baseline"]["heldout_nrmse"]["p_a.chamber"] for _, r, _ in chamber_rows]
    after = [r["after"]["heldout_nrmse"]["p_a.chamber"] for _, r, _ in chamber_rows]
    axes[0].bar(x - 0.2, before, 0.4, label="sealed chamber (nominal)")
    axes[0].bar(x + 0.2, after, 0.4, label="with the named effect")
    for i, (_, r, _) in enumerate(chamber_rows):
        lab = "+".join(f["effect"].replace("external_leak", "leak").replace("heat_transfer", "thermal")
                       for f in r["findings"]) or "none"
        alts = [a for f in r["findings"] for a in f["alternatives"]]
        lab += f"\n(or {alts[0].replace('external_leak', 'leak').replace('heat_transfer', 'thermal')})" if alts else ""
        axes[0].text(i, max(before[i], after[i]) * 1.3, lab, ha="center", fontsize=7)
    axes[0].set_yscale("log")
    axes[0].set_xticks(x, names, rotation=25, fontsize=8)
    axes[0].set_ylabel("held-out NRMSE of the pressure")
    axes[0].legend(fontsize=8)
    ax = axes[1]
    for s, r, _ in chamber_rows:
        ax.plot(x[names.index(s)], 0, alpha=0)
    leak = [(i, p["leak_time_constant_s"]) for i, (_, _, p) in enumerate(chamber_rows) if "leak_time_constant_s" in p]
    therm = [(i, p["thermal_time_constant_s"]) for i, (_, _, p) in enumerate(chamber_rows) if "thermal_time_constant_s" in p]
    if leak:
        ax.errorbar([i for i, _ in leak], [v["value"] for _, v in leak], [v["stderr"] for _, v in leak], fmt="o",
                    label="leak time constant")
    if therm:
        ax.errorbar([i for i, _ in therm], [v["value"] for _, v in therm], [v["stderr"] for _, v in therm], fmt="s",
                    label="thermal time constant")
    ax.set_yscale("log")
    ax.set_xticks(x, names, rotation=25, fontsize=8)
    ax.set_ylabel("time constant [s]")
    ax.legend(fontsize=8)
    ax.set_title("fitted time constants (± standard error)", fontsize=10)
    ctx.savefig(fig, "chambers.png")


def _plot_friction(ctx, friction_rows):
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for k, seal in enumerate(dict.fromkeys(r[0] for r in friction_rows)):
        rs = sorted([r for r in friction_rows if r[0] == seal], key=lambda r: r[1])
        col = f"C{k}"
        bar = np.array([r[1] for r in rs])
        fc = [r[3].get("coulomb_n") for r in rs]
        ok = [i for i, v in enumerate(fc) if v is not None]
        if ok:
            ax.errorbar(bar[ok], [fc[i]["value"] for i in ok], [fc[i]["stderr"] for i in ok], fmt="o-", color=col,
                        label=f"{seal}: doctor, Coulomb (symmetric part)")
        ax.plot(bar, [(r[4] - r[5]) / 2 for r in rs], "x--", color=col, alpha=0.7,
                label=f"{seal}: thesis F − pA, half the up/down difference")
        ax.plot(bar, [(r[4] + r[5]) / 2 for r in rs], "v:", color=col, alpha=0.7,
                label=f"{seal}: constant part (offset or asymmetry)")
    ax.set_xlabel("cap chamber pressure [bar gauge]")
    ax.set_ylabel("force [N]")
    ax.legend(fontsize=7)
    ax.set_title("rod-seal friction vs pressure", fontsize=10)
    ctx.savefig(fig, "friction_vs_pressure.png")


if __name__ == "__main__":
    main(__name__)
