"""Paper 002 §IV-B.3 (eqs. 10-12): orifice areas of every valve from static-volume transients.

Both arm2 joints are braced (stiff joint equalities like ``brace_shoulder``), every
chamber starts at room and then at supply pressure with its valve held at each command of a
0-10 V grid (0.1 V steps near the null), the DAQ records the pressures (averaged, with sensor
noise), and a linear least-squares fit per chamber and command on the smoothing-spline
pressure rate gives a_c(v)/V and a_r(v)/V with standard errors.  Areas follow from the
chamber volumes at the braced pose (geometry), and, as in the paper, from the full-open areas
(eqs. 11-12).  They are compared with the model's true maps (``pneumatics/valve.py``).
Without ``--fast``, the same procedure runs on humanoid38's 76 valves (all chambers at once)
and is compared with their per-valve scatter (models/humanoid38/fluid.toml).

Relative errors are taken where the true area is at least 10 % of the valve's full area (a
relative error of a shut port means nothing); where it is below, the absolute error as a
fraction of the full area is reported.
"""
from __future__ import annotations

import numpy as np

from identification.orifice import (
    DEFAULT_COMMANDS_V,
    calibrate_robot,
    calibration_errors,
    true_areas,
)
from pneumatics.robot import load_robot

from ._humanoid import FAST_COMMANDS_V
from .common import main, plt

SUMMARY = "§IV-B.3: orifice areas a_c(v), a_r(v) of every valve from static-volume transients vs the true maps"


def run(ctx):
    commands = FAST_COMMANDS_V if ctx.fast else DEFAULT_COMMANDS_V
    scale = 0.4 if ctx.fast else 1.0
    arm = load_robot("arm2")
    cal = calibrate_robot(arm, commands, seed=1, duration_scale=scale)
    err = calibration_errors(cal, arm.tables.valve)
    metrics = {
        "area_rel_error_median": float(np.median(err["volume"])),
        "area_rel_error_p90": float(np.percentile(err["volume"], 90)),
        "area_rel_error_max": float(err["volume"].max()),
        "area_rel_error_median_anchored": float(np.median(err["anchored"])),
        "closed_area_abs_error_median_frac": float(np.median(err["closed_abs_frac"])),
        "n_commands": int(cal.commands_v.size),
    }
    hum = None
    if not ctx.fast:
        humanoid = load_robot("humanoid38")
        hum = calibrate_robot(humanoid, commands, seed=2)
        herr = calibration_errors(hum, humanoid.tables.valve)
        metrics.update({
            "humanoid_area_rel_error_median": float(np.median(herr["volume"])),
            "humanoid_area_rel_error_p90": float(np.percentile(herr["volume"], 90)),
            "humanoid_area_rel_error_median_anchored": float(np.median(herr["anchored"])),
            "humanoid_valves": int(hum.charge_per_volume.shape[0]),
        })

    fine = np.linspace(0.0, 10.0, 401)
    t_c, t_r = true_areas(arm.tables.valve, fine)
    e_c, e_r = cal.areas()
    s_c, s_r = cal.area_stderr()
    ncols = 3 if hum is not None else 2
    fig, axes = plt.subplots(2, ncols, figsize=(5.2 * ncols, 7.5))
    for i, (act, ch) in enumerate(arm.chamber_names):
        ax = axes[i // 2, i % 2]
        ax.plot(fine, t_c[i] * 1e6, "C0-", lw=1, label="true a_c (to supply)")
        ax.plot(fine, t_r[i] * 1e6, "C1-", lw=1, label="true a_r (to room)")
        ax.errorbar(cal.commands_v, e_c[i] * 1e6, yerr=2 * s_c[i] * 1e6, fmt="C0o", ms=3.5, capsize=2,
                    label="recovered a_c (±2 s.e.)")
        ax.errorbar(cal.commands_v, e_r[i] * 1e6, yerr=2 * s_r[i] * 1e6, fmt="C1s", ms=3.5, capsize=2,
                    label="recovered a_r (±2 s.e.)")
        ax.set_title(f"arm2 {act}, chamber {ch}")
        ax.set_xlabel("valve command [V]")
        ax.set_ylabel("effective area [mm²]")
        if i == 0:
            ax.legend(fontsize=7)
    if hum is not None:
        h_c, h_r = true_areas(humanoid.tables.valve, hum.commands_v)
        g_c, g_r = hum.areas()
        for row, (tr, est, name) in enumerate(((h_c, g_c, "a_c"), (h_r, g_r, "a_r"))):
            ax = axes[row, 2]
            full = tr.max(axis=1, keepdims=True)
            m = tr >= 0.1 * full
            ax.loglog(tr[m] * 1e6, est[m] * 1e6, ".", ms=2.5, alpha=0.6)
            lim = [tr[m].min() * 1e6 * 0.8, tr[m].max() * 1e6 * 1.2]
            ax.plot(lim, lim, "k-", lw=0.8)
            ax.set_title(f"humanoid38, 76 valves: {name} where open ≥ 10 %")
            ax.set_xlabel("true area [mm²]")
            ax.set_ylabel("recovered area [mm²]")
    fig.suptitle("Orifice-area calibration from static-volume transients (paper 002 eqs. 10-12): "
                 f"median relative error {100 * metrics['area_rel_error_median']:.2f} %")
    fig.tight_layout()
    ctx.savefig(fig, "orifice_calibration.png")
    return metrics


if __name__ == "__main__":
    main(__name__)
