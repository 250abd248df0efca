"""Paper 002 §IV-A, Fig. 3: inverse dynamics of arm2 by linear regression (eqs. 1-5).

Nine datasets, as in the paper: three references x {normal speed, 2x fast, normal speed with
self-generated control perturbations}, each recorded while a PIDF controller (PID with
pressure feedback, eq. 15; plain PID limit-cycles on this arm, see docs/arm2_control.md)
tracks the reference, with sensor noise and DAQ averaging.  Velocities and accelerations
from smoothing splines of the measured angles.  Each dataset is split in time: the first
70 % is fitted, the last 30 % held out.

Metrics: ``r2_heldout`` — R^2 of the pressure differences predicted by the model with the
parameters averaged over the nine fits, on the held-out parts of all nine datasets (paper:
0.87 with average parameters); ``r2_heldout_specific`` — each dataset's own fit on its own
held-out part, averaged (paper: 0.88); ``param_cv_max`` — the largest coefficient of
variation (s.d. / |mean|) of a parameter across the nine fits (Fig. 3B's spread).
Writes ``inverse_dynamics.png`` (Fig. 3) and ``inverse_dynamics.json`` (the averaged model).
"""
from __future__ import annotations

import numpy as np

from controllers.perturbation import CommandPerturbation
from identification import inverse_dynamics as idyn
from identification.doctor.valve_arm.data import split

from ._arm2_control import arm2, gains, references, run_controller
from .common import main, plt

SUMMARY = "Fig. 3: arm2 inverse dynamics by regression (8 parameters, R^2 held out, spread over 9 datasets)"
CONDITIONS = ("normal", "fast", "perturbed")
HOLDOUT_FRACTION = 0.3


def record_datasets(robot, duration_s: float):
    """{(ref index, condition): Recording} for the nine PIDF-driven runs."""
    cfg = gains()["pidf"]
    null = robot.tables.valve[:, 0]
    refs = {"normal": references(robot, "normal", duration_s), "fast": references(robot, "fast", duration_s)}
    out = {}
    for i in range(len(refs["normal"])):
        for cond in CONDITIONS:
            ref = refs["fast" if cond == "fast" else "normal"][i]
            wrap = (lambda c, sim, s=i: CommandPerturbation(c, amplitude_v=1.5, hold_s=0.15, seed=100 + s)) \
                if cond == "perturbed" else None
            out[(i, cond)] = run_controller(robot, lambda sim, r=ref: cfg.build(r, null), ref, duration_s,
                                            seed=10 * i + CONDITIONS.index(cond), wrap=wrap)
    return out


def run(ctx):
    duration = 12.0 if ctx.fast else 60.0
    robot = arm2()
    gain = idyn.torque_gain(robot)
    recs = record_datasets(robot, duration)
    fits, train, held = {}, {}, {}
    for key, rec in recs.items():
        a, b = split(rec, HOLDOUT_FRACTION)
        train[key] = idyn.samples(a, robot.joint_range())
        held[key] = idyn.samples(b, robot.joint_range())
        fits[key] = idyn.fit(train[key], gain)
    params = np.array([f.params for f in fits.values()])
    mean_model = idyn.InverseDynamics(params.mean(axis=0), gain, params.std(axis=0, ddof=1))
    mean_model.save(ctx.out / "inverse_dynamics.json")
    ctx.written.append(ctx.out / "inverse_dynamics.json")
    r2_mean = idyn.r2(mean_model, list(held.values()))
    r2_specific = [idyn.r2(fits[k], held[k])["pooled"] for k in recs]
    r2_train = idyn.r2(mean_model, list(train.values()))
    cv = idyn.param_cv(params)
    _plot(ctx, recs, held, mean_model, fits, params, r2_mean["pooled"])
    metrics = {"r2_heldout": r2_mean["pooled"], "r2_heldout_shoulder": r2_mean["shoulder"],
               "r2_heldout_elbow": r2_mean["elbow"], "r2_heldout_specific": float(np.mean(r2_specific)),
               "r2_train": r2_train["pooled"], "param_cv_max": float(cv.max()),
               "param_cv_max_name": idyn.PARAM_NAMES[int(np.argmax(cv))], "n_datasets": len(recs),
               "dataset_seconds": duration}
    for name, v, c in zip(idyn.PARAM_NAMES, params.mean(axis=0), cv):
        metrics[f"{name.split('_')[0]}_mean"] = float(v)
        metrics[f"{name.split('_')[0]}_cv"] = float(c)
    return metrics


def _plot(ctx, recs, held, model, fits, params, r2):
    fig = plt.figure(figsize=(13, 7))
    key = (0, "normal")
    s = held[key]
    pred = model.pressure_difference(s.q, s.qd, s.qdd)
    t0 = s.time[0]
    win = s.time < t0 + 10.0
    tt = s.time[win]
    gap = np.r_[False, np.diff(tt) > 0.015]  # samples left out near the joint limits: break the line
    for j, joint in enumerate(idyn.JOINTS):
        ax = fig.add_subplot(2, 2, 1 + 2 * j)
        ax.plot(tt, np.where(gap, np.nan, s.d[win, j] / 1e5), "b", lw=1, label="measured")
        ax.plot(tt, np.where(gap, np.nan, pred[win, j] / 1e5), "r", lw=1, label="predicted")
        ax.set_ylabel(f"{joint} d = p+ - p- [bar]")
        ax.legend(fontsize=8, loc="upper right")
        if j == 1:
            ax.set_xlabel("time [s] (held-out part, reference 1, normal speed)")
    fig.axes[0].set_title(f"A: measured vs predicted pressure difference (held-out R² = {r2:.2f})")
    ax = fig.add_subplot(1, 2, 2)
    mean = params.mean(axis=0)
    markers = {"normal": "o", "fast": "s", "perturbed": "^"}
    for n, ((i, cond), f) in enumerate(fits.items()):
        x = np.arange(8) + 0.08 * (n - 4)
        ax.errorbar(x, f.params / mean, yerr=f.stderr / np.abs(mean), fmt=markers[cond], ms=4,
                    color=f"C{i}", label=f"ref {i + 1}, {cond}")
    ax.axhline(1.0, color="k", lw=0.6)
    ax.set_xticks(np.arange(8))
    ax.set_xticklabels([f"{n.split('_')[0]}\n{m:.3g}" for n, m in zip(idyn.PARAM_NAMES, mean)], fontsize=8)
    ax.set_ylabel("parameter / mean over the 9 datasets")
    ax.set_title("B: the 8 parameters fitted on 9 datasets (mean below each name)")
    ax.legend(fontsize=7, ncol=3)
    fig.suptitle("arm2 inverse dynamics by linear regression (paper 002 eqs. 1-5, Fig. 3)")
    fig.tight_layout()
    ctx.savefig(fig, "inverse_dynamics.png")


if __name__ == "__main__":
    main(__name__)
