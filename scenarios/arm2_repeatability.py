"""Paper 002 §V, Fig. 6C: repeatability of PIDF control and recovery from pushes.

A shorter reference is repeated three times in one run (each repetition followed by a
smooth return to its start, so the three are identical); the first repetition is discarded.
During the third the "experimenter" pushes the forearm (a Cartesian force on its centre of
mass through MuJoCo's ``data.xfrc_applied``, :class:`controllers.perturbation.ExternalPush`).
Runs 2 and 3 differ before the first push only by sensor noise; after each push the third
run should converge back onto the second.

Metrics: ``repeat_diff_deg`` — mean absolute difference between runs 2 and 3 (over both
joints) before the first push; ``reconverge_s`` — the longest time, over the pushes, from
the end of a push until the difference falls below ``RECONVERGED_DEG`` and stays there until
the next push (or the end); ``push_peak_deviation_deg`` — the largest difference during a
push; ``reconverged`` — 1 if every push was recovered within its window.
Writes ``repeatability.png``.
"""
from __future__ import annotations

import numpy as np

from controllers.perturbation import ExternalPush
from controllers.reference import JointReference, min_jerk

from ._arm2_control import gains, references, run_controller
from .common import main, plt

SUMMARY = "Fig. 6C: PIDF repeats a reference three times; pushes on the last, re-convergence"
FITTED_MODEL = "arm2"  # takes --fitted: a doctor's model.toml of arm2 (scenarios.common)
RETURN_S = 1.0
HOLD_S = 0.5
PUSH_S = 0.2
RECONVERGED_DEG = 1.0


def repeated(ref, times: int = 3) -> tuple[JointReference, float]:
    """The reference ``times`` times, each followed by a min-jerk return to its start; (ref, period)."""
    dt = float(np.median(np.diff(ref.time)))
    q = ref.q
    n_ret = round(RETURN_S / dt)
    s = min_jerk(np.linspace(0.0, 1.0, n_ret))[:, None]
    back = q[-1] + (q[0] - q[-1]) * s
    hold = np.repeat(q[:1], round(HOLD_S / dt), axis=0)
    one = np.vstack([q, back[1:], hold])
    period = one.shape[0] * dt
    allq = np.vstack([one] * times)
    return JointReference(np.arange(allq.shape[0]) * dt, allq, list(ref.joint_names)), period


def run(ctx):
    robot = ctx.load_robot("arm2")
    base_s = 5.0 if ctx.fast else 15.0
    base = references(robot, "normal", base_s, 1)[0]
    ref, period = repeated(base)
    # pushes in the third repetition: forearm pushed sideways and forwards
    push_at = [0.35, 0.7] if not ctx.fast else [0.45]
    forces = [(12.0, 12.0, 0.0), (-12.0, 8.0, 0.0)]
    windows = [(2 * period + f * period, 2 * period + f * period + PUSH_S, forces[k]) for k, f in enumerate(push_at)]
    null = robot.tables.valve[:, 0]
    cfg = gains()["pidf"]
    rec = run_controller(robot, lambda sim: cfg.build(ref, null), ref, float(ref.time[-1]), seed=3,
                         wrap=lambda c, sim: ExternalPush(c, sim, "forearm", windows))
    dt = float(np.median(np.diff(rec.time)))
    n = round(period / dt)
    q = np.degrees(rec.matrix("q", robot.joint_names))
    run2, run3 = q[n:2 * n], q[2 * n:3 * n]
    t_rel = np.arange(n) * dt
    diff = np.abs(run3 - run2).mean(axis=1)
    first = windows[0][0] - 2 * period
    before = t_rel < first
    recon, peaks, ok = [], [], True
    for k, (t0, t1, _) in enumerate(windows):
        a, b = t0 - 2 * period, t1 - 2 * period
        end = windows[k + 1][0] - 2 * period if k + 1 < len(windows) else t_rel[-1] + dt
        during = (t_rel >= a) & (t_rel < b)
        peaks.append(float(diff[during].max()))
        after = (t_rel >= b) & (t_rel < end)
        above = np.where(diff[after] > RECONVERGED_DEG)[0]
        if above.size == 0:
            recon.append(0.0)
        elif above[-1] == after.sum() - 1:
            ok = False
            recon.append(float(end - b))
        else:
            recon.append(float((above[-1] + 1) * dt))
    _plot(ctx, robot, t_rel, run2, run3, diff, windows, period)
    return {"repeat_diff_deg": float(diff[before].mean()), "reconverge_s": float(max(recon)),
            "push_peak_deviation_deg": float(max(peaks)), "reconverged": int(ok),
            "n_pushes": len(windows), "push_force_n": float(np.linalg.norm(forces[0])),
            "repetition_s": float(period)}


def _plot(ctx, robot, t, run2, run3, diff, windows, period):
    fig, axes = plt.subplots(3, 1, figsize=(11, 7.5), sharex=True)
    for j, joint in enumerate(robot.joint_names):
        ax = axes[j]
        ax.plot(t, run2[:, j], "b", lw=1.2, label="repetition 2")
        ax.plot(t, run3[:, j], "r", lw=1.0, label="repetition 3 (pushed)")
        for t0, t1, _ in windows:
            a = t0 - 2 * period
            y = run3[np.searchsorted(t, a), j]
            ax.annotate("", xy=(a, y), xytext=(a, y + 25), arrowprops={"arrowstyle": "->", "color": "k"})
        ax.set_ylabel(f"{joint} [deg]")
        ax.legend(fontsize=8, loc="upper right")
    axes[2].semilogy(t, np.maximum(diff, 1e-3), "k", lw=1)
    axes[2].axhline(RECONVERGED_DEG, color="g", ls="--", lw=0.8, label=f"{RECONVERGED_DEG:g} deg")
    for t0, t1, _ in windows:
        axes[2].axvspan(t0 - 2 * period, t1 - 2 * period, color="orange", alpha=0.3)
    axes[2].set_ylabel("|rep. 3 - rep. 2| [deg]")
    axes[2].set_xlabel("time within the repetition [s]")
    axes[2].legend(fontsize=8)
    fig.suptitle("arm2 PIDF repeatability: same reference twice, pushes (arrows) on the second (paper 002 Fig. 6C)")
    fig.tight_layout()
    ctx.savefig(fig, "repeatability.png")


if __name__ == "__main__":
    main(__name__)
