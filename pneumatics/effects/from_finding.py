"""A fitted effect (a doctor finding, or an ``[[effect]]`` of a model.toml) as the simulator's
:class:`~pneumatics.effects.effect_set.EffectSet` entry, through the effect registry.

The forms, their parameters and how each enters the simulator are the families' own
(:mod:`pneumatics.effects.registry`; the doctor reports a finding's parameters under the field
names of its family's form).  What this module adds is what a *fitted* model needs beyond that:

* ``end_stop`` (form ``spring_damper``): the doctor fits a one-sided spring k and damper b
  past the stop angle; the simulator's bumper is MuJoCo's soft joint limit moved to that
  angle, with its own time constant (effect_set.END_STOP_TIMECONST_S).  The stop is applied
  at the fitted angle, its k and b are not: *approximate*.
* ``force_sensor_offset`` (the bench doctor's load cell): no robot simulator entry: *not
  applied*.
* a pressure-sensor offset the torque balance found names its actuator: it is carried on
  chamber a, with the chamber-b equivalent as an isolability alternative.

:func:`effect_set` returns the EffectSet with a list of notes, one per entry it applied only
approximately or not at all; :func:`pneumatics.robot.load_robot` turns each note into a
:class:`FittedModelWarning`, so nothing in the file is dropped silently.
"""
from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from ..errors import ConfigError
from .effect_set import END_STOP_TIMECONST_S, EffectSet
from .registry import FAMILIES, get_family

#: parameters a finding may carry beyond its form's fields: isolability alternatives
ALTERNATIVE_PARAMETERS = {"pressure_sensor_offset": ("offset_pa_if_chamber_a", "offset_pa_if_chamber_b")}
#: form fields a finding may leave out (the doctor fits a tube's volume only where it pays)
MAY_OMIT = {("line_dynamics", "delay_volume"): ("volume_m3",)}


class FittedModelWarning(UserWarning):
    """An entry of a fitted model the simulator applies only approximately, or not at all."""


def _forms() -> dict:
    """(family, form) -> (required parameters, optional ones), from the registry: a form's
    magnitude fields are required, its shape fields (a Stribeck velocity) optional."""
    out = {}
    for name, fam in FAMILIES.items():
        for form, cls in fam.forms.items():
            fields = dataclasses.fields(cls)
            omit = MAY_OMIT.get((name, form), ())
            req = tuple(f.name for f in fields if f.metadata.get("magnitude", True) and f.name not in omit)
            opt = tuple(f.name for f in fields if f.name not in req) + ALTERNATIVE_PARAMETERS.get(name, ())
            out[(name, form)] = (req, opt)
    return out


#: (family, form) -> (required parameters, optional ones); parameters in the doctor's names
FORMS = _forms()

#: the Stribeck velocity [rad/s] of the doctor's stiction form (its default in the registry)
STRIBECK_RAD_S = get_family("stiction").forms["stribeck"]().stribeck_rad_s


def form_of(family: str, parameter_names) -> str:
    """The form of ``family`` whose required parameters are all among ``parameter_names``
    (the most specific one: most required, then most optional ones given, then fewest
    optional ones missing); a ConfigError if none fits."""
    names = set(parameter_names)
    fits = [(len(req), len(set(opt) & names), -len(set(opt) - names), form) for (fam, form), (req, opt) in FORMS.items()
            if fam == family and set(req) <= names]
    if not fits:
        raise ConfigError(f"effect {family!r} with parameters {sorted(names)}: no known form; known: "
                          + "; ".join(f"{form} ({', '.join(req)})" for (fam, form), (req, _) in FORMS.items()
                                      if fam == family))
    return max(fits)[-1]


def effect_set(effects: list, robot, source: str = "model.toml") -> tuple[EffectSet, list[str]]:
    """The EffectSet of ``effects`` ([FittedEffect]) on ``robot``, and one note per entry it
    applies approximately or not at all.  A malformed entry (unknown form or place, a
    parameter missing) is a ConfigError naming ``source`` and the entry."""
    out, notes = EffectSet(), []
    for i, e in enumerate(effects):
        where = f"{source} [[effect]] #{i + 1} ({e.family} at {e.place})"
        note = add_effect(out, e, robot, where)
        if note:
            notes.append(f"{where}: {note}")
    return out, notes


