"""The mass of a joint's subtree as a nuisance beside a constant force or a friction: where the
rigid body is held nominal, its mass errors load each joint with a gravity torque the replays do
not carry, and where the joint's gravity torque varies little over the recording that error
looks like a constant actuator force -- a pressure-sensor offset; at humanoid38's jaw, light and
damped 0.05 N m s/rad, like a friction (output_error_fit.MASS_NUISANCE).

Humanoid38's development recordings (+-3 % body masses and inertias; 2026-12-06, seeds of the
fresh runs of that day, looked at after they were reported): the output-error search named
nine pressure-sensor offsets of 1.3-3.2 kPa at the jaw and the knees on eight cases without
one (a null among them), each joint's of one sign.  A 3 % error of the jaw's mass is about 1e-3 N m
of gravity torque, what a 1.7 kPa offset on its 0.59 cm^3/rad vane gives.  Fitted beside its
subtree's mass scale, the right knee's offset of seed 519139745 fell from 7.6 to 1.7 standard
errors (the mass scale took -4.3 %), the jaw's of the null 519139759 from 6.9 to 2.8 (+3.9 %);
the true 6.2 kPa offset at the right knee of 519139761 stood at 8.2.  The screen fits the
subtree's one scale (a replay per level of the tree); a candidate's own fit fits the masses of
the subtree's first bodies one by one (:func:`body_sensitivities`, :func:`body_groups`), which
the screen's one scale cannot stand for where the bodies' errors differ.

The offset is fitted beside the nuisance by partialling it out (Frisch & Waugh, Econometrica
1(4), 1933; Lovell, JASA 58(304), 1963): the offset's sensitivity and the residual are each
taken off their projection on the nuisance's sensitivity, and the offset alone is fitted to
what is left.  Its value and its cluster-robust standard error are those of the joint fit (the
windows' scores are the same), and the share of the residual it removes is its share of what
the nuisance leaves.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .angle_replay import pressure_driven_angles
from .replay import MechMods

#: the probe: the subtree's masses and inertias scaled by 1 + MASS_PROBE, small enough for the
#: replay to answer linearly, large against its round-off
MASS_PROBE = 0.03


def subtree_bodies(model, joint: str) -> list[str]:
    """The bodies the joint ``joint`` moves (its own body and every body below it) that have mass."""
    top = int(model.joint(joint).bodyid[0])
    out = []
    for b in range(1, model.nbody):
        x = b
        while x > 0 and x != top:
            x = int(model.body_parentid[x])
        if x == top and model.body_mass[b] > 0:
            out.append(model.body(b).name)
    return out


def with_subtree_masses(mm: MechMods, model, joint_names, joints, share: float) -> MechMods:
    """``mm`` with the masses below each of ``joints`` (indices) changed by ``share``."""
    return with_body_masses(mm, [b for j in joints for b in subtree_bodies(model, joint_names[j])], share)


def with_body_masses(mm: MechMods, bodies, share: float) -> MechMods:
    """``mm`` with the masses (and inertias) of ``bodies`` changed by ``share``."""
    scale = dict(mm.mass_scale)
    for b in bodies:
        scale[b] = scale.get(b, 0.0) + share
    return replace(mm, mass_scale=scale)


def mass_sensitivity(exp, run, mm: MechMods, base_q: np.ndarray, joints, every: int, rows) -> np.ndarray:
    """(W, H, J) d q_j / d (subtree mass scale of j) at the windows ``rows`` of
    pressure_driven_angles(..., every) for each of ``joints``, all probed in one replay (no one
    of them an ancestor of another: their subtrees are apart); the others NaN.  ``base_q``:
    that replay of ``mm`` at ``rows``."""
    robot = run.robot
    probed = with_subtree_masses(mm, robot.model, robot.joint_names, joints, MASS_PROBE)
    q = pressure_driven_angles(exp, run.mods, probed, every=every, observer_mech=mm)[rows]
    out = np.full(base_q.shape, np.nan)
    out[..., list(joints)] = (q[..., list(joints)] - base_q[..., list(joints)]) / MASS_PROBE
    return out


#: at most this many mass nuisances beside a candidate offset: the joint's body and the next
#: ones below it on their own, the rest of its subtree as one.  Each is a replay per candidate
#: and round; one per body cost a fresh case (817822052, 2026-12-07) 862 s, eight arm and waist
#: joints screened for offsets, `waist_yaw`'s subtree of 25 bodies among them
MAX_BODY_GROUPS = 4


def body_groups(model, joint: str, most: int = MAX_BODY_GROUPS) -> list[list[str]]:
    """The bodies with mass of ``joint``'s subtree in at most ``most`` groups: the first
    ``most`` - 1 in the model's tree order (the joint's own body, then down its first branch)
    each alone, the rest together; each body alone when they are no more than ``most``."""
    bodies = subtree_bodies(model, joint)
    if len(bodies) <= most:
        return [[b] for b in bodies]
    return [[b] for b in bodies[:most - 1]] + [bodies[most - 1:]]


def body_sensitivities(exp, run, mm: MechMods, base_q: np.ndarray, joint: int, every: int, rows) -> np.ndarray:
    """(W, H, m) d q_j / d (mass scale of each of joint j's :func:`body_groups`, m of them) at
    the windows ``rows`` of pressure_driven_angles(..., every): one replay per group.  Each body's
    mass is off on its own (+-3 % on humanoid38's cases, as a real robot's links are weighed
    one by one), and one scale for the whole subtree leaves what their different lever arms
    give: a false 0.55 kPa offset at the left ankle pitch of development seed 7101 stood 8.6
    standard errors from zero beside the subtree's scale and 1.9 beside its three bodies' (its
    link +1.8 %, the foot +0.4 %, the toe -2.9 %); true offsets of 3.8 and 7.1 kPa at the neck
    yaw and left elbow of seeds 7102-7103 stood at 9.4 and 17.1 (6.9 and 17.8 beside the scale)."""
    robot = run.robot
    cols = []
    for group in body_groups(robot.model, robot.joint_names[joint]):
        q = pressure_driven_angles(exp, run.mods, with_body_masses(mm, group, MASS_PROBE), every=every,
                                   observer_mech=mm)[rows]
        cols.append((q[..., joint] - base_q[..., joint]) / MASS_PROBE)
    return np.stack(cols, axis=-1) if cols else np.zeros(base_q.shape[:2] + (0,))  # no mass: no nuisance


def partialled(a: np.ndarray, nuisance: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(a, r) each taken off its least-squares projection on ``nuisance`` (W, H) or (W, H, m),
    m nuisances at once: what the nuisances cannot explain; ``a`` (W, H) or (W, H, k), each of
    its k columns on its own, ``r`` (W, H).  Nuisances that do not move the angle leave both as
    they are, as does an empty set of windows (a joint whose replays all failed)."""
    rows = nuisance.shape[0] * nuisance.shape[1]
    n = nuisance.reshape(rows, nuisance.shape[2] if nuisance.ndim == 3 else 1)
    keep = np.all(np.isfinite(n), axis=0) & (np.sum(n ** 2, axis=0) > 0)   # no rows: none kept
    if not np.any(keep):
        return a, r

    def off(x):
        flat = x.reshape(rows, x.shape[2] if x.ndim == 3 else 1)
        coef = np.linalg.lstsq(n[:, keep], flat, rcond=None)[0]
        return (flat - n[:, keep] @ coef).reshape(x.shape)

    return off(a), off(r)
