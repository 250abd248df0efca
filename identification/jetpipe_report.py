"""Write a jet-pipe doctor report: ``report.json`` and ``report.md`` (bench_report's writer, the
same DESIGN.md contract) and ``heldout_fit.png`` (measured vs the calibrated model before and
after the findings, in the held-out window the findings changed most)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from pneumatics.io import atomic_write_text

from . import bench_report
from .bench_report import _plt, _save
from .jetpipe_doctor import CALIBRATION, _cfg, fitted_effects
from .jetpipe_replay import measured, replay

summary = bench_report.summary

UNITS = {"p_a": ("kPa", 1e-3), "p_b": ("kPa", 1e-3), "force": ("N", 1.0), "jet": ("mm", 1e3)}


def write(report: dict, out: str | Path, plots: bool = True) -> Path:
    """report.json, report.md and the PNG into ``out``; returns the report.json path."""
    out = Path(out)
    ctx = report.pop("_plot", None)
    path = bench_report.write(report, out, plots=False)
    if ctx is not None and plots:
        png = _plot(report, ctx, out)
        md = (out / "report.md").read_text() + f"\n![{png}]({png})\n"
        atomic_write_text(out / "report.md", md)
        report["_plot"] = ctx
    return path


def _plot(report, ctx, out: Path) -> str:
    plt = _plt()
    prob, held = ctx["problem"], ctx["held"]
    dev = np.array([report["calibration_change"][c[0]]["relative"] for c in CALIBRATION])
    cfg = _cfg(prob.cfg0, dev)
    fx = fitted_effects(report)
    tr = held[0]
    meas, before, after = measured(tr), replay(tr, cfg, type(fx)()), replay(tr, cfg, fx)
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
    _save(fig, out / "heldout_fit.png")
    return "heldout_fit.png"
