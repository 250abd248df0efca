"""Hydraulic joints (paper 001, the SARCOS elbow): oil circuit, servovalve, vane actuator.

Reuses the fluid layer's ideas with an oil medium (:mod:`pneumatics.oil`) instead of a gas:

* :mod:`.hysteresis`  Jiles-Atherton valve hysteresis with closing minor loops (eqs. 2-3)
* :mod:`.servovalve`  valve tip dynamics (eq. 4), metering areas, two-stage clearance leakage
* :mod:`.lines`       supply/return lines: resistance, inertance, capacitance (eqs. 6-7, 10)
* :mod:`.vane`        rotary vane actuator: volumes, torque, cross-chamber leakage
* :mod:`.circuit`     the six-state circuit ODE and its L-stable step (eqs. 5-10)
* :mod:`.kernel`      the same step compiled with numba
* :mod:`.config`      ``fluid.toml`` loader (``kind = "hydraulic"``)
* :mod:`.sim`         MuJoCo and hydraulics stepped together; :func:`load_hydraulic`
* :mod:`.runner`      current runs -> Recording (``run_measured``: the sensor columns the doctor reads)
* :mod:`.effects`     physics the nominal model may leave out (the hydraulic doctor's families)
"""
from .circuit import BLOCKED, VALVE, HydraulicCircuit, Port
from .config import HydraulicCfg, load_hydraulic_cfg
from .hysteresis import Hysteresis, HysteresisCfg
from .runner import run_current
from .sim import HydraulicJointSim, load_hydraulic

__all__ = [
           "BLOCKED",
           "VALVE",
           "HydraulicCfg",
           "HydraulicCircuit",
           "HydraulicJointSim",
           "Hysteresis",
           "HysteresisCfg",
           "Port",
           "load_hydraulic",
           "load_hydraulic_cfg",
           "run_current",
]
