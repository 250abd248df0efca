"""Write a bench doctor report: ``report.json`` (DESIGN.md contract), ``report.md`` and PNGs.

All files are written atomically (pneumatics.io), into the staging folder ``pneumasim doctor``
swaps in whole at the end (OutputFolder); plots show the measured channel against
every hypothesis on the fitted and the held-out part, and the residual before and after.
"""
from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np

from pneumatics.io import atomic_write_json, atomic_write_text

from identification.base.reporting import finding_line, jsonable, pyplot, save_figure, summary_head, with_error


def summary(report: dict) -> str:
    """What a person reads in ten seconds: each finding, its held-out NRMSE, what is unexplained."""
    lines = summary_head(report)
    for i, f in enumerate(report["findings"], 1):
        lines.append(finding_line(i, f, "data"))
        n = f["heldout_nrmse"]
        lines.append(f"     held-out NRMSE {f['heldout_channel']}: {n['before']:.3f} → {n['after']:.3f}")
    for u in report["unexplained"]:
        lines.append(f"  unexplained ({u['regime']}): {100 * u['share_of_residual']:.1f} % of the held-out residual")
    return "\n".join(lines)


def write(report: dict, out: str | Path, plots: bool = True) -> Path:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plot = report.pop("_plot", None)
    atomic_write_json(out / "report.json", jsonable(report))
    pngs = []
    if plot is not None and plots:
        pngs = _plots_chamber(report, plot, out) if report["diagnostics"]["kind"] == "bench_chamber" \
            else _plots_cylinder(report, plot, out)
    atomic_write_text(out / "report.md", _markdown(report, pngs))
    if plot is not None:
        report["_plot"] = plot
    return out / "report.json"


def _plots_chamber(report, plot, out: Path) -> list[str]:
    from .chamber_fit import model_pressure

    plt = pyplot()
    tr, ho, ch, cfg, tc = plot["train"], plot["held"], plot["channel"], plot["cfg"], plot["tc"]
    t = np.concatenate([tr.time, ho.time])
    meas = np.concatenate([tr[ch], ho[ch]])
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    axes[0].plot(t, (meas - cfg.room_pa) / 1e5, "k.", ms=2, label="measured")
    for h, s in plot["scored"].items():
        pred = model_pressure(h, s["fit"].values, t, tc, cfg)
        lw = 2.0 if h == plot["best"] else 1.0
        axes[0].plot(t, (pred - cfg.room_pa) / 1e5, lw=lw, label=f"{h} (held-out RMSE {np.sqrt(s['heldout_mse']):.0f} Pa)")
        axes[1].plot(t, (meas - pred) / 1e2, lw=lw, label=h)
    for ax in axes:
        ax.axvspan(ho.time[0], ho.time[-1], color="0.9", zorder=0)
        ax.axvline(tc, color="gray", ls=":", lw=1)
    axes[0].set_ylabel("gauge pressure [bar]")
    axes[0].set_title(textwrap.fill(f"{Path(report['diagnostics']['sources'][0]).name}: fitted on white, held out "
                                    f"on grey; {report['verdict_detail']}", 100), fontsize=9)
    axes[0].legend(fontsize=7)
    axes[1].set_ylabel("measured − model [hPa]")
    axes[1].set_xlabel("time [s]")
    axes[1].axhline(0, color="gray", lw=0.5)
    lim = max(5 * report["diagnostics"]["pressure_noise_pa"], np.percentile(np.abs(meas - model_pressure(
        plot["best"], plot["scored"][plot["best"]]["fit"].values, t, tc, cfg)), 99) * 3) / 1e2
    axes[1].set_ylim(-lim, lim)
    save_figure(fig, out / "pressure_hypotheses.png")
    return ["pressure_hypotheses.png"]


def _plots_cylinder(report, plot, out: Path) -> list[str]:
    plt = pyplot()
    tr, ho, scored, best = plot["train"], plot["held"], plot["scored"], plot["best"]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    ax = axes[0]
    for d, col, lab in ((tr, "tab:blue", "fitted part"), (ho, "tab:orange", "held-out part")):
        ax.plot(d.v * 1e3, d.residual, ".", ms=1.5, color=col, alpha=0.5, label=lab)
    if scored[best]["fit"] is not None:
        order = np.argsort(ho.v)
        ax.plot(ho.v[order] * 1e3, scored[best]["pred"][order], "k-", lw=1.5, label=f"{best}")
    ax.axhline(0, color="gray", lw=0.5)
    ax.set_xlabel("rod velocity dq/dt [mm/s]")
    ax.set_ylabel("force − p_g·A [N]  (the thesis's friction)")
    ax.set_xlim(np.percentile(tr.v, 0.5) * 1.3e3, np.percentile(tr.v, 99.5) * 1.3e3)
    ax.legend(fontsize=8, markerscale=5)
    ax.set_title("friction vs velocity", fontsize=10)
    ax = axes[1]
    n = min(ho.t.size, 2000)
    ax.plot(ho.t[:n], ho.residual[:n], "k.", ms=1.5, label="measured force − p_g·A")
    ax.plot(ho.t[:n], scored[best]["pred"][:n], lw=1.2, label=f"{best}")
    ax.plot(ho.t[:n], ho.residual[:n] - scored[best]["pred"][:n], lw=0.8, alpha=0.7, label="remaining error")
    ax.set_xlabel("time [s] (held-out part)")
    ax.set_ylabel("force [N]")
    ax.legend(fontsize=8, markerscale=5)
    ax.set_title(textwrap.fill(report["verdict_detail"], 90), fontsize=8)
    save_figure(fig, out / "friction_fit.png")
    return ["friction_fit.png"]


def _markdown(report: dict, pngs) -> str:
    lines = [f"# pneumasim doctor report — {report['model']}", "", "```", summary(report), "```", "",
             "## Findings", ""]
    if report["findings"]:
        lines += ["| effect | where | parameters | held-out NRMSE before → after | alternatives |",
                  "| --- | --- | --- | --- | --- |"]
        for f in report["findings"]:
            par = "; ".join(with_error(k, v, 4, 2) for k, v in f["parameters"].items())
            n = f["heldout_nrmse"]
            lines.append(f"| {f['effect']} | {json.dumps(f['where'])} | {par} | {n['before']:.3f} → {n['after']:.3f} "
                         f"| {', '.join(f['alternatives']) or '—'} |")
        lines.append("")
        lines += [f"- {f['evidence']}." for f in report["findings"]]
    else:
        lines.append("No effect improves the held-out prediction enough to be named.")
    lines += ["", f"Isolable: {'yes' if report['isolable'] else 'no'} — {report['verdict_detail']}.", "",
              "## Every hypothesis (fitted on the first part, predicting the held-out part)", "",
              "| hypothesis | parameters | held-out NRMSE |", "| --- | --- | --- |"]
    for h in report["hypotheses"]:
        par = "; ".join(with_error(k, v, 4, 2) for k, v in h["parameters"].items())
        bad = f" (implausible: {h['implausible']})" if h.get("implausible") else ""
        lines.append(f"| {h['name']} | {par or '—'}{bad} | {h['heldout_nrmse']:.3f} |")
    lines += ["", "## Diagnostics", ""]
    lines += [f"- {k}: {v}" for k, v in report["diagnostics"].items()]
    lines.append("")
    lines += [f"![{p}]({p})" for p in pngs]
    return "\n".join(lines) + "\n"
