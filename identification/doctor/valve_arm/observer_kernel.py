"""Compiled fine step of the state observer (state_observer.observe), between MuJoCo's two
half steps.

``mj_step2`` then ``mj_step1`` make one ``mj_step`` for the Euler integrator (MuJoCo
documentation, "mj_step1 / mj_step2"; the same to the bit, tests/test_doctor_state_observer.py)
and leave the actuators' lengths at the new positions, so between them :func:`fine_step` takes
those lengths, steps every chamber over the millisecond just simulated
(chamber_kernel.step_batch) and adds the sample's sums, and :func:`set_actuation` sets the
cylinders' forces and the joints' friction and end-stop torques for the next step (RK4 has no
such split: a model integrated with it runs the reference loop).  In Python every 1 ms step of
humanoid38 cost about 125 us, MuJoCo's step 50 us of it and the rest small numpy calls; with
these calls about 65 us.  state_observer.observe_reference is the readable twin, checked
against this path to round-off.

The joints' torques are replay.MechMods.torque's, compiled in torque_kernel.py.
"""
from __future__ import annotations

import numba

from pneumatics.kernel import write_forces

from .chamber_kernel import step_batch
from .torque_kernel import joint_torques


@numba.njit(cache=True, error_model="numpy")
def set_actuation(p, qpos, qvel, qadr, dadr, act, glob, law, active, ctrl, qfrc):
    """The cylinders' forces from pressures p (1, C) into ``ctrl`` (the simulator's
    pneumatics.kernel.write_forces, ``act`` and ``glob`` of pneumatics.kernel.pack), and the
    torque law's torques at the joints ``active`` into ``qfrc`` (MuJoCo's qfrc_applied)."""
    write_forces(p[0], ctrl, act, glob)
    joint_torques(qpos, qvel, qadr, dadr, law, active, qfrc)


@numba.njit(cache=True, error_model="numpy")
def chamber_travel(length, ids, act, length_zero, stroke, is_a, out):
    """Each chamber's travel (1, C) [m] from MuJoCo's actuator lengths (pneumatic.ChamberModel.travel)."""
    for c in range(out.shape[1]):
        a = act[c]
        x = min(max(length[ids[a]] - length_zero[a], 0.0), stroke[a])
        out[0, c] = x if is_a[c] else stroke[a] - x


@numba.njit(cache=True, error_model="numpy")
def fine_step(f, p, u, travel0, travel1, length, ids, act, length_zero, stroke, is_a, receiver, supply_pa, kargs,
              T, p_tube, supply_shift, acc_p, qpos, qadr, acc_q, p_next):
    """After MuJoCo's step to fine step f + 1: the chambers' travels there (travel1), their
    pressures ``p_next`` (1, C) from p over the step with commands u (1, C), the supply's
    receiver path followed (an empty ``receiver``: none); the sample's sums of angles and
    pressures.  ``kargs``: pneumatic.ChamberModel's packed kernel arguments."""
    chamber_travel(length, ids, act, length_zero, stroke, is_a, travel1)
    if receiver.size > 0:
        supply_shift[0] = receiver[min(f, receiver.size - 1)] - supply_pa
    step_batch(p, u, travel0, travel1, kargs[0], kargs[1], kargs[2], kargs[3], kargs[4], kargs[5], kargs[6], kargs[7],
               kargs[8], kargs[9], kargs[10], kargs[11], kargs[12], kargs[13], kargs[14], kargs[15], kargs[16], kargs[17],
               p_next, kargs[18], T, kargs[19], supply_shift, kargs[20], kargs[21], p_tube)
    for c in range(acc_p.size):
        acc_p[c] += p_next[0, c]
    for j in range(acc_q.size):
        acc_q[j] += qpos[qadr[j]]
    travel0[:, :] = travel1
