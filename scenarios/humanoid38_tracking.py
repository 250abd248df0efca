"""Paper 002 §VI-A, Fig. 7: the 38-DOF humanoid tracks a 60 s whole-body reference under PIDF.

The procedure of the paper, step by step:

1. per-valve orifice calibration (static volume, all 76 chambers at once;
   :mod:`identification.orifice`) and the linearising transform that makes every valve the
   canonical sigmoid (:mod:`controllers.linearize`), "transparent to the rest of the control
   system";
2. a sinusoidal command to each joint, one at a time, the others at null: the range of motion
   per volt sets a joint-specific gain scaling, the inverse of that range (``--fast``: all
   joints at once at distinct frequencies);
3. PIDF (002 eq. 15; ``controllers.pid.PIDFCfg``) with master gains tuned by hand, times the
   scaling, on the first standard humanoid reference (``models/humanoid38/references``);
4. the same PIDF with a model-based feed-forward (002 eqs. 16-17), the torques of the
   reference from the MuJoCo rigid-body model (the paper had no humanoid model yet).

Reported for each (``_pidf``, ``_model``): the median absolute error over all joints and
samples as a percentage of each joint's range (paper, PIDF: 3.4 %), and the time lag that
minimises it (paper: ~100 ms), with the error at that lag; ``median_err_pct_range`` and
``lag_ms`` are those of the better controller (named in ``controller``).  A second PIDF run of
the same reference (other sensor noise) gives the repeatability (paper: 0.03 % of range).

The paper attributes its ~100 ms lag to "the longer air tubes connecting the (off-board) valves
to the cylinders".  The model has none; further PIDF runs add the tubes of an assumed layout
(``models/humanoid38/tubes.toml``: off-board valve bank, 1.5 m into the pelvis, routed along
the limbs, 2.5 mm bore; :mod:`pneumatics.effects.tubes`) as ``line_dynamics`` (transport
delay and tube volume).  The paper tuned its gains on the robot with its tubes; with the gains
tuned without tubes (``_pidf_tubes_same_gains``) the small joints oscillate, so the
pressure-feedback master gain k_F is re-tuned with the tubes on the first 15 s (4 s with
``--fast``) over a short grid (``retuned_kf_v_per_bar``, a calibration), the others kept.
The best lag of that run (``_pidf_tubes``), refined between samples by a parabola through the
error curve's minimum, is ``predicted_lag_ms_tubes`` -- a prediction, against
``lag_ms_refined_pidf`` without tubes (and ``predicted_lag_ms_tubes_same_gains``).
"""
from __future__ import annotations

import numpy as np

import models
from controllers.reference import standard_references
from pneumatics.effects.effect_set import EffectSet
from pneumatics.effects.tubes import load_tube_layout, tube_lengths, tube_line_dynamics
from pneumatics.runner import run as run_loop
from pneumatics.sim import Simulation

from ._humanoid import (
    START_PRESSURE_PA,
    calibrated_linearizer,
    linearized_model_pidf,
    linearized_pidf,
    pidf_gains,
    range_test,
)
from .common import main, plt

SUMMARY = "§VI-A, Fig. 7: 38-DOF humanoid tracks a 60 s reference (calibrated valves, PIDF): error % of range, lag"
FITTED_MODEL = "humanoid38"  # takes --fitted: a doctor's model.toml of humanoid38 (scenarios.common)
MAX_LAG_MS = 300
PLOTTED = ["waist_yaw", "waist_pitch", "neck_yaw", "neck_pitch", "head_pitch", "jaw",
           "left_shoulder_pitch", "left_shoulder_roll", "left_shoulder_yaw", "left_elbow",
           "left_wrist_pitch", "right_shoulder_pitch", "right_shoulder_roll", "right_elbow",
           "left_hip_pitch", "left_knee", "left_ankle_pitch", "right_hip_roll", "right_knee", "right_toe"]


def lag_curve(q, ref, span, rate_hz: float, max_lag_ms: float = MAX_LAG_MS):
    """(lags [ms], median |q(t) - ref(t - lag)| / range [%]) for lags 0..max_lag_ms."""
    lags = np.arange(int(max_lag_ms * rate_hz / 1000) + 1)
    err = [100 * np.median(np.abs(q[k:] - ref[:len(ref) - k]) / span) for k in lags]
    return lags * 1000.0 / rate_hz, np.array(err)


