"""The model a ``pneumasim doctor`` run fitted, as a file the user keeps: ``model.toml``.

The file holds the model's name, every calibrated scale (dimensionless, multiplying the
nominal value in ``models/<name>/``), every kept effect with its place, physical form,
parameters (units in their names) and standard errors, what the doctor could not name, the
recordings it was fitted on, the pneumasim version, and the held-out NRMSE the doctor
measured with this model (so a reload can be checked against it).

:func:`read_fitted` reads and checks it (a :class:`~pneumatics.errors.ConfigError` naming the
file and field for anything malformed); :func:`write_fitted` writes it.  TOML is read with the
standard library's ``tomllib``; it is written by the small writer below rather than a new
dependency: the file needs only strings, numbers, lists of strings and inline tables, and a
hand-written layout keeps it readable (a comment header, one ``[[effect]]`` per effect).
Floats are written with ``repr``, the shortest text that reads back to the same double, so
``write(read(f))`` reproduces ``f`` byte for byte.

:func:`calibrated_robot` applies the calibration to a loaded robot; the effects reach the
simulator through :mod:`pneumatics.effects.from_finding`.
"""
from __future__ import annotations

import copy
import dataclasses
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from .config import read_toml
from .errors import ConfigError, UnknownNameError

FORMAT_VERSION = 1

#: calibration kinds: what each scale multiplies, and the kind of place it names
CALIBRATION_KINDS = {
    "supply_area_scale": ("chamber", "the valve's supply areas (supply_area_max_m2, the null leak with it)"),
    "exhaust_area_scale": ("chamber", "the valve's exhaust areas (exhaust_area_max_m2, the null leak with it)"),
    "dead_volume_scale": ("chamber", "the chamber's dead volume (dead_volume_a_m3 / dead_volume_b_m3)"),
    "mass_scale": ("body", "the body's mass and inertia tensor"),
    "damping_scale": ("joint", "the joint's damping (MJCF joint damping)"),
    "armature_scale": ("joint", "the joint's armature (MJCF joint armature)"),
}

HEADER = """\
# pneumasim fitted model: {name} as `pneumasim doctor` fitted it.
#
# Load it:   load_robot("{name}", fitted="model.toml")       (Python, pneumatics.robot)
#            pneumasim run SCENARIO --fitted model.toml       (scenarios that simulate {name})
# Units: SI, pressures absolute in Pa; each parameter's unit is in its name.
#
# [model]        the model's name, the pneumasim version, the recordings it was fitted and
#                judged on, and the held-out NRMSE per channel the doctor measured with this
#                model (its coupled replays; reloading reproduces them).
# [calibration]  "<kind>.<place>" = {{ value, stderr }}: dimensionless scales of the nominal
#                model's values (models/{name}/): supply_area_scale / exhaust_area_scale /
#                dead_volume_scale per chamber (actuator.chamber), mass_scale per body (mass
#                and inertia), damping_scale / armature_scale per joint.  Where a
#                line_dynamics effect sits, the tube's volume is that effect's volume_m3 and
#                the chamber's own scale is kept at most 1.
# [[effect]]     one kept effect: family (DESIGN.md vocabulary), form (its physical form,
#                pneumatics/effects/from_finding.py), where (its place), and parameters
#                {{ value, stderr }}.  The values are those of the doctor's final joint fit.
# [[unexplained]] a residual the doctor found and could not name: not in this model.
"""


@dataclass
class FittedEffect:
    """One kept effect: ``parameters`` maps name_unit -> {"value": v, "stderr": s}."""

    family: str
    form: str
    where: dict
    parameters: dict

    def value(self, name: str) -> float:
        return float(self.parameters[name]["value"])

    @property
    def place(self) -> str:
        """The place as the simulator names it: a joint, an actuator or "actuator.chamber"."""
        w = self.where
        if "chamber" in w:
            return f"{w['actuator']}.{w['chamber']}"
        return w.get("joint") or w.get("actuator") or w.get("supply", "all")


@dataclass
class FittedModel:
    """The content of a ``model.toml`` (see the module docstring)."""

    model: str
    calibration: dict = field(default_factory=dict)     # "<kind>.<place>" -> {"value", "stderr"}
    effects: list = field(default_factory=list)         # [FittedEffect]
    unexplained: list = field(default_factory=list)     # [{"where", "regime", "share_of_residual", "evidence"}]
    fitted_on: list = field(default_factory=list)       # recording sources
    heldout_on: list = field(default_factory=list)
    heldout_nrmse_after: dict = field(default_factory=dict)   # channel -> NRMSE the doctor measured
    pneumasim_version: str = ""
    path: Path | None = None                            # where it was read from

    def scale(self, kind: str, place: str) -> float:
        """The calibrated scale ``kind`` at ``place``; 1 (nominal) where the file has none."""
        entry = self.calibration.get(f"{kind}.{place}")
        return 1.0 if entry is None else float(entry["value"])

    def scales(self, kind: str) -> dict:
        """place -> scale of every calibration entry of ``kind``."""
        return {k.partition(".")[2]: float(v["value"]) for k, v in self.calibration.items()
                if k.partition(".")[0] == kind}


