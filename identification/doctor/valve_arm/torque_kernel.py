"""replay.MechMods.torque compiled: the joints' friction and end-stop torques the state observer
(observer_kernel) and the rigid body's replays (replay_kernel) add at every 1 ms step.

The friction law of effects/friction.py (Armstrong-Helouvry, Dupont and Canudas de Wit,
Automatica 30, 1994), compiled once for the simulator and these (pneumatics.kernel.friction_at),
and the end stops' bumper of effects/end_stop.py, packed per joint by
:func:`pack_torque_law`; MechMods.torque is the numpy reference
(tests/test_doctor_angle_replay.py, tests/test_doctor_state_observer.py).
"""
from __future__ import annotations

import numba
import numpy as np

from pneumatics.kernel import friction_at

#: the Stribeck velocity replay.MechMods.torque runs its stictions with [rad/s]
STRIBECK_RAD_S = 0.1
#: columns of the packed torque law (J, 9): Coulomb [N m], breakaway excess [N m], viscous
#: [N m s/rad], power-law viscous [N m (s/rad)^n], its exponent n, an end stop's side (+1 upper,
#: -1 lower, 0 none), its angle [rad], stiffness [N m/rad] and damping [N m s/rad]
LAW_COLUMNS = ("coulomb", "stiction", "viscous", "power", "exponent", "stop_side", "stop_rad", "stop_k", "stop_b")


def pack_torque_law(mech, J: int) -> tuple[np.ndarray, np.ndarray]:
    """((J, 9) law, (n,) the joints it acts at) of ``mech``'s frictions and end stops (None:
    none); raises ValueError for state torques (a Python function per joint), which only the
    Python loops run (state_observer.observe_reference, replay.step_windows)."""
    law = np.zeros((J, len(LAW_COLUMNS)))
    law[:, 4] = 1.0
    if mech is None:
        return law, np.zeros(0, np.int64)
    if mech.state_torques:
        raise ValueError("state torques run only in the Python loops")
    terms = (mech.coulomb_nm, mech.stiction_extra_nm, mech.viscous_nm_s, mech.viscous_power_nm)
    for col, arr in enumerate(terms):
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


@numba.njit(cache=True, error_model="numpy", inline="always")
def joint_torques(qpos, qvel, qadr, dadr, law, active, qfrc):
    """The packed torque law's torques [N m] at the joints ``active`` into ``qfrc`` (MuJoCo's
    qfrc_applied), at the angles and velocities of MuJoCo's ``qpos`` and ``qvel``."""
    for i in range(active.size):
        j = active[i]
        v, q = qvel[dadr[j]], qpos[qadr[j]]
        tau = friction_at(v, law[j, 0], law[j, 1], STRIBECK_RAD_S, law[j, 2], law[j, 3], law[j, 4])
        side = law[j, 5]
        if side != 0.0:
            pen = max(q - law[j, 6], 0.0) if side > 0 else min(q - law[j, 6], 0.0)
            if pen != 0.0:
                tau -= law[j, 7] * pen + law[j, 8] * v
        qfrc[dadr[j]] = tau
