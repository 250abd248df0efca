"""Valve-to-chamber tubes from a robot's geometry, as ``line_dynamics`` effects.

A tube of length L and bore D between an off-board valve and its chamber adds (Richer &
Hurmuzlu, *A high performance pneumatic force actuator system*, ASME J. Dyn. Sys. 122 (2000),
Part I, Sec. 3, the line model):

* a transport delay L / c of the flow from valve to chamber (c the speed of sound), and
* its volume pi D^2 / 4 L, which the chamber's air must fill too (added to the dead volume).

Both are what :class:`pneumatics.effects.effect_set.EffectSet.line_dynamics` simulates.  The
line model's attenuation of the mass flow by friction in the tube is not simulated, so a
predicted lag from these tubes is a lower bound on what real tubes of that size give.

The layout file (``models/<robot>/tubes.toml``, ``[tubes]``) states the assumptions: the
off-board run from the valve bank into the robot, the body where it enters, a routing factor
(tube / straight path) and the bore.  Inside the robot each tube follows the kinematic tree
from the entry body to the actuator's body (body origins at the ``home`` pose), then to the
cylinder's base pin (site ``<joint>_cyl_base``) where there is one; both chambers of an
actuator get the same length.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from ..errors import ConfigError

_FIELDS = {"offboard_length_m": (0.0, 50.0), "routing_factor": (1.0, 5.0),
           "inner_diameter_m": (1e-4, 0.05), "speed_of_sound_m_s": (100.0, 1000.0)}


@dataclass(frozen=True)
class TubeLayout:
    """Assumed tube routing (see the module docstring); SI units."""

    offboard_length_m: float
    entry_body: str
    routing_factor: float
    inner_diameter_m: float
    speed_of_sound_m_s: float


def load_tube_layout(path: str | Path) -> TubeLayout:
    """Read ``[tubes]`` of a layout file; a missing or out-of-range field names file and field."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise ConfigError(f"{path}: cannot read the tube layout: {e}") from None
    sec = doc.get("tubes")
    if not isinstance(sec, dict):
        raise ConfigError(f"{path}: expected a [tubes] section")
    values = {}
    for name, (lo, hi) in _FIELDS.items():
        v = sec.get(name)
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not lo <= v <= hi:
            raise ConfigError(f"{path}: [tubes] {name} must be a number in [{lo:g}, {hi:g}], got {v!r}")
        values[name] = float(v)
    if not isinstance(sec.get("entry_body"), str):
        raise ConfigError(f"{path}: [tubes] entry_body must be a body name (string)")
    return TubeLayout(entry_body=sec["entry_body"], **values)


def _chain(model, body: int) -> list[int]:
    """Body ids from ``body`` up to the world (inclusive)."""
    out = [body]
    while out[-1] != 0:
        out.append(int(model.body_parentid[out[-1]]))
    return out


def _tree_path_m(model, data, a: int, b: int) -> float:
    """Length [m] of the path between the origins of bodies a and b through their common ancestor."""
    ca, cb = _chain(model, a), _chain(model, b)
    common = next(x for x in ca if x in cb)
    length = 0.0
    for chain in (ca, cb):
        for child, parent in zip(chain, chain[1:]):
            if child == common:
                break
            length += float(np.linalg.norm(data.xpos[child] - data.xpos[parent]))
    return length


def _actuated_joint(model, act: int, name: str) -> int:
    """The joint an actuator drives: its joint transmission, else (site or tendon transmissions
    of cylinders with a varying moment arm) the joint of the same name (models name actuators
    after their joints)."""
    if int(model.actuator_trntype[act]) == int(mujoco.mjtTrn.mjTRN_JOINT):
        return int(model.actuator_trnid[act, 0])
    jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    if jid < 0:
        raise ConfigError(f"tube layout: actuator {name!r} has no joint transmission and no joint of its name")
    return jid


def tube_lengths(robot, layout: TubeLayout) -> dict[str, float]:
    """actuator -> tube length [m] at the robot's ``home`` pose (its qpos0 if it has none)."""
    m = robot.model
    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    try:
        entry = m.body(layout.entry_body).id
    except KeyError:
        raise ConfigError(f"tube layout: entry_body {layout.entry_body!r} is not a body of {robot.name}") from None
    out = {}
    for name, act in zip(robot.actuator_names, robot.actuator_ids):
        joint = _actuated_joint(m, int(act), name)
        body, end = int(m.jnt_bodyid[joint]), None
        site = f"{m.joint(joint).name}_cyl_base"
        if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, site) >= 0:
            sid = m.site(site).id
            body, end = int(m.site_bodyid[sid]), d.site_xpos[sid]
        inside = _tree_path_m(m, d, entry, body)
        if end is not None:
            inside += float(np.linalg.norm(end - d.xpos[body]))
        out[name] = layout.offboard_length_m + layout.routing_factor * inside
    return out


def tube_line_dynamics(robot, layout: TubeLayout) -> dict[str, dict]:
    """``EffectSet.line_dynamics`` for every chamber: {"<actuator>.<a|b>": {"delay_s", "volume_m3"}}."""
    bore = math.pi * layout.inner_diameter_m ** 2 / 4.0
    out = {}
    for act, length in tube_lengths(robot, layout).items():
        for ch in ("a", "b"):
            out[f"{act}.{ch}"] = {"delay_s": length / layout.speed_of_sound_m_s, "volume_m3": bore * length}
    return out
