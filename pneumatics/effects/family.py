"""The definition of one effect family, read by the simulator, the doctor and the case makers.

A family (DESIGN.md's effect vocabulary: ``valve_lag``, ``external_leak``, ...) is one piece
of physics a nominal model may leave out.  Its module holds, in one place:

* its **forms**: the physical laws it may take (an orifice or a laminar leak), each with a
  parameter dataclass whose fields (:func:`param`) carry unit, plausible range, meaning and
  whether they are a magnitude, named as the doctor reports them (DESIGN.md report.json);
* its **law**: the numpy function of the force, torque, flow or signal it changes;
* the **simulator hook** :meth:`Family.effect_set_entry`: what goes into an
  :class:`~pneumatics.effects.effect_set.EffectSet` at one place (:meth:`Family.add_to`);
* the **doctor hooks**: :meth:`Family.mods_entry` (the fields of the doctor's chamber model,
  ``identification.doctor.valve_arm.pneumatic_mods.PneumaticMods``, for families the pressure replays test) or
  :meth:`Family.torque_balance_term` (the torque a joint family adds to the rigid body's
  equation error, for families the torque balance tests);
* the **parameter ranges** the benchmarks' case makers draw from (:meth:`Family.draw`, magnitudes
  a real robot shows).

Compiled loops (pneumatics.kernel, identification.doctor.valve_arm.chamber_kernel) keep their own arithmetic but
read the arrays these hooks fill.  ``tests/effects/test_roundtrip.py`` checks, per family, that
a simulation with the effect and the doctor's replay of it with the same parameters agree.

The pattern follows mink's tasks (one small class per file on a small abstract base) and
mjlab's ``*Cfg`` dataclasses (every field documented, with its unit).
"""
from __future__ import annotations

import dataclasses
from abc import ABC
from typing import Any, ClassVar

import numpy as np

from ..config import from_table
from ..errors import PneumasimError, UnknownNameError

#: where a family acts: a joint ("elbow"), a chamber ("elbow.a"), an actuator ("elbow"), the supply
PLACE_KINDS = ("joint", "chamber", "actuator", "supply")
#: how the doctor tests a family on a valve-driven arm: its pressure replays, its torque balance,
#: or neither (a family of another plant: the bench doctors and the jet-pipe doctor keep their own)
DOCTOR_SIDES = ("pressure_replay", "torque_balance", "")


class NotOnThisSide(PneumasimError):
    """A hook asked of a family that the simulator or the doctor does not model that way."""


