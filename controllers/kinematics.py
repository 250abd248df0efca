"""Batched forward kinematics and Jacobians of our MJCF models, with pytorch-kinematics.

pytorch-kinematics (``pk``) computes the world pose of every frame of a kinematic tree and the
geometric Jacobian of a serial chain for a whole batch of joint configurations at once, in
torch (differentiable, CPU or GPU).  This module builds the ``pk.Chain`` from a compiled
``mujoco.MjModel`` and wraps the common case -- one arm, from the world to a hand body or
site -- in :class:`ArmKinematics`.

Why not ``pk.build_chain_from_mjcf``
------------------------------------
pk 0.10.0's MJCF loader (``pytorch_kinematics/mjcf.py``) has four problems for us:

1. **It fails with MuJoCo >= 3.12** (``KeyError: np.int32(3)``).  Its joint-type table
   ``JOINT_TYPE_MAP`` is keyed by ``mujoco.mjtJoint`` enum members and looked up with
   ``joint.type[0]``, a ``numpy.int32``.  The hashes agree, but the dict compares the stored
   key to the looked-up one, and the pybind11 enum's ``__eq__`` answers ``False`` for a
   ``numpy.int32`` (``mjJNT_HINGE == np.int32(3)`` is ``False`` while
   ``np.int32(3) == mjJNT_HINGE`` is ``True``).  Re-keying the table by ``int`` fixes this.
2. **A joint ``pos`` is composed the URDF way**: it builds ``body_offset @ T(jnt_pos) @ R(q)``
   and hangs the children on that frame, while MuJoCo rotates the body *about* the anchor,
   ``body_offset @ T(jnt_pos) @ R(q) @ T(-jnt_pos)``.  The result is silently wrong whenever
   ``jnt_pos != 0`` (even at q = 0 every descendant is shifted by ``jnt_pos``).
3. **It loses float64 precision**: every ``Transform3d`` and joint axis is created in float32,
   so even after ``chain.to(dtype=torch.float64)`` positions are off by ~1e-8 m (measured
   2.5e-8 m on a two-link test model), far above the 1e-9 m we check against MuJoCo.
4. It compiles the MJCF with ``MjModel.from_xml_string(text)``, so ``<include>`` files and
   mesh/texture paths relative to the model file cannot be found; and frames of sites are named
   like bodies, so a site and a body that share a name (legal in MuJoCo) collide.

Patching ``JOINT_TYPE_MAP`` at import time would only fix (1).  We therefore build the chain
ourselves from ``mujoco.MjModel`` (the body tree ``body_parentid``, ``body_pos``/``body_quat``,
``jnt_type``/``jnt_axis``/``jnt_range``, ``site_pos``/``site_quat``), in the chain's dtype from
the start (float64 by default), using pk only for its ``Frame``/``Link``/``Joint``/``Chain``/
``SerialChain`` classes and batched FK/Jacobian kernels.  MuJoCo does the parsing (includes,
defaults, ``euler``/``axisangle``/``fromto`` orientations, ``<frame>``, angle units), so
whatever MuJoCo compiles, we read.  Nothing in site-packages is modified or monkey-patched.

Model conventions handled:

* hinge -> pk ``revolute``, slide -> pk ``prismatic`` (axes as compiled, i.e. normalized, in
  the body frame); ``ball``/``free`` joints raise :class:`UnsupportedJointError` if they lie in
  the requested chain.
* a body with several joints becomes a row of frames, one joint each (MuJoCo composes the
  joints of a body in order about the body origin); the last one carries the body's name and
  the earlier ones are named ``"<body>:<joint>"``.
* any joint in the chain with a nonzero ``jnt_pos`` raises :class:`JointOffsetError`
  (our models put every joint at its body origin; see problem 2).
* the root frame is the world body, so all poses and Jacobians are in world coordinates, as
  MuJoCo's ``xpos``/``site_xpos`` and ``mj_jac*``.  A fixed base is a fixed frame.
* frames are named after bodies; sites after sites, or ``"site:<name>"`` if a body has the
  same name.  Unnamed bodies/joints/sites are called ``body<id>``/``joint<id>``/``site<id>``.
* geoms (pk "visuals") are not copied: they play no part in kinematics.

Joint order: the chain's joint order is pk's depth-first order, which along a serial chain is
root to tip -- the same as MuJoCo's dof order.  :class:`ArmKinematics` gives the MuJoCo
``qpos``/``dof`` index of each chain joint so MuJoCo vectors can be sliced into chain order.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Union

import mujoco
import numpy as np
import pytorch_kinematics as pk
import torch
from pytorch_kinematics import frame as pk_frame
from pytorch_kinematics import transforms as pk_tf

import models
from pneumatics.errors import ConfigError, UnknownNameError

__all__ = [
    "ArmKinematics",
    "JointOffsetError",
    "UnsupportedJointError",
    "build_chain",
    "load_model",
]

ModelSource = Union[str, os.PathLike, mujoco.MjModel]

# MuJoCo joint type -> pk joint type, keyed by int (see problem 1 in the module docstring).
_PK_JOINT_TYPE = {
    int(mujoco.mjtJoint.mjJNT_HINGE): "revolute",
    int(mujoco.mjtJoint.mjJNT_SLIDE): "prismatic",
}
_JNT_POS_TOL = 1e-12  # [m] a joint anchor farther than this from its body origin is an error


class JointOffsetError(ConfigError):
    """A joint in the chain has a nonzero ``pos`` (anchor not at its body's origin)."""


class UnsupportedJointError(ConfigError):
    """A ``ball`` or ``free`` joint lies in the requested chain."""


# ----------------------------------------------------------------------------- model loading

def load_model(src: ModelSource) -> mujoco.MjModel:
    """Compile a MuJoCo model.

    Args:
      src: a ``mujoco.MjModel`` (returned as is); an MJCF text (starts with ``<``); a path to an
        MJCF file; or the name of a model under ``models/`` (``models.mjcf_path(name)``).

    Returns:
      the compiled ``mujoco.MjModel``.
    """
    if isinstance(src, mujoco.MjModel):
        return src
    if isinstance(src, os.PathLike):
        return mujoco.MjModel.from_xml_path(os.fspath(src))
    if not isinstance(src, str):
        raise TypeError(f"expected an MjModel, MJCF text, path or model name, got {type(src).__name__}")
    if src.lstrip().startswith("<"):
        return mujoco.MjModel.from_xml_string(src)
    if src.lower().endswith((".xml", ".mjcf")) or os.sep in src or Path(src).is_file():
        return mujoco.MjModel.from_xml_path(src)
    return mujoco.MjModel.from_xml_path(str(models.mjcf_path(src)))


def _name(m: mujoco.MjModel, obj: mujoco.mjtObj, i: int, prefix: str) -> str:
    return mujoco.mj_id2name(m, obj, i) or f"{prefix}{i}"


def _resolve_end(m: mujoco.MjModel, end_link: str) -> tuple[int, int | None]:
    """``end_link`` -> (body id, site id or None).  Plain names: body first, then site;
    ``"body:NAME"`` / ``"site:NAME"`` force the kind."""
    kind, _, bare = end_link.partition(":") if end_link.startswith(("body:", "site:")) else ("", "", end_link)
    if kind in ("", "body"):
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, bare)
        if b >= 0:
            return b, None
    if kind in ("", "site"):
        s = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, bare)
        if s >= 0:
            return int(m.site_bodyid[s]), s
    valid = [_name(m, mujoco.mjtObj.mjOBJ_BODY, i, "body") for i in range(m.nbody)]
    valid += [_name(m, mujoco.mjtObj.mjOBJ_SITE, i, "site") for i in range(m.nsite)]
    raise UnknownNameError("body or site", end_link, valid)


