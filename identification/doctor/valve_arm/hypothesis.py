"""A hypothesis of the doctor: one effect family in one form at one place, with its parameters'
start, bounds and probe, and how it changes the chamber model (``apply``) or the rigid body's
equation error (``regressor``).  :func:`torque_regressor` builds a mechanical one's regressor
from the family's own law (Family.torque_balance_term)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from pneumatics.effects.registry import get_family

from .calibrate import SCALE_BOUND

__all__ = ["Hypothesis", "place_of", "torque_regressor"]


@dataclass
class Hypothesis:
    family: str
    where: dict
    kind: str                     # "pneumatic" | "mechanical"
    params: list                  # [(name_unit, start, lower, upper, probe step)]
    chambers: list = field(default_factory=list)   # chambers whose replay it changes
    joint: int | None = None
    apply: Callable | None = None           # (mods, x) -> mods
    regressor: Callable | None = None       # (exp, td) -> (N, J, E)
    fixed: dict = field(default_factory=dict)  # parameters chosen before the linear fit: name -> {value, stderr}
    null_value: float = 0.0       # the parameter value that switches the effect off (apply(mods, [null]))
    adds_volume: float = 0.0      # a tube's volume adds to this nominal dead volume [m^3]: it may grow past the calibration bound
    tested: tuple | None = None   # indices of the parameters the keep rule tests (None: all)
    any_tested: bool = False      # the keep rule asks one of them, not each (rules.keeps)
    screened: bool = True         # scored and fitted by the greedy search (False: by its own check, supply_receiver)
    form: str = ""                # the family's form when not its first (tells two forms at one place apart)
    state_torque: Callable | None = None    # (values (k,), q (W,), qd (W,)) -> torque applied at its joint (W,) [N m]:
                                            # the yardsticks' fitted torque, for the angle replay (angle_replay)
    local: bool = False           # acts in a regime of its joint's angle alone (an end stop in contact)

    def keep_mask(self) -> np.ndarray:
        """(k,) bool: the parameters that must each be MIN_T standard errors from 0 (a sensor's
        warm-up drift must be; the offset it starts from may be 0)."""
        k = len(self.params)
        return np.ones(k, bool) if self.tested is None else np.isin(np.arange(k), self.tested)

    def __post_init__(self):
        if self.regressor is not None:  # the equations the torque data leave out, left out here too
            reg = self.regressor
            self.regressor = lambda exp, td: td.mask(reg(exp, td))

    def null_vector(self) -> np.ndarray:
        """Every parameter at the value that switches the effect off."""
        return np.full(len(self.params), self.null_value)

    def switched_off(self, mods):
        """``mods`` without this effect: its parameters at their null values, and a tube's
        volume (``adds_volume``) taken back to what a calibration may hold (SCALE_BOUND)."""
        out = self.apply(mods, self.null_vector())
        if self.adds_volume:
            scale = out.dead_volume_scale.copy()
            scale[self.chambers] = np.minimum(scale[self.chambers], SCALE_BOUND)
            out = out.copy(dead_volume_scale=scale)
        return out

    @property
    def label(self) -> str:
        return f"{self.family}@{place_of(self.where)}" + (f" ({self.form})" if self.form else "")


def place_of(where: dict) -> str:
    """A place as the doctor names it in labels and per-place tables: the joint, the actuator's
    chamber ("left_elbow.a"), the actuator, or "all" (the supply)."""
    return where.get("joint") or (f"{where['actuator']}.{where['chamber']}" if "chamber" in where
                                  else where.get("actuator", "all"))


def torque_regressor(family: str, joint: int, units: list[dict], form: str | None = None):
    """(exp, td) -> (N, J, E): the torque the family adds to the equation error per unit of each
    parameter (linear in them), from its own law (Family.torque_balance_term)."""
    fam = get_family(family)
    cls = fam.form_class(form)

    def reg(exp, td):
        return np.stack([fam.torque_balance_term(exp, td, joint, cls(**u)) for u in units], axis=2)
    return reg