def pneumasim_version() -> str:
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("pneumasim")
    except PackageNotFoundError:
        return "unknown"


# -- reading ------------------------------------------------------------------------------
def read_fitted(path) -> FittedModel:
    """Read and check a model.toml; every problem is a ConfigError naming the file and field."""
    path = Path(path)
    doc = read_toml(path, "fitted model file")
    where = str(path)
    fmt = doc.get("format_version")
    if fmt != FORMAT_VERSION:
        raise ConfigError(f"{where}: format_version = {fmt!r}; this pneumasim reads format_version = "
                          f"{FORMAT_VERSION} (is it a model.toml written by pneumasim doctor?)")
    known = {"format_version", "model", "calibration", "effect", "unexplained"}
    for key in doc:
        if key not in known:
            raise ConfigError(f"{where}: unknown key {key!r}; valid: {', '.join(sorted(known))}")
    m = _table(doc.get("model"), f"{where} [model]")
    fields = {"name", "pneumasim_version", "fitted_on", "heldout_on", "heldout_nrmse_after"}
    for key in m:
        if key not in fields:
            raise ConfigError(f"{where} [model]: unknown field {key!r}; valid: {', '.join(sorted(fields))}")
    name = m.get("name")
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{where} [model].name: expected the model's name (a string), got {name!r}")
    cal = _table(doc.get("calibration", {}), f"{where} [calibration]")
    for key, entry in cal.items():
        kind, _, place = key.partition(".")
        if kind not in CALIBRATION_KINDS or not place:
            raise ConfigError(f"{where} [calibration].{key!r}: expected '<kind>.<place>' with kind one of "
                              f"{', '.join(CALIBRATION_KINDS)}")
        _estimate(entry, f"{where} [calibration].{key!r}", positive=True)
    effects = [_effect(e, f"{where} [[effect]] #{i + 1}") for i, e in enumerate(_list(doc.get("effect", []), where, "effect"))]
    unexplained = [_table(u, f"{where} [[unexplained]] #{i + 1}")
                   for i, u in enumerate(_list(doc.get("unexplained", []), where, "unexplained"))]
    for i, u in enumerate(unexplained):
        _table(u.get("where", {}), f"{where} [[unexplained]] #{i + 1}.where")
    nrmse = _table(m.get("heldout_nrmse_after", {}), f"{where} [model].heldout_nrmse_after")
    for k, v in nrmse.items():
        _number(v, f"{where} [model].heldout_nrmse_after.{k!r}")
    return FittedModel(
        model=name, calibration=cal, effects=effects,
        unexplained=unexplained,
        fitted_on=_strings(m.get("fitted_on", []), f"{where} [model].fitted_on"),
        heldout_on=_strings(m.get("heldout_on", []), f"{where} [model].heldout_on"),
        heldout_nrmse_after={k: float(v) for k, v in nrmse.items()},
        pneumasim_version=str(m.get("pneumasim_version", "")), path=path)


def _effect(t, where) -> FittedEffect:
    from .effects import VOCABULARY

    t = _table(t, where)
    for key in ("family", "form", "where", "parameters"):
        if key not in t:
            raise ConfigError(f"{where}: missing field {key!r}")
    extra = set(t) - {"family", "form", "where", "parameters"}
    if extra:
        raise ConfigError(f"{where}: unknown field {sorted(extra)[0]!r}; valid: family, form, where, parameters")
    if t["family"] not in VOCABULARY:
        raise UnknownNameError("effect family", str(t["family"]), VOCABULARY)
    place = _table(t["where"], f"{where}.where")
    if not place or not all(isinstance(v, str) for v in place.values()):
        raise ConfigError(f"{where}.where: expected a place such as {{ joint = \"elbow\" }}, got {place!r}")
    params = _table(t["parameters"], f"{where}.parameters")
    for k, v in params.items():
        _estimate(v, f"{where}.parameters.{k}")
    return FittedEffect(str(t["family"]), str(t["form"]), dict(place), params)


def _table(x, where) -> dict:
    if not isinstance(x, dict):
        raise ConfigError(f"{where}: expected a table, got {type(x).__name__}")
    return x


def _list(x, where, key) -> list:
    if not isinstance(x, list):
        raise ConfigError(f"{where}: {key} must be an array of tables ([[{key}]])")
    return x


def _strings(x, where) -> list:
    if not isinstance(x, list) or not all(isinstance(s, str) for s in x):
        raise ConfigError(f"{where}: expected a list of strings, got {x!r}")
    return list(x)


def _number(v, where) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ConfigError(f"{where}: expected a number, got {v!r}")
    return float(v)