class Family(ABC):
    """One effect family.  Subclasses set the class attributes and override the hooks they have."""

    name: ClassVar[str]
    place_kind: ClassVar[str]
    forms: ClassVar[dict[str, type]]
    """form name -> parameter dataclass; the first is the default form"""
    physics: ClassVar[str]
    """one line: the law, for the docs table"""
    sources: ClassVar[str]
    """papers or textbooks the law comes from"""
    simulator: ClassVar[str] = ""
    """how the arm simulator applies it ("" = not on valve-driven arms)"""
    doctor: ClassVar[str] = ""
    """one of DOCTOR_SIDES: how the arm doctor tests it"""
    plants: ClassVar[tuple[str, ...]] = ("valve_arm",)
    """model kinds that simulate it (valve_arm, bench_chamber, bench_cylinder, jetpipe)"""
    roundtrip_gap: ClassVar[str] = ""
    """why there is no arm2 round trip simulator -> doctor for this family ("" = there is one)"""
    benchmark_ok: ClassVar[bool] = True
    """drawn by the blind benchmark (False: it cannot be concealed)"""

    # -- parameters --------------------------------------------------------------------------
    @property
    def default_form(self) -> str:
        return next(iter(self.forms))

    def form_class(self, form: str | None = None) -> type:
        form = self.default_form if form is None else form
        if form not in self.forms:
            raise UnknownNameError(f"form of {self.name}", form, self.forms)
        return self.forms[form]

    def params(self, values: dict, form: str | None = None):
        """The parameter dataclass of ``form`` from a {field: value} dict, fields checked
        against their units and plausible ranges (ConfigError naming the field)."""
        return from_table(self.form_class(form), dict(values), f"effect {self.name} ({form or self.default_form})")

    def form_of(self, params) -> str:
        for form, cls in self.forms.items():
            if isinstance(params, cls):
                return form
        raise PneumasimError(f"{self.name}: {type(params).__name__} is none of its forms "
                             f"({', '.join(c.__name__ for c in self.forms.values())})")

    def scaled(self, params, k: float):
        """Parameters with the effect's magnitude times k (what the case makers' concealment halves)."""
        return dataclasses.replace(params, **{f.name: getattr(params, f.name) * k for f in dataclasses.fields(params)
                                              if f.metadata.get("magnitude", True)})

    # -- simulator ---------------------------------------------------------------------------
    def effect_set_entry(self, params) -> dict[str, Any]:
        """{EffectSet field: value at one place} of these parameters (the supply's: the value)."""
        raise NotOnThisSide(f"{self.name}: the arm simulator does not model it ({self.roundtrip_gap})")

    def add_to(self, effects, place: str, params) -> None:
        """Switch the effect on in ``effects`` (an EffectSet) at ``place``.  Dict-valued entries
        at one place merge; a family whose terms add up at one place (friction) overrides this."""
        for attr, value in self.effect_set_entry(params).items():
            if self.place_kind == "supply":
                setattr(effects, attr, value)
            elif isinstance(value, dict):
                getattr(effects, attr).setdefault(place, {}).update(value)
            else:
                getattr(effects, attr)[place] = value

    # -- doctor --------------------------------------------------------------------------------
    def mods_entry(self, params) -> dict[str, float]:
        """{PneumaticMods field: value at one place} for the doctor's pressure replays."""
        raise NotOnThisSide(f"{self.name}: the doctor's pressure replays do not model it")

    def apply_to_mods(self, mods, robot, place: str, params):
        """A copy of the doctor's chamber model ``mods`` with the effect at ``place``: arrays per
        chamber, per actuator, or a scalar for the supply; other places keep their values."""
        changes = {}
        for attr, value in self.mods_entry(params).items():
            if self.place_kind == "supply":
                changes[attr] = float(value)
                continue
            names = place_names(robot, self.place_kind)
            if place not in names:
                raise UnknownNameError(self.place_kind, place, names)
            arr = getattr(mods, attr)
            arr = np.full(len(names), self.mods_off_value) if arr is None else np.array(arr, float)
            arr[names.index(place)] = value
            changes[attr] = arr
        return mods.copy(**changes)

    mods_off_value: ClassVar[float] = 0.0
    """the PneumaticMods array value that leaves a place without the effect"""

    def torque_balance_term(self, exp, td, joint: int, params) -> np.ndarray:
        """(N, J) torque [N m] the effect adds to the equation error tau_act - tau_inv of the
        doctor's torque balance (``identification.doctor.valve_arm.mechanics``) at joint index ``joint``."""
        raise NotOnThisSide(f"{self.name}: the doctor's torque balance does not model it")

    # -- benchmarks ----------------------------------------------------------------------------
    def places(self, robot) -> list[str]:
        """The places of ``robot`` the simulator can put this family at (every place of its
        kind unless the family needs more of it)."""
        return place_names(robot, self.place_kind)

    def draw(self, rng: np.random.Generator):
        """Parameters of a hidden effect, drawn from magnitudes a real robot shows."""
        raise NotOnThisSide(f"{self.name}: the arm case makers do not draw it")

    def describe(self) -> str:
        """Forms and their fields with units, for the docs and error messages."""
        rows = []
        for form, cls in self.forms.items():
            fields = ", ".join(f"{f.name} [{f.metadata.get('unit', '-')}]" for f in dataclasses.fields(cls))
            rows.append(f"{form}: {fields}")
        return "; ".join(rows)


def param(default: Any = dataclasses.MISSING, doc: str = "", unit: str = "-", lo: float | None = None,
          hi: float | None = None, magnitude: bool = True):
    """A parameter field (pneumatics.config.spec's metadata: doc, SI unit, plausible range) that
    also says whether it is a ``magnitude`` of the effect (scaled by :meth:`Family.scaled`) or a
    shape (a Stribeck velocity, a side) that keeps its value."""
    meta = {"doc": doc, "unit": unit, "lo": lo, "hi": hi, "magnitude": magnitude}
    if default is dataclasses.MISSING:
        return dataclasses.field(metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def place_names(robot, kind: str) -> list[str]:
    """The places of ``kind`` on ``robot``, named like recording columns."""
    if kind == "joint":
        return list(robot.joint_names)
    if kind == "chamber":
        return [f"{a}.{c}" for a, c in robot.chamber_names]
    if kind == "actuator":
        return list(robot.actuator_names)
    if kind == "supply":
        return ["all"]
    raise UnknownNameError("place kind", kind, PLACE_KINDS)


def where_of(kind: str, place: str) -> dict:
    """DESIGN.md's report.json ``where`` of a place of ``kind``."""
    if kind == "chamber":
        a, c = place.split(".")
        return {"actuator": a, "chamber": c}
    if kind == "actuator":
        return {"actuator": place}
    if kind == "supply":
        return {"supply": "all"}
    return {"joint": place}


def joint_column(n_samples: int, n_joints: int, joint: int, values) -> np.ndarray:
    """(N, J) zeros with column ``joint`` = values: a torque acting at one joint."""
    out = np.zeros((n_samples, n_joints))
    out[:, joint] = values
    return out
