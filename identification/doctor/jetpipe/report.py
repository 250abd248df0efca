"""Write a jet-pipe doctor report (DESIGN.md "The mismatch finder"), every file atomically
(pneumatics.io; ``pneumasim doctor`` swaps the whole folder in at the end): ``report.json``; ``heldout_fit.png`` (measured vs the calibrated model before
and after the findings, in the held-out window the findings changed most); ``regimes.png``
(the noise-weighted squared residual vs the regime feature where each finding's improvement
or each unexplained residual concentrates, before and after); ``doctor.rrd`` (Rerun: measured,
nominal = calibrated without findings, and corrected = with the findings, traces of the
held-out data); ``report.md`` (the same for people, written last)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from pneumatics.io import atomic_save, atomic_write_json, atomic_write_text

from identification.base.reporting import finding_line, jsonable, pyplot, save_figure, summary_head, with_error

from .diagnose import fitted_effects
from .hypotheses import CALIBRATION, calibrated_cfg
from .regimes import FEATURES
from .replay import measured, replay

UNITS = {"p_a": ("kPa", 1e-3), "p_b": ("kPa", 1e-3), "force": ("N", 1.0), "jet": ("mm", 1e3)}
#: report channel -> recording column (DESIGN.md names, as JetpipeSim.run writes them)
COLUMNS = {"p_a": "p_a.piston", "p_b": "p_b.piston", "force": "force.piston", "jet": "x_jet.piston"}


def summary(report: dict) -> str:
    """What a person reads in ten seconds: where, what, how sure, how much better."""
    lines = summary_head(report, report["diagnostics"]["seconds"])
    for i, f in enumerate(report["findings"], 1):
        lines.append(finding_line(i, f, "sensors"))
        lines.append(f"     when: {f['regime']}; bootstrap inclusion {f['inclusion_probability']:.2f}")
        n, nr = f["heldout_nrmse"], f["heldout_nrmse_in_regime"]
        lines.append(f"     held-out NRMSE {f['heldout_channel']}: {n['before']:.3f} → {n['after']:.3f}"
                     + (f" (in that regime {nr['before']:.3f} → {nr['after']:.3f})" if f["regime_detail"]["feature"] else ""))
    for u in report["unexplained"]:
        lines.append(f"  unexplained at {' '.join(str(v) for v in u['where'].values())} ({u['level']}), "
                     f"{u['regime']}: {100 * u['share_of_residual']:.0f} % of the held-out excess")
    return "\n".join(lines)


def write(report: dict, out: str | Path, plots: bool = True, rerun: bool = True) -> Path:
    """report.json, the PNGs, doctor.rrd and report.md into ``out``; returns the report.json path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ctx = report.pop("_plot", None)
    atomic_write_json(out / "report.json", jsonable(report))
    pngs = []
    if ctx is not None and (plots or rerun):
        runs = _replays(report, ctx)  # the held-out replays, shared by the plot and the .rrd
        if plots:
            pngs = [_plot_fit(report, ctx, runs[0], out)]
            if ctx.get("regimes"):
                pngs.append(_plot_regimes(ctx["regimes"], out))
        if rerun:
            _rrd(report, ctx, runs, out)
        report["_plot"] = ctx
    atomic_write_text(out / "report.md", _markdown(report, pngs))
    return out / "report.json"


def _replays(report, ctx):
    """Per held-out trace: (trace, measured, calibrated without findings, with findings)."""
    prob, held = ctx["problem"], ctx["held"]
    dev = np.array([report["calibration_change"][c[0]]["relative"] for c in CALIBRATION])
    cfg = calibrated_cfg(prob.cfg0, dev)
    fx = fitted_effects(report)
    return [(tr, measured(tr), replay(tr, cfg, type(fx)()), replay(tr, cfg, fx)) for tr in held]


def _rrd(report, ctx, runs, out: Path):
    """doctor.rrd: held-out measured / nominal (calibrated, no findings) / corrected traces,
    under ``measured/``, ``nominal/``, ``corrected/`` (``.../heldout<k>/`` with several files)."""
    from pneumatics.jetpipe.sim import JetpipeSim, build
    from workflow.rerun_log import RerunLogger

    prob = ctx["problem"]
    robot = JetpipeSim(build(prob.cfg0)).rerun_robot()

    def save(tmp):
        logger = RerunLogger(robot, path=tmp, recording_name=f"doctor {report['model']}: held-out data")
        for k, (tr, meas, nominal, corrected) in enumerate(runs):
            sub = f"/heldout{k + 1}" if len(runs) > 1 else ""
            for prefix, chans in (("measured", meas), ("nominal", nominal), ("corrected", corrected)):
                cols = {"time": tr.time, **{COLUMNS[c]: chans[c] for c in prob.channels}}
                if prefix == "measured":
                    cols["i_cmd.piston"] = tr.command_a
                logger.log_recording(cols, prefix=prefix + sub)
        logger.close()
    atomic_save(out / "doctor.rrd", save)


def _plot_fit(report, ctx, run, out: Path) -> str:
    """``run``: (trace, measured, calibrated without findings, with findings) of one held-out trace."""
    plt = pyplot()
    prob = ctx["problem"]
    tr, meas, before, after = run
    win = report["findings"][0]["windows"][0] if report["findings"] and report["findings"][0]["windows"] else \
        [float(tr.time[0]), float(tr.time[0]) + 1.0]
    m = (tr.time >= win[0]) & (tr.time <= win[1])
    chans = prob.channels
    fig, axes = plt.subplots(len(chans), 1, figsize=(9, 2.2 * len(chans)), sharex=True)
    for ax, c in zip(np.atleast_1d(axes), chans):
        unit, k = UNITS[c]
        ax.plot(tr.time[m], meas[c][m] * k, "k.", ms=1.5, label="measured")
        ax.plot(tr.time[m], before[c][m] * k, lw=1.0, label="calibrated model")
        if report["findings"]:
            ax.plot(tr.time[m], after[c][m] * k, lw=1.0, label="+ findings")
        ax.set_ylabel(f"{c} [{unit}]")
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].legend(fontsize=7)
    np.atleast_1d(axes)[0].set_title(f"held-out window: {report['verdict_detail']}", fontsize=9)
    np.atleast_1d(axes)[-1].set_xlabel("time [s]")
    save_figure(fig, out / "heldout_fit.png")
    return "heldout_fit.png"


