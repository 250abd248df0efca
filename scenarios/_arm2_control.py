"""Shared set-up of the arm2 control and identification scenarios (paper 002 §IV-V).

References: the three stored arm2 references (``controllers.reference.standard_references
("arm2", speed)``, ``models/arm2/references/``; "fast" is the same motion 2x faster), or,
without them, the procedural ``hand_moved`` references with seeds 0, 1, 2.  Runs start on the reference with both chambers at 4 bar, with sensor noise
and DAQ averaging, at the model's 100 Hz control rate.
"""
from __future__ import annotations

import warnings

import numpy as np

from controllers.pid import ARM2_PID, ARM2_PIDF
from pneumatics.robot import load_robot
from pneumatics.runner import run as run_loop
from pneumatics.sim import CommandClippedWarning, Simulation

SPEEDS = {"normal": 1.0, "fast": 2.0}
REF_SEEDS = (0, 1, 2)
START_PRESSURE_PA = 4.0e5


def references(robot, speed_name: str, duration_s: float, n: int = 3):
    """``n`` joint references (objects with reference(t), derivatives(t), time)."""
    speed = SPEEDS[speed_name]
    try:
        from controllers.reference import standard_references
    except ImportError:
        standard_references = None
    if standard_references is not None:
        refs = list(standard_references("arm2", speed))[:n]
        return [_truncate(r, duration_s) for r in refs]
    from controllers.reference import hand_moved

    return [hand_moved(robot.joint_names, robot.joint_range(), duration_s, seed=s, speed=speed)
            for s in REF_SEEDS[:n]]


def _truncate(ref, duration_s):
    if ref.time[-1] <= duration_s + 1e-9:
        return ref
    from controllers.reference import JointReference

    k = int(np.searchsorted(ref.time, duration_s, side="right"))
    kw = {"lam": ref.lam} if getattr(ref, "lam", None) is not None else {}  # the same smoothing
    return JointReference(ref.time[:k].copy(), ref.q[:k].copy(), list(ref.joint_names), **kw)


def run_controller(robot, controller_factory, ref, duration_s: float, seed: int = 0, wrap=None):
    """Run one controller (``controller_factory(sim) -> controller``) on ``ref``."""
    sim = Simulation(robot)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=START_PRESSURE_PA)
    ctrl = controller_factory(sim)
    if wrap is not None:
        ctrl = wrap(ctrl, sim)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CommandClippedWarning)
        return run_loop(sim, ctrl, min(duration_s, float(ref.time[-1])), seed=seed)


def arm2():
    return load_robot("arm2")


def gains():
    return {"pid": ARM2_PID, "pidf": ARM2_PIDF}


def mae_vs_lag(rec, joints, lags_s: np.ndarray) -> np.ndarray:
    """(len(lags),) mean absolute error [deg] between q(t + lag) and q*(t), averaged over
    joints (paper 002 Fig. 6B)."""
    q = rec.matrix("q", joints)
    r = rec.matrix("ref", joints)
    dt = float(np.median(np.diff(rec.time)))
    out = []
    for lag in lags_s:
        k = round(lag / dt)
        n = q.shape[0] - k
        out.append(float(np.degrees(np.abs(q[k:k + n] - r[:n])).mean()))
    return np.array(out)