# ----------------------------------------------------------------------------- chain building

def _pose_matrix(pos: np.ndarray, quat: np.ndarray) -> np.ndarray:
    """(3,) position and (4,) wxyz quaternion -> (4, 4) homogeneous transform, float64."""
    T = np.eye(4)
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat, dtype=np.float64))
    T[:3, :3] = R.reshape(3, 3)
    T[:3, 3] = pos
    return T


def _transform(T: np.ndarray, dtype, device) -> pk_tf.Transform3d:
    return pk_tf.Transform3d(matrix=torch.tensor(T, dtype=dtype, device=device))


def _check_joint(m: mujoco.MjModel, j: int, body_name: str) -> None:
    jname = _name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")
    jtype = int(m.jnt_type[j])
    if jtype not in _PK_JOINT_TYPE:
        kind = mujoco.mjtJoint(jtype).name.removeprefix("mjJNT_").lower()
        raise UnsupportedJointError(
            f"joint {jname!r} of body {body_name!r} is a {kind} joint; the kinematic chain "
            "supports only hinge and slide joints (pick an end link whose chain avoids it)")
    pos = m.jnt_pos[j]
    if np.max(np.abs(pos)) > _JNT_POS_TOL:
        raise JointOffsetError(
            f"joint {jname!r} of body {body_name!r} has pos={pos.tolist()} (nonzero joint offset); "
            "pytorch-kinematics would rotate the body about the wrong point. Move the joint to "
            "the body origin (put the offset in the body's pos instead) and set its pos to 0.")