def warn_notes(notes: list[str], stacklevel: int = 4):
    """One FittedModelWarning per note, attributed to load_robot's caller by default."""
    for n in notes:
        warnings.warn(n, FittedModelWarning, stacklevel=stacklevel)


def add_effect(effects: EffectSet, e, robot, where: str = "effect") -> str | None:
    """Put fitted effect ``e`` into ``effects`` through its family; None if exact, else a note
    saying what is not applied.  Several friction forms at one joint add up."""
    if (e.family, e.form) not in FORMS:
        forms = [f for fam, f in FORMS if fam == e.family]
        raise ConfigError(f"{where}: unknown form {e.form!r} of {e.family}; known: {', '.join(forms) or 'none'}")
    required, optional = FORMS[(e.family, e.form)]
    missing = [p for p in required if p not in e.parameters]
    unknown = [p for p in e.parameters if p not in required + optional]
    if missing or unknown:
        raise ConfigError(f"{where}: form {e.form} needs parameters {', '.join(required)}"
                          + (f" (optional: {', '.join(optional)})" if optional else "")
                          + f"; missing {missing}, unknown {unknown}")
    v = {k: e.value(k) for k in e.parameters}
    place = _place(e, robot, where)
    if e.family == "force_sensor_offset":
        return "a load-cell offset has no entry in the robot simulator: not applied"
    if e.family == "end_stop" and e.form == "spring_damper":
        return _end_stop(effects, robot, place, v)
    fam = get_family(e.family)
    values = {k: x for k, x in v.items() if k not in ALTERNATIVE_PARAMETERS.get(e.family, ())}
    fam.add_to(effects, place, fam.params(values, e.form))  # friction terms at one joint add up
    return None


def _place(e, robot, where: str) -> str:
    """The simulator's name of e's place, checked against ``robot``.  A pressure-sensor offset
    the torque balance found names only its actuator; the doctor carries it on chamber a."""
    w = e.where
    chambers = [f"{a}.{c}" for a, c in robot.chamber_names]
    if e.family == "supply_droop":
        return "all"
    if "chamber" in w:
        place, valid, kind = f"{w.get('actuator')}.{w['chamber']}", chambers, "chamber"
    elif "joint" in w:
        place, valid, kind = w["joint"], robot.joint_names, "joint"
    elif "actuator" in w:
        place, valid, kind = w["actuator"], robot.actuator_names, "actuator"
    else:
        raise ConfigError(f"{where}: where = {w!r}: expected a joint, an actuator or an actuator and chamber")
    if place not in valid:
        raise ConfigError(f"{where}: {robot.name} has no {kind} {place!r}; valid: {', '.join(valid)}")
    if e.family == "pressure_sensor_offset" and kind == "actuator":
        return f"{place}.a"
    return place


def _end_stop(effects: EffectSet, robot, joint: str, v: dict) -> str:
    """The bumper at the fitted stop angle, as the simulator's soft joint limit moved inward."""
    jid = robot.model.joint(joint).id
    lo, hi = robot.model.jnt_range[jid] if robot.model.jnt_limited[jid] else (-np.pi, np.pi)
    upper = v["side_sign"] > 0
    intrusion = (hi - v["stop_rad"]) if upper else (v["stop_rad"] - lo)
    effects.end_stop.setdefault(joint, {})["upper_intrusion_rad" if upper else "lower_intrusion_rad"] = \
        float(max(intrusion, 0.0))
    return (f"stop at {v['stop_rad']:.4g} rad applied as MuJoCo's soft joint limit (time constant "
            f"{1000 * END_STOP_TIMECONST_S:.0f} ms); the fitted stiffness {v['stiffness_nm_per_rad']:.3g} N m/rad and damping "
            f"{v['damping_nm_s_per_rad']:.3g} N m s/rad are not (approximate)")
