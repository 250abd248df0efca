"""Write a hydraulic doctor report (DESIGN.md "The mismatch finder"), every file atomically:
``report.json``; ``heldout_fit.png`` (measured vs the calibrated model before and after the
findings, over the held-out window the first finding changed most); ``fitted_effects.toml`` (the
calibrated parameters and the kept effects with standard errors, as
:class:`pneumatics.hydraulics.effects.HydraulicEffects` fields: ``build_sim(fitted_effects(report))``
simulates what was found; not DESIGN.md's ``model.toml``, which ``load_robot`` and
``pneumasim run --fitted`` read for the valve-driven arms and which does not apply to this
plant); ``report.md`` (the same for people, written last)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from identification.base.reporting import finding_line, jsonable, pyplot, save_figure, summary_head, with_error
from pneumatics.io import atomic_write_json, atomic_write_text


UNITS = {"p_a": ("MPa", 1e-6), "p_b": ("MPa", 1e-6), "vane": ("N m", 1.0), "load": ("N m", 1.0), "rigid": ("N m", 1.0),
         "brace": ("mrad", 1e3)}


def summary(report: dict) -> str:
    """What a person reads in ten seconds: where, what, how sure, how much better."""
    lines = summary_head(report, report["diagnostics"]["seconds"])
    for i, f in enumerate(report["findings"], 1):
        lines.append(finding_line(i, f, "sensors"))
        n = f["heldout_nrmse"]
        lines.append(f"     when: {f['regime']}; held-out NRMSE {f['heldout_channel']}: "
                     f"{n['before']:.3f} → {n['after']:.3f}")
    for u in report["unexplained"]:
        lines.append(f"  unexplained at {' '.join(str(v) for v in u['where'].values())} ({u['level']}), "
                     f"{u['regime']}: {100 * u['share_of_residual']:.0f} % of the held-out J")
    weak = [f for f in report["diagnostics"].get("weakly_observable", [])
            if f not in {x["effect"] for x in report["findings"]}]
    if weak:
        lines += [f"note: {', '.join(weak)} barely show in free-arm recordings;",
                  "      record the elbow braced too (sidecar \"braced\": true) to test them"]
    return "\n".join(lines)


def fitted_toml(report: dict) -> str:
    """The model as fitted: calibrated parameters and kept effects, each with its standard error."""
    lines = [f'model = "{report["model"]}"', 'kind = "hydraulic"', "", "[calibrated]"]
    lines += [f"{k} = {v:.9g}" for k, v in report["calibrated"].items()]
    lines += ["", "[calibration_change]  # relative to nominal"]
    lines += [f"{k} = {{ relative = {v['relative']:.6g}, stderr = {v['stderr']:.3g} }}"
              for k, v in report["calibration_change"].items()]
    lines += ["", "[effects]  # pneumatics.hydraulics.effects.HydraulicEffects fields"]
    for f in report["findings"]:
        for k, v in f["parameters"].items():
            lines.append(f"{k} = {{ value = {v['value']:.9g}, stderr = {v['stderr']:.3g}, effect = \"{f['effect']}\" }}")
    return "\n".join(lines) + "\n"


def write(report: dict, out: str | Path, plots: bool = True) -> Path:
    """report.json, fitted_effects.toml, heldout_fit.png and report.md into ``out``; returns the report.json path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ctx = report.pop("_plot", None)
    atomic_write_json(out / "report.json", jsonable(report))
    atomic_write_text(out / "fitted_effects.toml", fitted_toml(report))
    pngs = []
    if ctx is not None and plots:
        pngs.append(_plot_fit(report, ctx, out))
        report["_plot"] = ctx
    atomic_write_text(out / "report.md", _markdown(report, pngs))
    return out / "report.json"


