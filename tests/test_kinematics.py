"""controllers.kinematics: pytorch-kinematics FK and Jacobians against MuJoCo, in float64."""
from __future__ import annotations

import mujoco
import numpy as np
import pytest
import pytorch_kinematics as pk
import torch

import models
from controllers.kinematics import (ArmKinematics, JointOffsetError, UnsupportedJointError,
                                    build_chain, load_model)
from pneumatics.errors import UnknownNameError

N_CONFIGS = 20
ATOL = 1e-9

HUMANOID = models.ROOT / "humanoid38" / "humanoid38.xml"
needs_humanoid = pytest.mark.skipif(not HUMANOID.is_file(),
                                    reason="models/humanoid38/humanoid38.xml not built yet")


def random_qpos(m: mujoco.MjModel, rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, nq) configurations: every hinge/slide uniform in its range ([-pi, pi] if unlimited)."""
    qpos = np.tile(m.qpos0, (n, 1))
    for j in range(m.njnt):
        if m.jnt_type[j] in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            lo, hi = m.jnt_range[j] if m.jnt_limited[j] else (-np.pi, np.pi)
            qpos[:, m.jnt_qposadr[j]] = rng.uniform(lo, hi, n)
    return qpos


def mujoco_reference(m: mujoco.MjModel, qpos: np.ndarray, body: int, site: int | None):
    """Per configuration: end position (3,), rotation (3, 3), jacp and jacr (3, nv)."""
    d = mujoco.MjData(m)
    out = []
    for qp in qpos:
        d.qpos[:] = qp
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)  # mj_jac* needs cdof/subtree_com
        jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        if site is None:
            mujoco.mj_jacBody(m, d, jacp, jacr, body)
            pos, mat = d.xpos[body].copy(), d.xmat[body].reshape(3, 3).copy()
        else:
            mujoco.mj_jacSite(m, d, jacp, jacr, site)
            pos, mat = d.site_xpos[site].copy(), d.site_xmat[site].reshape(3, 3).copy()
        out.append((pos, mat, jacp, jacr))
    return [np.stack(x) for x in zip(*out)]


def check_end(m: mujoco.MjModel, end: str, rng: np.random.Generator) -> None:
    """ArmKinematics(m, end) against MuJoCo; ``end`` is a body name or ``"site:NAME"``."""
    arm = ArmKinematics(m, end)
    if end.startswith("site:"):
        body, site = -1, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, end[5:])
    else:
        body, site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, end), None
    if site is not None:
        body = int(m.site_bodyid[site])
    qpos = random_qpos(m, rng, N_CONFIGS)
    pos, mat, jacp, jacr = mujoco_reference(m, qpos, body, site)
    q = arm.q_from_qpos(qpos)

    np.testing.assert_allclose(arm.fk(q), pos, rtol=0, atol=ATOL, err_msg=f"fk {end}")
    np.testing.assert_allclose(arm.pose(q)[:, :3, :3], mat, rtol=0, atol=ATOL, err_msg=f"rot {end}")
    J = arm.jacobian(q)
    assert J.shape == (N_CONFIGS, 6, arm.n)
    np.testing.assert_allclose(J[:, :3], jacp[:, :, arm.dof_indices], rtol=0, atol=ATOL,
                               err_msg=f"jacp {end}")
    np.testing.assert_allclose(J[:, 3:], jacr[:, :, arm.dof_indices], rtol=0, atol=ATOL,
                               err_msg=f"jacr {end}")
    np.testing.assert_array_equal(arm.jacobian(q, position_only=True), J[:, :3])
    # the chain holds every dof that moves the end point
    others = np.setdiff1d(np.arange(m.nv), arm.dof_indices)
    assert np.all(jacp[:, :, others] == 0) and np.all(jacr[:, :, others] == 0)


def check_full_tree(m: mujoco.MjModel, rng: np.random.Generator) -> None:
    chain = build_chain(m)
    names = chain.get_joint_parameter_names()
    qadr = [m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in names]
    qpos = random_qpos(m, rng, N_CONFIGS)
    T = chain.forward_kinematics(torch.as_tensor(qpos[:, qadr]))
    body_frame = [m.body(b).name or f"body{b}" for b in range(m.nbody)]
    site_frame = [m.site(s).name or f"site{s}" for s in range(m.nsite)]
    site_frame = [f"site:{n}" if n in body_frame else n for n in site_frame]
    d = mujoco.MjData(m)
    for k, qp in enumerate(qpos):
        d.qpos[:] = qp
        mujoco.mj_kinematics(m, d)
        for b in range(1, m.nbody):
            M = T[body_frame[b]].get_matrix()[k].numpy()
            np.testing.assert_allclose(M[:3, 3], d.xpos[b], rtol=0, atol=ATOL)
            np.testing.assert_allclose(M[:3, :3], d.xmat[b].reshape(3, 3), rtol=0, atol=ATOL)
        for s in range(m.nsite):
            M = T[site_frame[s]].get_matrix()[k].numpy()
            np.testing.assert_allclose(M[:3, 3], d.site_xpos[s], rtol=0, atol=ATOL)


# ------------------------------------------------------------------------------------ arm2

def test_arm2_site_and_body():
    m = load_model("arm2")
    rng = np.random.default_rng(0)
    check_end(m, "site:hand", rng)
    check_end(m, "forearm", rng)
    check_full_tree(m, rng)


def test_arm2_api():
    arm = ArmKinematics("arm2", "hand")
    assert arm.joint_names == ["shoulder", "elbow"]
    assert list(arm.dof_indices) == [0, 1]
    assert isinstance(arm.chain, pk.SerialChain)
    q = arm.sample(7, np.random.default_rng(1))
    assert q.shape == (7, 2) and np.all(q >= arm.lower) and np.all(q <= arm.upper)
    # q = 0: the arm points straight up, hand 0.32 m above the shoulder
    np.testing.assert_allclose(arm.fk(np.zeros(2)), [0, 0, 0.32], atol=1e-15)
    assert arm.fk(q).shape == (7, 3) and arm.fk(q[0]).shape == (3,)
    assert arm.jacobian(q[0]).shape == (6, 2) and arm.jacobian(q, True).shape == (7, 3, 2)
    # torch in -> torch out, differentiable, matching the Jacobian
    qt = torch.tensor(q, requires_grad=True)
    p = arm.fk(qt)
    assert torch.is_tensor(p)
    g, = torch.autograd.grad(p[:, 2].sum(), qt)
    np.testing.assert_allclose(g.numpy(), arm.jacobian(q)[:, 2, :], atol=1e-12)
    # a body plus site_offset is the same point as the site
    via_body = ArmKinematics("arm2", "forearm", site_offset=[0, 0, 0.32])
    np.testing.assert_allclose(via_body.fk(q), arm.fk(q), atol=1e-15)
    np.testing.assert_allclose(via_body.jacobian(q), arm.jacobian(q), atol=1e-15)
    with pytest.raises(ValueError, match=r"shape \(B, 2\)"):
        arm.fk(np.zeros(3))
    with pytest.raises(UnknownNameError, match="valid"):
        ArmKinematics("arm2", "nose")


# ------------------------------------------------------------------------------------ humanoid

@needs_humanoid
def test_humanoid38_ends():
    m = load_model(HUMANOID)
    rng = np.random.default_rng(2)
    children = set(int(p) for p in m.body_parentid[1:])
    leaves = [m.body(b).name for b in range(1, m.nbody) if b not in children]
    sites = [f"site:{m.site(s).name}" for s in range(m.nsite)]
    assert leaves
    for end in leaves + sites:
        check_end(m, end, rng)


@needs_humanoid
def test_humanoid38_full_tree():
    check_full_tree(load_model(HUMANOID), np.random.default_rng(3))


# ------------------------------------------------------------------------------------ odd models

OFFSET_JOINT = """
<mujoco>
  <worldbody>
    <body name="a">
      <joint name="j1" axis="0 1 0"/>
      <geom size="0.05"/>
      <body name="b" pos="0 0 0.3">
        <joint name="j2" axis="1 0 0" pos="0 0 0.1"/>
        <geom size="0.05"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_joint_pos_offset_raises():
    with pytest.raises(JointOffsetError, match=r"joint 'j2' of body 'b' has pos=\[0\.0, 0\.0, 0\.1\]"):
        build_chain(OFFSET_JOINT)
    with pytest.raises(JointOffsetError, match="nonzero joint offset"):
        ArmKinematics(OFFSET_JOINT, "b")
    # a chain that does not contain the offset joint is fine
    assert ArmKinematics(OFFSET_JOINT, "a").joint_names == ["j1"]