def refined_lag_ms(lags_ms, curve) -> float:
    """Lag [ms] at the minimum of the error curve, refined by the vertex of the parabola through
    the lowest sample and its neighbours (the curve is sampled at the 10 ms control period)."""
    k = int(np.argmin(curve))
    if k == 0 or k == len(curve) - 1:
        return float(lags_ms[k])
    y0, y1, y2 = curve[k - 1], curve[k], curve[k + 1]
    den = y0 - 2 * y1 + y2
    shift = 0.5 * (y0 - y2) / den if den > 0 else 0.0
    return float(lags_ms[k] + shift * (lags_ms[1] - lags_ms[0]))


def humanoid_tubes(robot) -> tuple[EffectSet, dict]:
    """The assumed valve-to-cylinder tubes as effects, and their lengths {actuator: m}."""
    layout = load_tube_layout(models.folder(robot.name) / "tubes.toml")
    return EffectSet(line_dynamics=tube_line_dynamics(robot, layout)), tube_lengths(robot, layout)


def retune_kf(robot, range_per_volt, ref, lin, effects, duration_s: float, grid) -> float:
    """The master k_F [V/bar] of ``grid`` with the least zero-lag median error (% of range) over
    the first ``duration_s`` of ``ref`` with ``effects`` on (the other master gains kept)."""
    span = np.ptp(robot.joint_range(), axis=1)
    errors = []
    for kf in grid:
        rec = track(robot, pidf_gains(range_per_volt, {"kf_v_per_bar": kf}), ref, lin, duration_s, seed=1,
                    effects=effects)
        q, qr = rec.matrix("q", robot.joint_names), rec.matrix("ref", robot.joint_names)
        errors.append(float(np.median(np.abs(q - qr) / span)))
    return float(grid[int(np.argmin(errors))])


def track(robot, cfg, ref, lin, duration, seed, logger=None, model: bool = False, effects=None):
    if effects is not None and robot.effects is not None:  # a fitted model's effects stay on
        effects = robot.effects.combined(effects)
    sim = Simulation(robot, effects=effects)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=START_PRESSURE_PA)
    ctrl = linearized_model_pidf(cfg, ref, lin, robot) if model else linearized_pidf(cfg, ref, lin)
    return run_loop(sim, ctrl, duration, seed=seed, logger=logger)


def run(ctx):
    duration = 8.0 if ctx.fast else 60.0
    robot = ctx.load_robot("humanoid38")
    lin, _, cal_err = calibrated_linearizer(robot, ctx.fast)
    range_per_volt = range_test(robot, lin, one_at_a_time=not ctx.fast)
    cfg = pidf_gains(range_per_volt)
    ref = standard_references("humanoid38", "normal")[0]
    logger = ctx.rerun_logger(robot, "humanoid38 tracking")
    recs = {"pidf": track(robot, cfg, ref, lin, duration, seed=1, logger=logger),
            "model": track(robot, cfg, ref, lin, duration, seed=1, model=True)}
    tubes, tube_len = humanoid_tubes(robot)
    recs["pidf_tubes_same_gains"] = track(robot, cfg, ref, lin, duration, seed=1, effects=tubes)
    kf_grid = (0.5, 1.0) if ctx.fast else (0.5, 0.75, 1.0, 1.5, 2.0)
    kf_tubes = retune_kf(robot, range_per_volt, ref, lin, tubes, 4.0 if ctx.fast else 15.0, kf_grid)
    recs["pidf_tubes"] = track(robot, pidf_gains(range_per_volt, {"kf_v_per_bar": kf_tubes}), ref, lin, duration,
                               seed=1, effects=tubes)
    if logger is not None:
        logger.close()
    again = track(robot, cfg, ref, lin, duration, seed=2) if not ctx.fast else None
    names = robot.joint_names
    rng = robot.joint_range()
    span = rng[:, 1] - rng[:, 0]
    res = {}
    for key, rec in recs.items():
        q, qr = rec.matrix("q", names), rec.matrix("ref", names)
        lags, curve = lag_curve(q, qr, span, rec.rate_hz)
        res[key] = {"q": q, "qr": qr, "lags": lags, "curve": curve, "best": int(np.argmin(curve)),
                    "per_joint": 100 * np.median(np.abs(q - qr) / span, axis=0)}
    best_key = min(("pidf", "model"), key=lambda k: res[k]["curve"][0])

    rec = recs["pidf"]
    _plot(ctx, rec, res, names)
    ctx.save_recording(rec, "tracking_pidf.csv")
    ctx.save_recording(recs["model"], "tracking_model.csv")

    b = res[best_key]
    metrics = {
        "median_err_pct_range": float(b["curve"][0]),
        "lag_ms": float(b["lags"][b["best"]]),
        "controller": best_key,
        "calib_area_rel_error_median": float(np.median(cal_err["volume"])),
        "range_test_rad_per_v_median": float(np.median(range_per_volt)),
        "duration_s": duration,
    }
    for key, r in res.items():
        metrics[f"median_err_pct_range_{key}"] = float(r["curve"][0])
        metrics[f"lag_ms_{key}"] = float(r["lags"][r["best"]])
        metrics[f"median_err_pct_range_at_lag_{key}"] = float(r["curve"][r["best"]])
        metrics[f"worst_joint_median_err_pct_range_{key}"] = float(r["per_joint"].max())
    metrics["worst_joint_pidf"] = names[int(np.argmax(res["pidf"]["per_joint"]))]
    for key in ("pidf", "pidf_tubes", "pidf_tubes_same_gains"):
        metrics[f"lag_ms_refined_{key}"] = refined_lag_ms(res[key]["lags"], res[key]["curve"])
    metrics["predicted_lag_ms_tubes"] = metrics["lag_ms_refined_pidf_tubes"]
    metrics["predicted_lag_ms_tubes_same_gains"] = metrics["lag_ms_refined_pidf_tubes_same_gains"]
    metrics["retuned_kf_v_per_bar"] = kf_tubes
    lengths = np.array(list(tube_len.values()))
    line_volume = np.array([v["volume_m3"] for v in tubes.line_dynamics.values()])
    metrics.update({"tube_length_m_min": float(lengths.min()), "tube_length_m_max": float(lengths.max()),
                    "tube_volume_over_dead_volume_median": float(np.median(line_volume / robot.tables.dead_volume)),
                    "tube_delay_ms_median": float(1000 * np.median([v["delay_s"] for v in tubes.line_dynamics.values()]))})
    if again is not None:
        q2 = again.matrix("q", names)
        metrics["repeat_diff_pct_range"] = float(100 * np.median(np.abs(q2 - res["pidf"]["q"]) / span))
    return metrics