def _estimate(entry, where, positive: bool = False):
    """A {value, stderr} pair: the value finite (and > 0 for a scale); the stderr a number
    (nan or inf where the fit gave no error bar)."""
    entry = _table(entry, where)
    if set(entry) != {"value", "stderr"}:
        raise ConfigError(f"{where}: expected {{ value = ..., stderr = ... }}, got keys {sorted(entry)}")
    v = _number(entry["value"], f"{where}.value")
    _number(entry["stderr"], f"{where}.stderr")
    if not math.isfinite(v) or (positive and v <= 0):
        raise ConfigError(f"{where}.value = {v!r}: expected a finite{' positive' if positive else ''} number")


# -- writing ------------------------------------------------------------------------------
def write_fitted(fm: FittedModel, path) -> Path:
    """Write ``fm`` as a model.toml at ``path`` (atomically); returns the path."""
    from .io import atomic_write_text

    path = Path(path)
    atomic_write_text(path, fitted_text(fm))
    return path


def fitted_text(fm: FittedModel) -> str:
    """The model.toml text of ``fm``."""
    out = [HEADER.format(name=fm.model), f"format_version = {FORMAT_VERSION}", "", "[model]",
           f"name = {_toml(fm.model)}", f"pneumasim_version = {_toml(fm.pneumasim_version)}",
           f"fitted_on = {_toml(list(fm.fitted_on))}", f"heldout_on = {_toml(list(fm.heldout_on))}",
           f"heldout_nrmse_after = {_toml(fm.heldout_nrmse_after)}", "", "[calibration]"]
    out += [f"{_key(k)} = {_toml(v)}" for k, v in fm.calibration.items()]
    for e in fm.effects:
        out += ["", "[[effect]]", f"family = {_toml(e.family)}", f"form = {_toml(e.form)}",
                f"where = {_toml(e.where)}", "[effect.parameters]"]
        out += [f"{_key(k)} = {_toml(v)}" for k, v in e.parameters.items()]
    for u in fm.unexplained:
        out += ["", "[[unexplained]]"] + [f"{_key(k)} = {_toml(v)}" for k, v in u.items()]
    return "\n".join(out) + "\n"


_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(k: str) -> str:
    return k if _BARE_KEY.match(k) else json.dumps(k)


def _toml(v) -> str:
    """One TOML value: strings, booleans, numbers (nan/inf as TOML writes them), lists and
    inline tables of these."""
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a JSON string is a valid TOML basic string
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float) or hasattr(v, "dtype"):
        v = float(v)
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_toml(x)}" for k, x in v.items()) + " }" if v else "{}"
    raise TypeError(f"model.toml cannot hold a {type(v).__name__}: {v!r}")


# -- the calibration, applied -----------------------------------------------------------------
def calibrated_robot(robot, fm: FittedModel):
    """``robot`` (as :func:`pneumatics.robot.load_robot` built it) with ``fm``'s calibration:
    valve areas and dead volumes scaled in its fluid parameters, body masses and inertias, joint
    damping and armature scaled in a copy of its MuJoCo model.  An unknown place is a
    ConfigError naming the file's entry."""
    src = fm.path or "model.toml"
    chambers = [f"{a}.{c}" for a, c in robot.chamber_names]
    fluid = robot.fluid
    for key in fm.calibration:
        kind, _, place = key.partition(".")
        valid = {"chamber": chambers, "joint": robot.joint_names,
                 "body": [robot.model.body(i).name for i in range(1, robot.model.nbody)]}[CALIBRATION_KINDS[kind][0]]
        if place not in valid:
            raise ConfigError(f"{src} [calibration].{key!r}: {robot.name} has no {CALIBRATION_KINDS[kind][0]} "
                              f"{place!r}; valid: {', '.join(valid)}")
    for a, c in robot.chamber_names:
        act = next(x for x in fluid.actuators if x.name == a)
        valve = getattr(act, f"valve_{c}")
        valve = dataclasses.replace(
            valve, supply_area_max_m2=valve.supply_area_max_m2 * fm.scale("supply_area_scale", f"{a}.{c}"),
            exhaust_area_max_m2=valve.exhaust_area_max_m2 * fm.scale("exhaust_area_scale", f"{a}.{c}"))
        dead = getattr(act, f"dead_volume_{c}_m3") * fm.scale("dead_volume_scale", f"{a}.{c}")
        fluid = fluid.replace_actuator(a, **{f"valve_{c}": valve, f"dead_volume_{c}_m3": dead})
    model = copy.copy(robot.model)
    for body, s in fm.scales("mass_scale").items():
        b = model.body(body).id
        model.body_mass[b] *= s
        model.body_inertia[b] *= s
    for joint, s in fm.scales("damping_scale").items():
        model.dof_damping[model.joint(joint).dofadr[0]] *= s
    for joint, s in fm.scales("armature_scale").items():
        model.dof_armature[model.joint(joint).dofadr[0]] *= s
    # the fluid tables rebuilt from the scaled parameters, then the scaled MuJoCo model (the
    # masses, damping and armature do not move the pistons' zero lengths the tables hold)
    return dataclasses.replace(robot.with_fluid(fluid), model=model)
