"""What a viewer or logger reads of a robot that :func:`pneumatics.robot.load_robot` does not
build (the jet-pipe actuator, the hydraulic elbow): its MJCF model and the names that map a
recording's columns onto it.  ``workflow.rerun_log.RerunLogger`` takes either a
:class:`pneumatics.robot.Robot` or one of these.
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np


@dataclass
class RobotView:
    """A robot as a logger sees it: the model, its joints' qpos slots and its chambers."""

    name: str
    model: mujoco.MjModel
    joint_names: list
    """joints logged, in recording order (``q.<joint>`` columns)"""
    qpos_index: np.ndarray
    """each joint's address in ``data.qpos``"""
    actuator_names: list
    chamber_names: list
    """[(actuator, "a" | "b"), ...]"""
