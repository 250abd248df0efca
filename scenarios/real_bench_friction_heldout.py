"""The real bench's friction fit judged on what it did not see: each seal's run at one pressure
predicted from the seal's other three pressures (TU Delft thesis data, CC0; see
scenarios/real_bench_doctor.py and docs/real_bench.md).

For every seal (Circle, O-ring257, X-ring257) and every held-out pressure (1, 3, 5, 7 bar
gauge): fit the pressure-growing friction law on the other three files
(:func:`identification.doctor.bench.friction_heldout.predict_held_out`), predict the held-out file's
force trace, and compare it with the measurement (NRMSE), with p_g A alone, and with the law
fitted on that file itself.  1 and 7 bar are extrapolations, 3 and 5 bar interpolations.
The thesis's own numbers -- friction = F - p A averaged per direction -- are predicted too.

Metrics: ``heldout_nrmse_median`` (all 12 held-out files, law ``growth+offset``),
``..._interpolation`` / ``..._extrapolation``, ``..._worst`` and its file, the nominal and
in-file medians, and ``thesis_friction_abs_error_n_median``: |predicted - measured| of the
thesis's per-direction friction.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from pneumatics.bench.model import load_bench
from identification.doctor.bench.friction_heldout import TERMS, predict_held_out
from pneumatics.errors import PneumasimError
from pneumatics.importer import import_file

from .common import main, plt
from .real_bench_doctor import DATA, SEAL_BORE_M

SUMMARY = "real bench: each seal's friction at one pressure predicted from its other three (held-out files)"

LAW = "growth+offset"
FAST_SEALS = ("X-ring257",)


def friction_files() -> list[Path]:
    """The thesis's cylinder logs: ``../shared/real/...`` beside the repository, or the folder
    named by the environment variable PNEUMASIM_REAL_DATA (a checkout elsewhere)."""
    folder = Path(os.environ.get("PNEUMASIM_REAL_DATA", DATA)) / "friction"
    files = sorted(folder.glob("*.csv"))
    if not files:
        raise PneumasimError(f"{folder}: no thesis friction logs (*.csv) found; set PNEUMASIM_REAL_DATA "
                             f"to the folder holding friction/")
    return files


def run(ctx):
    cfg = load_bench("bench_cylinder")
    files = {}
    for f in friction_files():
        seal, bar = f.stem.rsplit("_", 1)
        if ctx.fast and seal not in FAST_SEALS:
            continue
        files.setdefault(seal, []).append(import_file(f, "zillen_friction", meta={"bore_m": SEAL_BORE_M[seal]}))
    results = {}
    for seal, recs in files.items():
        for k, rec in enumerate(recs):
            results[(seal, k)] = predict_held_out(cfg, recs[:k] + recs[k + 1:], rec)
    rows = sorted(results.items(), key=lambda kv: (kv[0][0], kv[1].gauge_bar))
    metrics = _summarise(rows)
    _plot(ctx, rows)
    return metrics


def _summarise(rows) -> dict:
    pressures = np.array([r.gauge_bar for _, r in rows])
    extreme = (pressures <= pressures.min() + 0.5) | (pressures >= pressures.max() - 0.5)
    m = {"heldout_files": len(rows)}
    for law in TERMS:
        suffix = "" if law == LAW else f"_{law.replace('+', '_')}"
        scores = np.array([r.nrmse[law] for _, r in rows])
        m[f"heldout_nrmse_median{suffix}"] = float(np.median(scores))
        m[f"heldout_nrmse_worst{suffix}"] = float(scores.max())
        m[f"heldout_nrmse_median_interpolation{suffix}"] = float(np.median(scores[~extreme]))
        m[f"heldout_nrmse_median_extrapolation{suffix}"] = float(np.median(scores[extreme]))
    worst = max(rows, key=lambda kv: kv[1].nrmse[LAW])
    m["heldout_nrmse_worst_file"] = f"{worst[0][0]}_{worst[1].gauge_bar:.0f}bar"
    m["nominal_nrmse_median"] = float(np.median([r.nrmse_nominal for _, r in rows]))
    m["in_file_nrmse_median"] = float(np.median([r.nrmse_in_file for _, r in rows]))
    err = [abs(p - q) for _, r in rows for p, q in zip(r.predicted_up_down_n[LAW], r.friction_up_down_n)]
    m["thesis_friction_abs_error_n_median"] = float(np.median(err))
    m["thesis_friction_abs_error_n_max"] = float(np.max(err))
    for (seal, _), r in rows:
        m[f"heldout_nrmse_{seal}_{r.gauge_bar:.0f}bar"] = r.nrmse[LAW]
    return m


def _plot(ctx, rows):
    seals = list(dict.fromkeys(s for (s, _), _ in rows))
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.3))
    for i, seal in enumerate(seals):
        rs = [r for (s, _), r in rows if s == seal]
        bar = [r.gauge_bar for r in rs]
        col = f"C{i}"
        axes[0].plot(bar, [r.nrmse_nominal for r in rs], "x:", color=col, alpha=0.6)
        axes[0].plot(bar, [r.nrmse[LAW] for r in rs], "o-", color=col, label=f"{seal}: predicted from the other 3")
        axes[0].plot(bar, [r.nrmse_in_file for r in rs], "s--", color=col, mfc="none", alpha=0.8)
        for d, mk in ((0, "^"), (1, "v")):
            axes[1].plot(bar, [r.friction_up_down_n[d] for r in rs], mk, color=col, ms=7,
                         label=f"{seal}: measured" if d == 0 else None)
            axes[1].plot(bar, [r.predicted_up_down_n[LAW][d] for r in rs], "-", color=col, lw=1,
                         label=f"{seal}: predicted" if d == 0 else None)
    axes[0].set_yscale("log")
    axes[0].set_xlabel("held-out file's gauge pressure [bar]")
    axes[0].set_ylabel("force NRMSE on the held-out file")
    axes[0].set_title("x: p A alone; o: predicted; □: fitted on the file itself", fontsize=10)
    axes[0].legend(fontsize=8)
    axes[1].set_xlabel("gauge pressure [bar]")
    axes[1].set_ylabel("thesis friction F − pA per direction [N]")
    axes[1].set_title("▲ q growing, ▼ q falling: measured; lines: predicted from the other pressures", fontsize=10)
    axes[1].legend(fontsize=7, ncol=2)
    for a in axes:
        a.grid(alpha=0.3, which="both")
    fig.tight_layout()
    ctx.savefig(fig, "friction_heldout.png")


if __name__ == "__main__":
    main(__name__)
