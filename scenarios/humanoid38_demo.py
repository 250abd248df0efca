"""A few seconds of the 38-DOF humanoid under open-loop valve patterns.

Every joint's two valves are driven in antiphase around their own null by slow sines of
different frequencies, amplitudes and phases (a "breathing" pattern that moves every joint),
interrupted by a half-second where every valve is opened fully one way.  The run must stay
finite, warning-free and physically plausible: pressures positive, near [room, supply] and
exceeding it only where a piston compresses a chamber.
"""
from __future__ import annotations

import numpy as np

from pneumatics.runner import OpenLoop, run as run_loop
from pneumatics.sim import Simulation

from .common import main, plt

SUMMARY = "38-DOF humanoid under open-loop valve patterns: finite, warning-free, plausible pressures"
FITTED_MODEL = "humanoid38"  # takes --fitted: a doctor's model.toml of humanoid38 (scenarios.common)


def pattern(n_act: int, null_v: np.ndarray, seed: int = 0):
    rng = np.random.default_rng(seed)
    freq = rng.uniform(0.3, 1.2, n_act)
    amp = rng.uniform(0.3, 1.5, n_act)
    phase = rng.uniform(0, 2 * np.pi, n_act)

    def commands(t):
        e = amp * np.sin(2 * np.pi * freq * t + phase)
        if 2.0 <= t < 2.5:  # everything full open one way
            e = np.full(n_act, 5.0)
        u = np.empty(2 * n_act)
        u[0::2] = null_v[0::2] + e
        u[1::2] = null_v[1::2] - e
        return np.clip(u, 0, 10)

    return commands


def run(ctx):
    duration = 3.0 if ctx.fast else 8.0
    robot = ctx.load_robot("humanoid38")
    sim = Simulation(robot)
    sim.reset(pressure_pa=4.0e5)
    n_act = len(robot.actuator_names)
    logger = ctx.rerun_logger(robot, "humanoid38 demo")
    rec = run_loop(sim, OpenLoop(pattern(n_act, robot.tables.valve[:, 0])), duration, noise=False, logger=logger)
    if logger is not None:
        logger.close()
    warnings = {w: int(sim.data.warning[i].number) for i, w in enumerate(
        ["inertia", "contactfull", "cnstrfull", "vgeomfull", "badqpos", "badqvel", "badqacc", "badctrl"])
        if i < len(sim.data.warning)}
    p = np.column_stack([rec.matrix("p_a", robot.actuator_names), rec.matrix("p_b", robot.actuator_names)])
    q = rec.matrix("q", robot.joint_names)
    rng_ = robot.joint_range()
    span = rng_[:, 1] - rng_[:, 0]
    frac = (q - rng_[:, 0]) / span
    fig, axes = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    for j in range(0, len(robot.joint_names), 2):
        axes[0].plot(rec.time, frac[:, j], lw=0.8)
    axes[0].set_ylabel("joint position [fraction of range]\n(every second joint)")
    axes[1].plot(rec.time, p / 1e5, lw=0.5)
    axes[1].set_ylabel("76 chamber pressures [bar abs]")
    axes[1].set_xlabel("time [s]")
    axes[0].set_title("humanoid38 under open-loop valve patterns")
    fig.tight_layout()
    ctx.savefig(fig, "humanoid38_demo.png")
    return {
        "max_pressure_pa": float(p.max()),
        "min_pressure_pa": float(p.min()),
        "finite": bool(np.all(np.isfinite(p)) and np.all(np.isfinite(q))),
        "mujoco_warnings": int(sum(warnings.values())),
        "joint_travel_median_frac": float(np.median(np.ptp(frac, axis=0))),
        "duration_s": duration,
    }


if __name__ == "__main__":
    main(__name__)