MIXED = """
<mujoco>
  <worldbody>
    <body name="base" pos="0.1 -0.2 0.5" euler="0.2 0.3 0.4">
      <body name="carriage" pos="0.05 0 0" quat="0.9 0.2 0.1 0.3">
        <joint name="lift" type="slide" axis="0.2 0.1 1" range="-0.2 0.2"/>
        <joint name="yaw" axis="0.3 0.4 1"/>
        <geom size="0.05"/>
        <body name="hand" pos="0.123456789 0.3 0.7" quat="0.9 0.1 0.3 0.2">
          <joint name="roll" axis="1 0.2 0" range="-1 1"/>
          <geom size="0.05"/>
          <site name="hand" pos="0.1 0.2 0.3" euler="0.1 0.2 0.3"/>
          <site name="tip" pos="0 0 0.4"/>
        </body>
      </body>
      <body name="ball_link" pos="0 0.3 0">
        <joint name="ball" type="ball"/>
        <geom size="0.05"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_slide_multi_joint_body_and_name_clash():
    """Slide + hinge on one body, unnormalized axes, odd poses, a site named like a body."""
    m = load_model(MIXED)
    rng = np.random.default_rng(4)
    check_end(m, "hand", rng)    # the body
    check_end(m, "site:tip", rng)
    check_end(m, "site:hand", rng)  # the site, not the body of the same name
    assert ArmKinematics(m, "site:hand").joint_names == ["lift", "yaw", "roll"]
    assert ArmKinematics(m, "hand").chain.get_frame_names(exclude_fixed=False)[-1] == "hand"
    assert ArmKinematics(m, "site:hand").chain.get_frame_names(exclude_fixed=False)[-1] == "site:hand"
    check_full_tree(mujoco.MjModel.from_xml_string(MIXED.replace('type="ball"', 'axis="0 0 1"')), rng)
    # the ball joint is outside these chains, but the full tree contains it
    with pytest.raises(UnsupportedJointError, match="'ball' of body 'ball_link' is a ball joint"):
        build_chain(m)
