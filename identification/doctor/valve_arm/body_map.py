"""Where on the robot the doctor's findings are: a body map.

A humanoid's owner reads "which of my 76 chambers, which of my 38 joints" faster from a picture
of the robot than from a table.  Every finding and every ``unexplained`` entry is put on the
joint it acts at (a chamber's or a cylinder's entry on the joint its actuator drives, through
the MuJoCo actuator's transmission); supply entries concern every chamber and are listed apart.

Two views of the same marks:

- :func:`body_map_png`: the kinematic tree at the model's reference pose (``qpos0``), bodies as
  dots joined to their parents, drawn on the two axes the robot spans most, the marked joints
  coloured (findings red, unexplained orange) and labelled;
- :func:`log_body_map`: the same marks in the doctor's Rerun recording, as points attached to
  the marked joints' bodies, so they move with the replayed robot.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from pneumatics.robot import actuator_moment_arms

FINDING_RGB = (0.85, 0.1, 0.1)
UNEXPLAINED_RGB = (0.95, 0.55, 0.0)


@dataclass
class Mark:
    """What the report says at one joint."""

    joint: str
    findings: list[str] = field(default_factory=list)
    """'<effect> (<chamber or cylinder>)' of each finding acting at this joint"""
    unexplained: list[str] = field(default_factory=list)
    """... of each unexplained entry"""

    @property
    def label(self) -> str:
        return "; ".join(self.findings + [f"unexplained {u}" for u in self.unexplained])

    @property
    def rgb(self) -> tuple:
        return FINDING_RGB if self.findings else UNEXPLAINED_RGB


def actuator_joints(robot) -> dict[str, str]:
    """actuator name -> the joint it drives: the one of its largest moment arm at the reference
    pose (pneumatics.robot.actuator_moment_arms: a rotary actuator's transmission is its joint;
    a linear cylinder's is a spatial tendon across one joint)."""
    return {name: max(arms, key=arms.get) for name, arms in actuator_moment_arms(robot).items() if arms}


def marks(robot, report: dict) -> tuple[dict[str, Mark], list[str]]:
    """The marks per joint name and the supply's entries (effect names) of ``report``."""
    by_actuator = actuator_joints(robot)
    out: dict[str, Mark] = {}
    supply: list[str] = []

    def place(where: dict) -> tuple[str | None, str]:
        if "joint" in where:
            return where["joint"], ""
        if "actuator" in where:
            detail = f"chamber {where['chamber']}" if "chamber" in where else "cylinder"
            return by_actuator.get(where["actuator"]), detail
        return None, ""

    for f in report.get("findings", []):
        joint, detail = place(f["where"])
        text = f"{f['effect']}" + (f" ({detail})" if detail else "")
        if joint is None:
            supply.append(f["effect"])
        else:
            out.setdefault(joint, Mark(joint)).findings.append(text)
    for u in report.get("unexplained", []):
        joint, detail = place(u["where"])
        if joint is None:
            supply.append("unexplained")
        else:
            out.setdefault(joint, Mark(joint)).unexplained.append(detail or "torque")
    return out, supply


def reference_pose(model: mujoco.MjModel) -> mujoco.MjData:
    """Forward kinematics at qpos0 (the pose the MJCF is written in)."""
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    return d


def drawing_axes(points: np.ndarray) -> tuple[int, int]:
    """The two world axes along which ``points`` (N, 3) spread most, in axis order (a front
    view of a standing humanoid: y and z; an arm reaching up in a plane: that plane)."""
    spread = np.ptp(points, axis=0)
    a, b = sorted(np.argsort(spread)[-2:])
    return int(a), int(b)


def geom_segments(model: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """(G, 2, 3) end points of the drawn geoms in world coordinates: a capsule's or a cylinder's
    axis, a box's longest axis, a point for the others (the links' shapes: on arm2 both hinges
    sit at the shoulder and only the geoms show the links)."""
    out = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == 0:  # the floor and the world's decorations
            continue
        c, rot, size = d.geom_xpos[g], d.geom_xmat[g].reshape(3, 3), model.geom_size[g]
        t = int(model.geom_type[g])
        if t in (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
            half = rot[:, 2] * size[1]
        elif t == int(mujoco.mjtGeom.mjGEOM_BOX):
            k = int(np.argmax(size))
            half = rot[:, k] * size[k]
        else:
            half = np.zeros(3)
        out.append([c - half, c + half])
    return np.array(out).reshape(-1, 2, 3)


def body_map_png(robot, report: dict, out: str | Path, name: str = "body_map.png") -> str:
    """Draw the kinematic tree with the report's marks into ``out/name``; returns ``name``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pneumatics.io import atomic_save

    m = robot.model
    d = reference_pose(m)
    joint_ids = [m.joint(j).id for j in robot.joint_names]
    anchors = np.array([d.xanchor[j] for j in joint_ids]) if joint_ids else np.zeros((0, 3))
    segs = geom_segments(m, d)
    ax0, ax1 = drawing_axes(np.vstack([d.xpos[1:], anchors, segs.reshape(-1, 3)]))
    axis_name = "xyz"
    found, supply = marks(robot, report)
    fig, ax = plt.subplots(figsize=(6, 7.5))
    for b in range(1, m.nbody):  # each body joined to its parent
        p = m.body_parentid[b]
        ax.plot([d.xpos[p, ax0], d.xpos[b, ax0]], [d.xpos[p, ax1], d.xpos[b, ax1]], color="0.6", lw=1.5, zorder=1)
    for a, b in segs:  # the links' shapes
        ax.plot([a[ax0], b[ax0]], [a[ax1], b[ax1]], color="0.75", lw=4, solid_capstyle="round", zorder=0)
    ax.scatter(d.xpos[1:, ax0], d.xpos[1:, ax1], s=8, color="0.45", zorder=2)
    ax.scatter(anchors[:, ax0], anchors[:, ax1], s=18, facecolor="white", edgecolor="0.3", zorder=3,
               label="joint")
    for n, (k, j) in enumerate((k, j) for k, j in enumerate(robot.joint_names) if j in found):
        mk = found[j]
        x, y = anchors[k, ax0], anchors[k, ax1]
        ax.scatter([x], [y], s=120, color=mk.rgb, edgecolor="black", zorder=4)
        # staggered: joints may share an anchor (arm2's two hinges sit at the shoulder)
        ax.annotate(f"{j}: {mk.label}", (x, y), xytext=(10, 8 - 14 * (n % 6)), textcoords="offset points", fontsize=7,
                    color=mk.rgb, zorder=5, bbox={"boxstyle": "round,pad=0.2", "fc": "white", "alpha": 0.8, "lw": 0})
    handles = [plt.Line2D([], [], marker="o", ls="", color=FINDING_RGB, label="finding"),
               plt.Line2D([], [], marker="o", ls="", color=UNEXPLAINED_RGB, label="unexplained")]
    ax.legend(handles=handles, fontsize=8, loc="lower right")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"world {axis_name[ax0]} [m]")
    ax.set_ylabel(f"world {axis_name[ax1]} [m]")
    title = f"{report.get('model', robot.name)}: where the findings act (reference pose)"
    if supply:
        title += f"\nsupply (every chamber): {', '.join(supply)}"
    if not found and not supply:
        title += "\nnothing marked: no finding, nothing unexplained"
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    atomic_save(Path(out) / name, lambda tmp: fig.savefig(tmp, dpi=100))
    plt.close(fig)
    return name


def log_body_map(logger, robot, report: dict) -> int:
    """Mark the report's joints in ``logger``'s Rerun recording (a
    workflow.rerun_log.RerunLogger): a point at each marked joint's anchor, attached to its
    body's entity so it follows the replayed robot, coloured and labelled as in the PNG.
    Returns the number of joints marked."""
    import rerun as rr

    from workflow.rerun_log.arrow import entity_part

    m = robot.model
    found, supply = marks(robot, report)
    logger.log_static()
    for j, mk in found.items():
        jid = m.joint(j).id
        body = int(m.jnt_bodyid[jid])
        path = f"{logger.body_paths[body]}/doctor_{entity_part(j)}"
        logger.recording.log(path, rr.Points3D([m.jnt_pos[jid]], colors=[mk.rgb], radii=[0.025],
                                               labels=[f"{j}: {mk.label}"]), static=True)
    if supply:
        logger.recording.log("world/doctor_supply", rr.TextDocument("supply (every chamber): " + ", ".join(supply)),
                             static=True)
    return len(found)
