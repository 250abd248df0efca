"""arm2 set-ups shared by the Fig. 2 scenarios."""
from __future__ import annotations

import numpy as np

from pneumatics.robot import load_robot
from pneumatics.sim import Simulation


def horizontal_elbow_sim(robot=None) -> Simulation:
    """arm2 (``robot``, default the nominal one) oriented so link 2 moves in the horizontal
    plane (paper 002 Fig. 2C): gravity along the elbow axis (world x at q1 = 0) and the
    shoulder braced by the model's ``brace_shoulder`` equality.  The shoulder's valves stay at null."""
    robot = robot or load_robot("arm2")
    sim = Simulation(robot)
    sim.model.opt.gravity[:] = (-9.81, 0.0, 0.0)
    sim.model.eq_active0[sim.model.equality("brace_shoulder").id] = 1  # survives reset()
    return sim


def deg(x):
    return np.degrees(x)