def _body_frames(m: mujoco.MjModel, b: int, names: dict, dtype, device
                 ) -> tuple[pk_frame.Frame, pk_frame.Frame]:
    """Frames of body ``b``: (first, last).  ``first`` carries the body offset from its parent
    and the first joint; children of the body hang on ``last`` (== first if <= 1 joint)."""
    bname = names["body"][b]
    offset = _transform(_pose_matrix(m.body_pos[b], m.body_quat[b]), dtype, device)
    jnts = list(range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]))
    if not jnts:
        f = pk_frame.Frame(bname, link=pk_frame.Link(bname, offset=offset),
                           joint=pk_frame.Joint(bname + "_fixed_joint", dtype=dtype, device=device))
        return f, f
    frames = []
    for k, j in enumerate(jnts):
        _check_joint(m, j, bname)
        jname = names["joint"][j]
        fname = bname if k == len(jnts) - 1 else f"{bname}:{jname}"
        limits = (float(m.jnt_range[j, 0]), float(m.jnt_range[j, 1])) if m.jnt_limited[j] else None
        joint = pk_frame.Joint(jname, joint_type=_PK_JOINT_TYPE[int(m.jnt_type[j])],
                               axis=torch.tensor(m.jnt_axis[j], dtype=dtype, device=device),
                               dtype=dtype, device=device, limits=limits)
        link = pk_frame.Link(fname, offset=offset if k == 0 else None)
        frames.append(pk_frame.Frame(fname, link=link, joint=joint))
    for parent, child in zip(frames, frames[1:]):
        parent.children = [child]
    return frames[0], frames[-1]


def _site_frame(m: mujoco.MjModel, s: int, names: dict, dtype, device) -> pk_frame.Frame:
    sname = names["site_frame"][s]
    offset = _transform(_pose_matrix(m.site_pos[s], m.site_quat[s]), dtype, device)
    return pk_frame.Frame(sname, link=pk_frame.Link(sname, offset=offset),
                          joint=pk_frame.Joint(sname + "_fixed_joint", dtype=dtype, device=device))


def _frame_names(m: mujoco.MjModel) -> dict:
    body = [_name(m, mujoco.mjtObj.mjOBJ_BODY, i, "body") for i in range(m.nbody)]
    joint = [_name(m, mujoco.mjtObj.mjOBJ_JOINT, i, "joint") for i in range(m.njnt)]
    taken = set(body)
    site = [_name(m, mujoco.mjtObj.mjOBJ_SITE, i, "site") for i in range(m.nsite)]
    site_frame = [f"site:{n}" if n in taken else n for n in site]
    return {"body": body, "joint": joint, "site_frame": site_frame}


def _build(m: mujoco.MjModel, bodies: list[int], sites: list[int], dtype, device) -> pk.Chain:
    """A pk.Chain rooted at the world body over ``bodies`` (ids, parents before children,
    body 0 first) and ``sites``."""
    names = _frame_names(m)
    attach = {}  # body id -> frame its children hang on
    root = pk_frame.Frame(names["body"][0], link=pk_frame.Link(names["body"][0]),
                          joint=pk_frame.Joint(dtype=dtype, device=device))
    attach[0] = root
    for b in bodies[1:]:
        first, last = _body_frames(m, b, names, dtype, device)
        parent = attach[int(m.body_parentid[b])]
        parent.children = parent.children + [first]
        attach[b] = last
    for s in sites:
        parent = attach[int(m.site_bodyid[s])]
        parent.children = parent.children + [_site_frame(m, s, names, dtype, device)]
    return pk.Chain(root, dtype=dtype, device=device)


def _ancestors(m: mujoco.MjModel, b: int) -> list[int]:
    path = [b]
    while path[-1] != 0:
        path.append(int(m.body_parentid[path[-1]]))
    return path[::-1]


def _end_frame_name(m: mujoco.MjModel, body: int, site: int | None) -> str:
    names = _frame_names(m)
    return names["body"][body] if site is None else names["site_frame"][site]