def _plot(ctx, rec, res, names):
    """tracking.png (20 joints, PIDF and model-based PIDF against the reference) and
    tracking_lag.png (median error against time lag, with and without tubes)."""
    r = res["pidf"]
    fig, axes = plt.subplots(4, 5, figsize=(16, 10), sharex=True)
    for ax, j in zip(axes.flat, PLOTTED):
        i = names.index(j)
        ax.plot(rec.time, np.degrees(r["q"][:, i]), "r-", lw=0.9)
        ax.plot(rec.time, np.degrees(res["model"]["q"][:, i]), "b-", lw=0.6, alpha=0.7)
        ax.plot(rec.time, np.degrees(r["qr"][:, i]), "k-", lw=0.7)
        ax.set_title(f"{j} ({r['per_joint'][i]:.1f} % / {res['model']['per_joint'][i]:.1f} %)", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    for ax in axes[:, 0]:
        ax.set_ylabel("angle [deg]")
    fig.suptitle(f"humanoid38, 20 of 38 joints: reference (black), PIDF (red; median error {r['curve'][0]:.1f} % of "
                 f"range, best lag {r['lags'][r['best']]:.0f} ms), model-based PIDF (blue; "
                 f"{res['model']['curve'][0]:.1f} %) -- paper 002 Fig. 7: PIDF 3.4 %, ~100 ms", fontsize=10)
    fig.tight_layout()
    ctx.savefig(fig, "tracking.png")
    fig, ax = plt.subplots(figsize=(6, 4))
    for key, label in (("pidf", "PIDF"), ("model", "model-based PIDF"), ("pidf_tubes_same_gains", "PIDF, with tubes, same gains"),
                       ("pidf_tubes", "PIDF, with tubes, k_F re-tuned")):
        ax.plot(res[key]["lags"], res[key]["curve"], label=label)
    ax.axhline(3.4, color="k", ls=":", lw=0.8, label="paper, PIDF at zero lag")
    ax.set_xlabel("time lag [ms]")
    ax.set_ylabel("median |error| [% of joint range]")
    ax.set_title("humanoid38 tracking error vs lag (cf. paper 002 Fig. 6B)")
    ax.legend(fontsize=8)
    ctx.savefig(fig, "tracking_lag.png")


if __name__ == "__main__":
    main(__name__)