def _plot_regimes(entries, out: Path) -> str:
    """Binned mean of the noise-weighted squared residual vs each entry's regime feature."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(entries), figsize=(4.5 * len(entries), 3.4), squeeze=False)
    for ax, e in zip(axes[0], entries):
        name = e["feature"] or "current command"
        x = e["feats"][name]
        unit, k = FEATURES[name]
        edges = np.unique(np.quantile(x, np.linspace(0, 1, 13)))
        b = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
        centre = np.array([np.median(x[b == i]) for i in range(edges.size - 1)]) * k
        for w, lab in ((e["before"], "before"), (e["after"], "after")):
            ax.plot(centre, [np.mean(w[b == i]) for i in range(edges.size - 1)], "o-", ms=3, label=lab)
        ax.set_yscale("log")
        ax.set_xlabel(f"{name} [{unit}]" + ("" if e["feature"] else " (spread throughout)"), fontsize=8)
        ax.set_ylabel("mean sum r²/σ² per sample (12 quantile bins)", fontsize=7)
        ax.set_title(e["title"], fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, out / "regimes.png")
    return "regimes.png"


def _markdown(report: dict, pngs) -> str:
    d = report["diagnostics"]
    lines = [f"# pneumasim doctor report — {report['model']}", "", "```", summary(report), "```", "", "## Findings", ""]
    if report["findings"]:
        lines += [("| effect | where | regime (measured) | parameters | held-out NRMSE before → after | inclusion | "
                  "alternatives |"), "| --- | --- | --- | --- | --- | --- | --- |"]
        for f in report["findings"]:
            par = "; ".join(with_error(k, v, 4, 2) for k, v in f["parameters"].items())
            n, r = f["heldout_nrmse"], f["regime_detail"]
            reg = f["regime"] + (f" ({100 * r['share']:.0f} % of the improvement in {100 * r['cover']:.0f} % of "
                                 f"the samples)" if r["feature"] else "")
            lines.append(f"| {f['effect']} | {json.dumps(f['where'])} | {reg} | {par} | {f['heldout_channel']}: "
                         f"{n['before']:.3f} → {n['after']:.3f} | {f['inclusion_probability']:.2f} | "
                         f"{', '.join(f['alternatives']) or '—'} |")
        lines.append("")
        lines += [f"- {f['evidence']}." for f in report["findings"]]
    else:
        lines.append("No effect improves the held-out prediction enough to be named.")
    lines += ["", "## Unexplained", ""]
    lines += [f"- {json.dumps(u['where'])}: {u['level']}, {u['regime']}; windows {u['windows']}"
              for u in report["unexplained"]] or ["Nothing above the noise floor is left unexplained."]
    lines += ["", f"Isolable: {'yes' if report['isolable'] else 'no'} — {report['verdict_detail']}.", "",
              "## Residual tests on the held-out data (Ljung)", "",
              (f"Ljung-Box Q over lags 1-{d['ljung_box_heldout']['lags']} (white: Q near the lag count, p > 0.05) "
              "and the largest cross-correlation of the residual with the current command over lags 0-50 ms "
              "(independent of the input: below the 95 % bound)."), "",
              "| channel | Q before | Q after | max xcorr before | max xcorr after | 95 % bound |",
              "| --- | --- | --- | --- | --- | --- |"]
    lb, xc = d["ljung_box_heldout"], d["input_xcorr_heldout"]
    for c in d["channels"]:
        lines.append(f"| {c} | {lb['before'][c]['q']:.4g} | {lb['after'][c]['q']:.4g} | "
                     f"{xc['before'][c]['max_abs']:.3f} ({xc['before'][c]['lag_ms']:.0f} ms) | "
                     f"{xc['after'][c]['max_abs']:.3f} ({xc['after'][c]['lag_ms']:.0f} ms) | {xc['after'][c]['bound']:.3f} |")
    lines += ["", "## Every hypothesis (first round, fitted with the calibration, scored on the held-out part)", "",
              "| hypothesis | parameters | held-out J | held-out NRMSE |", "| --- | --- | --- | --- |"]
    for h in report["hypotheses"]:
        par = "; ".join(with_error(k, v, 4, 2) for k, v in h["parameters"].items())
        lines.append(f"| {h['name']} | {par} | {h['heldout_j']:.4g} | {h['heldout_nrmse']:.4f} |")
    lines += ["", "## Calibration (relative change from nominal)", ""]
    lines += [f"- {k}: {100 * v['relative']:+.1f} % ± {100 * v['stderr']:.1f} %" for k, v in report["calibration_change"].items()]
    lines += ["", "## Diagnostics", ""]
    skip = {"ljung_box_heldout", "input_xcorr_heldout"}
    lines += [f"- {k}: {v}" for k, v in jsonable(d).items() if k not in skip]
    lines.append("")
    lines += [f"![{p}]({p})" for p in pngs]
    lines += ["", ("Traces (measured, nominal = calibrated without the findings, corrected = with them) of the "
              "held-out data: `doctor.rrd` (`rerun doctor.rrd`).")]
    return "\n".join(lines) + "\n"
