"""The rigid body's replay windows (angle_replay.read_angles) stepped without leaving compiled
code.

Each window is its own MuJoCo state pushed by the cylinders' recorded 1 ms forces and the
joints' torque law (torque_kernel); the windows do not interact, so one compiled call steps a
window through all its steps, calling MuJoCo's ``mj_step1`` and ``mj_step2`` (one ``mj_step``
for the Euler integrator, to the bit) through their addresses (pneumatics.kernel.call_mujoco).
In Python each window's step cost the bindings' calls and small array copies beside MuJoCo's
step, about a third of a replay of humanoid38.  replay.step_windows is the readable twin
(tests/test_doctor_angle_replay.py).
"""
from __future__ import annotations

import mujoco
import numba
import numpy as np

from pneumatics.kernel import MUJOCO_FUNCTIONS, STEP1, STEP2, call_mujoco

from .torque_kernel import joint_torques


def compiled_replays_possible(model, mech) -> bool:
    """Whether :func:`window_angles` can step ``model`` under ``mech``: MuJoCo's library found,
    no state torques (Python functions), not the RK4 integrator (no half steps)."""
    return (MUJOCO_FUNCTIONS is not None and not mech.state_torques
            and model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4)


@numba.njit(cache=True, error_model="numpy")
def window_angles(fns, model_addr, data_addr, qpos, qvel, ctrl, qfrc, qadr, dadr, ids, forces, first, rows, n_sub,
                  averaged, law, active, out):
    """Step one window ``rows`` samples of ``n_sub`` 1 ms steps from its present state: each
    step the actuators ``ids`` push with ``forces[first + step]`` (F, A) and the joints take the
    packed torque law (law, active); ``out`` (rows, J) gets each sample's angles (their mean
    over the sample when ``averaged``), as MuJoCo holds them (true angles)."""
    acc = np.zeros(qadr.size)
    for step in range(rows * n_sub):
        call_mujoco(fns[STEP1], model_addr, data_addr)
        for a in range(ids.size):
            ctrl[ids[a]] = forces[first + step, a]
        joint_torques(qpos, qvel, qadr, dadr, law, active, qfrc)
        call_mujoco(fns[STEP2], model_addr, data_addr)
        for j in range(qadr.size):
            acc[j] += qpos[qadr[j]]
        if (step + 1) % n_sub == 0:
            row = (step + 1) // n_sub - 1
            for j in range(qadr.size):
                out[row, j] = acc[j] / n_sub if averaged else qpos[qadr[j]]
                acc[j] = 0.0
