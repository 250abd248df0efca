"""Compiled fine step of the state observer (state_observer.observe), between MuJoCo's two
half steps.

``mj_step2`` then ``mj_step1`` make one ``mj_step`` for the Euler integrator (MuJoCo
documentation, "mj_step1 / mj_step2"; the same to the bit, tests/test_doctor_state_observer.py)
and leave the actuators' lengths at the new positions, so between them :func:`fine_step` takes
those lengths, steps every chamber over the millisecond just simulated
(chamber_kernel.step_batch) and adds the sample's sums, and :func:`set_actuation` sets the
cylinders' forces and the joints' friction and end-stop torques for the next step (RK4 has no
such split: a model integrated with it runs the reference loop).  In Python every 1 ms step of humanoid38
cost about 125 us, MuJoCo's step 50 us of it and the rest small numpy calls; with these calls
about 65 us.
state_observer.observe_reference is the readable twin, checked against this path to round-off.

The joints' torques are replay.MechMods.torque's: the friction law of effects/friction.py
(Armstrong-Helouvry et al., Automatica 30, 1994, with tanh for sign) and the end stops' bumper
of effects/end_stop.py, packed per joint by :func:`pack_torque_law`.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from pneumatics.effects.friction import SMOOTH_RAD_S

from .chamber_kernel import step_batch

#: the Stribeck velocity replay.MechMods.torque runs its stictions with [rad/s]
STRIBECK_RAD_S = 0.1
#: columns of the packed torque law (J, 9): Coulomb [N m], breakaway excess [N m], viscous
#: [N m s/rad], power-law viscous [N m (s/rad)^n], its exponent n, an end stop's side (+1 upper,
#: -1 lower, 0 none), its angle [rad], stiffness [N m/rad] and damping [N m s/rad]
LAW_COLUMNS = ("coulomb", "stiction", "viscous", "power", "exponent", "stop_side", "stop_rad", "stop_k", "stop_b")


def pack_torque_law(mech, J: int) -> tuple[np.ndarray, np.ndarray]:
    """((J, 9) law, (n,) the joints it acts at) of ``mech``'s frictions and end stops (None:
    none); raises ValueError for state torques (a Python function per joint), which only the
    reference loop runs."""
    law = np.zeros((J, len(LAW_COLUMNS)))
    law[:, 4] = 1.0
    if mech is None:
        return law, np.zeros(0, np.int64)
    if mech.state_torques:
        raise ValueError("state torques run only in state_observer.observe_reference")
    for col, arr in ((0, mech.coulomb_nm), (1, mech.stiction_extra_nm), (2, mech.viscous_nm_s), (3, mech.viscous_power_nm)):
        if arr is not None:
            law[:, col] = np.broadcast_to(np.asarray(arr, float), (J,))
    for j, n in mech.viscous_exponents.items():
        law[j, 4] = n
    if mech.end_stop_nm_per_rad is not None and mech.end_stops:
        for j, (stop, side) in mech.end_stops.items():
            b = 0.0 if mech.end_stop_nm_s_per_rad is None else mech.end_stop_nm_s_per_rad[j]
            law[j, 5:9] = (1.0 if side > 0 else -1.0), stop, mech.end_stop_nm_per_rad[j], b
    active = np.nonzero(np.any(law[:, [0, 1, 2, 3, 5]] != 0.0, axis=1))[0].astype(np.int64)
    return law, active


@numba.njit(cache=True, error_model="numpy")
def set_actuation(p, qpos, qvel, qadr, dadr, ids, area_a, area_b, room_pa, law, active, ctrl, qfrc):
    """The cylinders' forces (chamber.actuator_force) from pressures p (1, C) into ``ctrl``, and
    the torque law's torques at the joints ``active`` into ``qfrc`` (MuJoCo's qfrc_applied)."""
    for a in range(ids.size):
        ctrl[ids[a]] = area_a[a] * p[0, 2 * a] - area_b[a] * p[0, 2 * a + 1] - (area_a[a] - area_b[a]) * room_pa
    for i in range(active.size):
        j = active[i]
        v, q = qvel[dadr[j]], qpos[qadr[j]]
        s = math.tanh(v / SMOOTH_RAD_S)
        speed = max(abs(v), SMOOTH_RAD_S)
        tau = -(law[j, 0] * s + law[j, 1] * math.exp(-(v / STRIBECK_RAD_S) ** 2) * s + law[j, 2] * v
                + law[j, 3] * v * speed ** (law[j, 4] - 1.0))
        side = law[j, 5]
        if side != 0.0:
            pen = max(q - law[j, 6], 0.0) if side > 0 else min(q - law[j, 6], 0.0)
            if pen != 0.0:
                tau -= law[j, 7] * pen + law[j, 8] * v
        qfrc[dadr[j]] = tau


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