def build_chain(mjcf_path_or_model_name: ModelSource, end_link: str | None = None,
                dtype: torch.dtype = torch.float64, device: str | torch.device = "cpu") -> pk.Chain:
    """Build a pytorch-kinematics chain from an MJCF model.

    Args:
      mjcf_path_or_model_name: model name under ``models/``, MJCF path, MJCF text or
        ``mujoco.MjModel`` (see :func:`load_model`).
      end_link: a body or site name.  If given, returns the ``pk.SerialChain`` from the world
        body to it (only that path is built, so ball/free joints elsewhere do not matter).
        Plain names resolve to a body first, then a site; ``"site:NAME"``/``"body:NAME"``
        force the kind.  If None, returns the full tree (every body and site) as ``pk.Chain``.
      dtype: chain dtype; float64 by default (FK matches MuJoCo to ~1e-15).
      device: torch device of the chain.

    Returns:
      ``pk.SerialChain`` (end_link given) or ``pk.Chain`` rooted at the world body, whose joint
      parameters (``chain.get_joint_parameter_names()``) are MuJoCo's hinge/slide joint names.
      ``chain.forward_kinematics(th)`` takes ``th`` (B, n_joints) and returns world transforms.

    Raises:
      JointOffsetError: a joint in the chain has a nonzero ``pos``.
      UnsupportedJointError: a ball/free joint in the chain.
      UnknownNameError: ``end_link`` names no body or site.
    """
    m = load_model(mjcf_path_or_model_name)
    if end_link is None:
        return _build(m, list(range(m.nbody)), list(range(m.nsite)), dtype, device)
    body, site = _resolve_end(m, end_link)
    tree = _build(m, _ancestors(m, body), [] if site is None else [site], dtype, device)
    return pk.SerialChain(tree, _end_frame_name(m, body, site), dtype=dtype, device=device)


# ----------------------------------------------------------------------------- arm wrapper