def _plot_fit(report, ctx, out: Path) -> str:
    """heldout_fit.png: each channel's held-out residual before and after the findings, over
    the first finding's best window (or 2 s) of the first held-out recording that scores it
    (a braced recording for the brace channel)."""
    plt = pyplot()
    prob = ctx["problem"]
    none = type(ctx["fx"])()
    win = report["findings"][0]["windows"][0] if report["findings"] and report["findings"][0]["windows"] else None
    fig, axes = plt.subplots(len(prob.channels), 1, figsize=(9, 2.0 * len(prob.channels)))
    for ax, c in zip(np.atleast_1d(axes), prob.channels):
        tr = next(t for t in prob.held if prob.masks[id(t)][c].any())
        before, after = prob.sample_residuals(tr, ctx["dev"], none), prob.sample_residuals(tr, ctx["dev"], ctx["fx"])
        w = win if win is not None and tr.time[0] <= win[0] < tr.time[-1] else [float(tr.time[0]) + 0.5,
                                                                                 float(tr.time[0]) + 2.5]
        mk = (tr.time >= w[0]) & (tr.time <= w[1]) & prob.masks[id(tr)][c]
        unit, k = UNITS[c]
        ax.plot(tr.time[mk], before[c][mk] * k, ".", ms=1.5, label="residual, calibrated model")
        if report["findings"]:
            ax.plot(tr.time[mk], after[c][mk] * k, ".", ms=1.5, label="residual, + findings")
        ax.set_ylabel(f"{c} [{unit}]" + ("\nbraced" if tr.braced else ""), fontsize=8)
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].legend(fontsize=7)
    np.atleast_1d(axes)[0].set_title(f"held-out residuals: {report['verdict_detail']}", fontsize=9)
    np.atleast_1d(axes)[-1].set_xlabel("time [s]")
    fig.tight_layout()
    save_figure(fig, out / "heldout_fit.png")
    return "heldout_fit.png"


def _markdown(report: dict, pngs) -> str:
    d = report["diagnostics"]
    lines = [f"# pneumasim doctor report — {report['model']}", "", "```", summary(report), "```", "", "## Findings", ""]
    if report["findings"]:
        lines += ["| effect | where | regime | parameters | held-out NRMSE before → after | alternatives |",
                  "| --- | --- | --- | --- | --- | --- |"]
        for f in report["findings"]:
            par = "; ".join(with_error(k, v, 4, 2) for k, v in f["parameters"].items())
            n = f["heldout_nrmse"]
            lines.append(f"| {f['effect']} | {json.dumps(f['where'])} | {f['regime']} | {par} | {f['heldout_channel']}: "
                         f"{n['before']:.3f} → {n['after']:.3f} | {', '.join(f['alternatives']) or '—'} |")
        lines += ["", *[f"- {f['evidence']}." for f in report["findings"]]]
    else:
        lines.append("No effect improves the held-out prediction enough to be named.")
    lines += ["", "## Unexplained", ""]
    lines += [f"- {json.dumps(u['where'])}: {u['level']}, {u['regime']}" for u in report["unexplained"]] or \
        ["A flexible model of the residuals predicts nothing more on the held-out data."]
    lines += ["", "## Every hypothesis (first round, with its side's calibration, scored on the held-out part)", "",
              "| hypothesis | parameters | held-out J |", "| --- | --- | --- |"]
    for h in report["hypotheses"]:
        par = "; ".join(with_error(k, v, 4, 2) for k, v in h["parameters"].items())
        lines.append(f"| {h['name']} | {par} | {h['heldout_j']:.4g} |")
    lines += ["", "## Calibration (relative change from nominal)", ""]
    lines += [f"- {k}: {100 * v['relative']:+.2f} % ± {100 * v['stderr']:.2f} %"
              for k, v in report["calibration_change"].items()]
    lines += ["", "## Diagnostics", "", *[f"- {k}: {v}" for k, v in jsonable(d).items()], ""]
    lines += [f"![{p}]({p})" for p in pngs]
    return "\n".join(lines) + "\n"
