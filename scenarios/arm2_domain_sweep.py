"""How the arm2 PIDF tracking degrades away from the conditions it was tuned for: a grid of
supply pressures and valve-area scales, one closed-loop run per grid point, run through the
sweep (:mod:`workflow.sweep`; every core, or Ray with ``PNEUMASIM_RAY=auto|ADDRESS``).

Each case rebuilds arm2's fluid parameters with ``[supply] supply_pa`` replaced and every
valve's ``supply_area_max_m2`` and ``exhaust_area_max_m2`` multiplied by the scale (the
orifice flow of paper 002 eqs. 6-8 scales with the area, so the scale is a faster or slower
valve of the same shape), and runs the fixed gains ``controllers.pid.ARM2_PIDF`` on the same
seeded hand-moved reference with the same sensor noise.  The tracking error is the RMS over
both joints and the whole run after a 1 s pre-roll under control.

Writes ``tracking_error_map.png`` (heat map), ``grid.json`` and ``sweep/cases/<i>.json`` (a rerun
into the same ``--out`` resumes).  Metrics: ``cases``, ``failed``, ``rms_error_deg_min``,
``rms_error_deg_max``, ``rms_error_deg_nominal`` (7 bar, scale 1).
"""
from __future__ import annotations

import dataclasses

import numpy as np

import models
from controllers.pid import ARM2_PIDF
from controllers.reference import hand_moved
from pneumatics.io import atomic_write_json
from pneumatics.params import load_fluid
from pneumatics.robot import load_robot
from pneumatics.runner import run as run_loop
from pneumatics.sim import Simulation
from workflow.sweep import options_from_env, raise_on_failure, sweep

from .common import main, plt

SUMMARY = "PIDF tracking error over a grid of supply pressures and valve-area scales (heat map, via the sweep)"
#: its sweep's finished cases are kept when a run is interrupted; a rerun into the same --out
#: resumes them (pneumatics.io.OutputFolder, resumable)
RESUMABLE = True

SUPPLY_BAR = (3.0, 4.0, 5.0, 6.0, 7.0)           # absolute; the model's own is 7 bar
AREA_SCALES = (0.35, 0.5, 0.7, 1.0, 1.4, 2.0)
NOMINAL = (7.0, 1.0)
REFERENCE_SEED = 11


def scaled_fluid(fluid, supply_pa: float, area_scale: float):
    """``fluid`` with the supply pressure replaced and every valve's areas times ``area_scale``."""
    def valve(v):
        return dataclasses.replace(v, supply_area_max_m2=v.supply_area_max_m2 * area_scale,
                                   exhaust_area_max_m2=v.exhaust_area_max_m2 * area_scale)

    acts = tuple(dataclasses.replace(a, valve_a=valve(a.valve_a), valve_b=valve(a.valve_b)) for a in fluid.actuators)
    return dataclasses.replace(fluid, supply=dataclasses.replace(fluid.supply, supply_pa=supply_pa), actuators=acts)


def track(case: dict) -> dict:
    """One grid point: RMS and peak tracking error [deg] of ARM2_PIDF (the sweep's case function)."""
    fluid = scaled_fluid(load_fluid(models.fluid_path("arm2")), case["supply_pa"], case["area_scale"])
    robot = load_robot("arm2", fluid=fluid)
    ref = hand_moved(robot.joint_names, robot.joint_range(), case["seconds"], seed=case["seed"])
    sim = Simulation(robot)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=0.5 * (case["supply_pa"] + fluid.supply.room_pa))
    null = robot.tables.valve[:, 0]
    run_loop(sim, ARM2_PIDF.build(ref, null), 1.0, seed=case["seed"])  # pre-roll: pressures settle under control
    sim.data.time = 0.0
    rec = run_loop(sim, ARM2_PIDF.build(ref, null), case["seconds"], seed=case["seed"] + 7)
    err = np.degrees(np.column_stack([rec[f"ref.{j}"] - rec[f"q.{j}"] for j in robot.joint_names]))
    if not np.all(np.isfinite(err)):
        raise FloatingPointError("tracking error is not finite")
    return {"rms_error_deg": float(np.sqrt(np.mean(err ** 2))),
            "max_error_deg": float(np.abs(err).max()),
            "rms_error_deg_per_joint": dict(zip(robot.joint_names, np.sqrt(np.mean(err ** 2, axis=0)).tolist()))}


def grid(fast: bool):
    if fast:
        return (4.0, 7.0), (0.5, 1.0), 4.0
    return SUPPLY_BAR, AREA_SCALES, 30.0


def run(ctx):
    supplies, scales, seconds = grid(ctx.fast)
    cases = [{"supply_pa": s * 1e5, "area_scale": k, "seconds": seconds, "seed": REFERENCE_SEED}
             for s in supplies for k in scales]
    results = sweep(track, cases, out=ctx.out / "sweep", **options_from_env())
    err = np.full((len(supplies), len(scales)), np.nan)
    for r in results:
        if r.ok:
            err[divmod(r.index, len(scales))] = r.result["rms_error_deg"]
    atomic_write_json(ctx.out / "grid.json", {"supply_bar": list(supplies), "area_scale": list(scales),
                                              "seconds": seconds, "rms_error_deg": [[None if np.isnan(x) else x
                                                                                    for x in row] for row in err]})
    _heat_map(ctx, supplies, scales, err, seconds)
    failed = sum(not r.ok for r in results)
    if failed == len(results):
        raise_on_failure(results, "arm2_domain_sweep")
    metrics = {"cases": len(results), "failed": failed,
               "rms_error_deg_min": float(np.nanmin(err)), "rms_error_deg_max": float(np.nanmax(err))}
    if NOMINAL[0] in supplies and NOMINAL[1] in scales:
        metrics["rms_error_deg_nominal"] = float(err[supplies.index(NOMINAL[0]), scales.index(NOMINAL[1])])
    return metrics


def _heat_map(ctx, supplies, scales, err, seconds):
    fig, ax = plt.subplots(figsize=(1.3 * len(scales) + 2.5, 0.8 * len(supplies) + 2))
    cmap = plt.get_cmap("viridis").with_extremes(bad="lightgrey")  # failed cases in grey
    im = ax.imshow(np.ma.masked_invalid(err), origin="lower", cmap=cmap, aspect="auto")
    ax.set_xticks(range(len(scales)), [f"{k:g}" for k in scales])
    ax.set_yticks(range(len(supplies)), [f"{s:g}" for s in supplies])
    for i in range(len(supplies)):
        for k in range(len(scales)):
            text = "failed" if np.isnan(err[i, k]) else f"{err[i, k]:.1f}"
            ax.text(k, i, text, ha="center", va="center", fontsize=9,
                    color="black" if np.isnan(err[i, k]) or err[i, k] > np.nanmean(err) else "white")
    ax.set_xlabel("valve area scale (x model's supply and exhaust areas)")
    ax.set_ylabel("supply pressure [bar abs]")
    fig.colorbar(im, ax=ax, label="RMS tracking error [deg]")
    ax.set_title(f"arm2 PIDF (fixed gains) on a {seconds:g} s hand-moved reference")
    fig.tight_layout()
    ctx.savefig(fig, "tracking_error_map.png")


if __name__ == "__main__":
    main(__name__)