class ArmKinematics:
    """Forward kinematics and Jacobian of one serial chain, world -> end body or site.

    Batched over joint configurations; numpy in -> numpy out, torch in -> torch out (keeps the
    autograd graph).  A 1-D ``q`` of shape (n,) gives unbatched results ((3,), (6, n), ...).

    Args:
      model_name: model name under ``models/``, MJCF path, MJCF text or ``mujoco.MjModel``.
      end_body: a body or site name (plain names: body first, then site; ``"site:NAME"`` forces
        a site).  The end point is that frame's origin, i.e. MuJoCo's ``xpos``/``site_xpos``.
      site_offset: optional (3,) point in the end frame's coordinates, added to the end point
        (like a site at ``pos=site_offset`` on the end body).
      dtype, device: of the underlying ``pk.SerialChain``.

    Attributes:
      model: the compiled ``mujoco.MjModel``.
      chain: the ``pk.SerialChain``.
      joint_names: (n,) MuJoCo names of the chain's joints, root to tip.
      joint_ids: (n,) MuJoCo joint ids.
      qpos_indices: (n,) index of each joint in MuJoCo's ``qpos``; ``q = qpos[..., qpos_indices]``.
      dof_indices: (n,) index of each joint in MuJoCo's ``qvel``/Jacobian columns.
      lower, upper: (n,) joint range; -inf/inf where the joint is not limited.
    """

    def __init__(self, model_name: ModelSource, end_body: str, site_offset=None, *,
                 dtype: torch.dtype = torch.float64, device: str | torch.device = "cpu"):
        self.model = load_model(model_name)
        self.end_name = end_body
        self.chain: pk.SerialChain = build_chain(self.model, end_body, dtype=dtype, device=device)
        self.dtype, self.device = dtype, torch.device(device)
        self.joint_names: list[str] = list(self.chain.get_joint_parameter_names())
        names = _frame_names(self.model)["joint"]
        self.joint_ids = np.array([names.index(n) for n in self.joint_names], dtype=int)
        self.qpos_indices = self.model.jnt_qposadr[self.joint_ids].copy()
        self.dof_indices = self.model.jnt_dofadr[self.joint_ids].copy()
        limited = self.model.jnt_limited[self.joint_ids].astype(bool)
        rng = self.model.jnt_range[self.joint_ids]
        self.lower = np.where(limited, rng[:, 0], -np.inf)
        self.upper = np.where(limited, rng[:, 1], np.inf)
        self.site_offset = (None if site_offset is None else
                            torch.as_tensor(np.asarray(site_offset, dtype=np.float64), dtype=dtype,
                                            device=self.device).reshape(3))
        self._end_idx = self.chain._serial_eef_frame_idx

    @property
    def n(self) -> int:
        """Number of joints in the chain."""
        return len(self.joint_names)

    def __repr__(self) -> str:
        return f"ArmKinematics(end={self.end_name!r}, joints={self.joint_names})"

    # -- input/output conversion
    def _prep(self, q) -> tuple[torch.Tensor, bool, bool]:
        is_torch = torch.is_tensor(q)
        th = q if is_torch else torch.as_tensor(np.asarray(q, dtype=np.float64))
        th = th.to(dtype=self.dtype, device=self.device)
        unbatched = th.ndim == 1
        if unbatched:
            th = th.unsqueeze(0)
        if th.ndim != 2 or th.shape[1] != self.n:
            raise ValueError(f"q must have shape (B, {self.n}) or ({self.n},) for joints "
                             f"{self.joint_names}; got {tuple(th.shape)}")
        return th, is_torch, unbatched

    @staticmethod
    def _out(x: torch.Tensor, is_torch: bool, unbatched: bool):
        if unbatched:
            x = x[0]
        return x if is_torch else x.detach().cpu().numpy()

    def _end_pose(self, T: torch.Tensor) -> torch.Tensor:
        """(B, 4, 4) end-frame pose -> same with the site offset applied to the translation."""
        if self.site_offset is None:
            return T
        T = T.clone()
        T[:, :3, 3] = T[:, :3, 3] + T[:, :3, :3] @ self.site_offset
        return T

    # -- API
    def pose(self, q):
        """World pose of the end frame (translated by ``site_offset``).

        Args:
          q: (B, n) or (n,) joint positions, in ``joint_names`` order.
        Returns:
          (B, 4, 4) or (4, 4) homogeneous transforms (rotation = MuJoCo's ``xmat``/``site_xmat``).
        """
        th, is_torch, unbatched = self._prep(q)
        T = self.chain.forward_kinematics_tensor(th)[self._end_idx]
        return self._out(self._end_pose(T), is_torch, unbatched)

    def fk(self, q):
        """World position of the end point.

        Args:
          q: (B, n) or (n,) joint positions, in ``joint_names`` order.
        Returns:
          (B, 3) or (3,) positions (MuJoCo's ``xpos``/``site_xpos`` of the end frame, plus
          ``site_offset`` rotated into the world).
        """
        th, is_torch, unbatched = self._prep(q)
        T = self.chain.forward_kinematics_tensor(th)[self._end_idx]
        return self._out(self._end_pose(T)[:, :3, 3], is_torch, unbatched)

    def jacobian(self, q, position_only: bool = False):
        """Geometric Jacobian of the end point in world coordinates.

        Args:
          q: (B, n) or (n,) joint positions, in ``joint_names`` order.
          position_only: return only the translational rows.
        Returns:
          (B, 6, n) -- rows 0:3 translational (d end point / dq, MuJoCo's ``jacp``), rows 3:6
          rotational (world angular velocity / dq, MuJoCo's ``jacr``) -- or (B, 3, n) if
          ``position_only``; without the batch dimension for a 1-D ``q``.  Columns follow
          ``joint_names``, i.e. MuJoCo's columns ``dof_indices``.
        """
        th, is_torch, unbatched = self._prep(q)
        J, T = self.chain.jacobian_tensor(th, ret_eef_pose=True)  # about the end-frame origin
        if self.site_offset is not None:
            r = T[:, :3, :3] @ self.site_offset  # (B, 3) world vector origin -> end point
            J = torch.cat([J[:, :3] + torch.cross(J[:, 3:], r.unsqueeze(-1).expand_as(J[:, 3:]), dim=1),
                           J[:, 3:]], dim=1)
        if position_only:
            J = J[:, :3]
        return self._out(J, is_torch, unbatched)

    def q_from_qpos(self, qpos):
        """Chain joint positions from MuJoCo's ``qpos``: (..., nq) -> (..., n)."""
        return qpos[..., self.qpos_indices]

    def sample(self, n_samples: int, rng: np.random.Generator | None = None) -> np.ndarray:
        """(n_samples, n) configurations uniform in the joint ranges (unlimited: [-pi, pi])."""
        rng = np.random.default_rng() if rng is None else rng
        lo = np.where(np.isfinite(self.lower), self.lower, -np.pi)
        hi = np.where(np.isfinite(self.upper), self.upper, np.pi)
        return rng.uniform(lo, hi, size=(n_samples, self.n))
