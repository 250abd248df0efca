"""A fitted effect (a doctor finding, or an ``[[effect]]`` of a model.toml) as the simulator's
:class:`~pneumatics.effects.effect_set.EffectSet` entry: the one place that mapping is written.

Each (family, form) the doctor can report names the parameters it carries and how they
enter the EffectSet.  The doctor's hypotheses (``identification/doctor/valve_arm/hypotheses.py``) test the
same physics the simulator runs (``effects/__init__.py``'s table), so most map exactly.
Two do not:

* ``end_stop`` (form ``spring_damper``): the doctor fits a one-sided spring k and damper b
  past the stop angle; the simulator's bumper is MuJoCo's soft joint limit moved to that
  angle, with its own time constant (effect_set.END_STOP_TIMECONST_S).  The stop is applied
  at the fitted angle, its k and b are not: *approximate*.
* ``force_sensor_offset`` (the bench doctor's load cell): no robot simulator entry: *not
  applied*.

:func:`effect_set` returns the EffectSet with a list of notes, one per entry it applied only
approximately or not at all; :func:`pneumatics.robot.load_robot` turns each note into a
:class:`FittedModelWarning`, so nothing in the file is dropped silently.
"""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import ConfigError
from .effect_set import END_STOP_TIMECONST_S, EffectSet

#: the Stribeck velocity [rad/s] of the doctor's stiction form (identification.doctor.valve_arm.replay.MechMods.torque)
STRIBECK_RAD_S = 0.1


class FittedModelWarning(UserWarning):
    """An entry of a fitted model the simulator applies only approximately, or not at all."""


#: (family, form) -> (required parameters, optional ones); parameters in the doctor's names
FORMS = {
    ("valve_leak", "both_lands_alike"): (("leak_area_m2",), ()),
    ("valve_leak", "two_lands"): (("supply_leak_area_m2", "exhaust_leak_area_m2"), ()),
    ("external_leak", "orifice"): (("leak_area_m2",), ()),
    ("external_leak", "laminar"): (("conductance_kg_s_pa",), ()),
    ("piston_leak", "orifice"): (("leak_area_m2",), ()),
    ("piston_leak", "laminar"): (("conductance_kg_s_pa",), ()),
    ("valve_hysteresis", "play"): (("half_width_v",), ()),
    ("valve_lag", "first_order"): (("time_constant_s",), ()),
    ("line_dynamics", "delay_and_volume"): (("delay_s",), ("volume_m3",)),
    ("heat_transfer", "energy_equation"): (("conductance_w_k",), ()),
    # offset_pa_if_chamber_<c>: the same actuator force error carried on the other chamber, an
    # isolability alternative the doctor reports; the offset itself acts on the place given
    ("pressure_sensor_offset", "additive"): (("offset_pa",), ("offset_pa_if_chamber_a", "offset_pa_if_chamber_b")),
    ("angle_sensor_offset", "additive"): (("offset_rad",), ()),
    ("supply_droop", "linear"): (("droop_pa_per_kg_s",), ()),
    ("backlash", "dead_zone"): (("gap_rad",), ()),
    ("coulomb_friction", "coulomb"): (("coulomb_nm",), ()),
    ("stiction", "stribeck"): (("coulomb_nm", "breakaway_extra_nm"), ("stribeck_velocity_rad_s",)),
    ("viscous_friction", "viscous"): (("viscous_nm_s_per_rad",), ()),
    ("end_stop", "spring_damper"): (("stiffness_nm_per_rad", "damping_nm_s_per_rad", "stop_rad", "side_sign"), ()),
    ("force_sensor_offset", "additive"): (("offset_n",), ()),
}


def form_of(family: str, parameter_names) -> str:
    """The form of ``family`` whose required parameters are all among ``parameter_names``
    (the most specific one); a ConfigError if none fits."""
    names = set(parameter_names)
    fits = [(len(req), form) for (fam, form), (req, _) in FORMS.items() if fam == family and set(req) <= names]
    if not fits:
        raise ConfigError(f"effect {family!r} with parameters {sorted(names)}: no known form; known: "
                          + "; ".join(f"{form} ({', '.join(req)})" for (fam, form), (req, _) in FORMS.items()
                                      if fam == family))
    return max(fits)[1]


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
    """Put fitted effect ``e`` into ``effects``; None if exact, else a note saying what is not
    applied.  Several friction forms at one joint add up."""
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
    fam = e.family
    if fam == "force_sensor_offset":
        return "a load-cell offset has no entry in the robot simulator: not applied"
    if fam == "end_stop":
        return _end_stop(effects, robot, place, v)
    if fam in ("coulomb_friction", "stiction", "viscous_friction"):
        fr = effects.friction.setdefault(place, {})
        add = {"coulomb_nm": v.get("coulomb_nm", 0.0), "stiction_extra_nm": v.get("breakaway_extra_nm", 0.0),
               "viscous_nm_s": v.get("viscous_nm_s_per_rad", 0.0)}
        for k, x in add.items():
            if x:
                fr[k] = fr.get(k, 0.0) + x
        if fam == "stiction":
            fr["stribeck_rad_s"] = v.get("stribeck_velocity_rad_s", STRIBECK_RAD_S)
        return None
    if fam == "valve_leak":
        if e.form == "both_lands_alike":
            effects.valve_leak_m2[place] = v["leak_area_m2"]
        else:
            effects.valve_leak_m2[place] = v["supply_leak_area_m2"]
            effects.valve_leak_exhaust_m2[place] = v["exhaust_leak_area_m2"]
        return None
    if fam == "line_dynamics":
        effects.line_dynamics[place] = {"delay_s": v["delay_s"], "volume_m3": v.get("volume_m3", 0.0)}
        return None
    if fam == "supply_droop":
        effects.supply_droop_pa_per_kg_s = v["droop_pa_per_kg_s"]
        return None
    attr, key, value = {
        ("external_leak", "orifice"): ("external_leak_m2", None, "leak_area_m2"),
        ("external_leak", "laminar"): ("external_leak_laminar_kg_s_pa", None, "conductance_kg_s_pa"),
        ("piston_leak", "orifice"): ("piston_leak_m2", None, "leak_area_m2"),
        ("piston_leak", "laminar"): ("piston_leak_laminar_kg_s_pa", None, "conductance_kg_s_pa"),
        ("valve_hysteresis", "play"): ("valve_hysteresis_v", None, "half_width_v"),
        ("valve_lag", "first_order"): ("valve_lag_s", None, "time_constant_s"),
        ("heat_transfer", "energy_equation"): ("heat_transfer", "conductance_w_k", "conductance_w_k"),
        ("pressure_sensor_offset", "additive"): ("pressure_offset_pa", None, "offset_pa"),
        ("angle_sensor_offset", "additive"): ("angle_offset_rad", None, "offset_rad"),
        ("backlash", "dead_zone"): ("backlash", "gap_rad", "gap_rad"),
    }[(fam, e.form)]
    getattr(effects, attr)[place] = v[value] if key is None else {key: v[value]}
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
