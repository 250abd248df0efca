"""The doctor's fitted model as files the user keeps, and its replay from them.

* :func:`fitted_model` turns a doctor run's final state (report, the final joint fit's
  parameter values, the calibration's standard errors) into a
  :class:`pneumatics.fitted_model.FittedModel`; :func:`write_fitted_files` writes it as
  ``model.toml`` and the plain-MuJoCo ``fitted.xml`` (:mod:`pneumatics.fitted_mjcf`).
* :func:`replay_mods` and :func:`heldout_replay` run a robot loaded with
  ``load_robot(name, fitted=...)`` through the doctor's own coupled replays
  (:func:`identification.doctor.valve_arm.replay.coupled_replay`): the calibration comes baked into the
  loaded robot, the effects through the doctor's hypotheses (the same ``apply`` functions its
  fits used), so a reload reproduces the report's held-out NRMSE.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from pneumatics.effects.from_finding import STRIBECK_RAD_S, form_of
from pneumatics.effects.registry import FAMILIES, get_family
from pneumatics.errors import ConfigError
from pneumatics.fitted_model import FittedEffect, FittedModel, pneumasim_version, write_fitted

from .data import pool, prepare
from .hypotheses import pneumatic_hypotheses
from .pneumatic_mods import PneumaticMods
from .replay import MechMods, ReplayResult, coupled_replay
from .search import MECH_ATTRS


def fitted_model(robot, report: dict, final_params: list, cal_stderr: dict) -> FittedModel:
    """The FittedModel of a doctor run: ``report`` as :func:`identification.doctor.diagnose`
    builds it, ``final_params`` the parameters of each of its findings in the final joint fit
    (aligned with ``report["findings"]``), ``cal_stderr`` the calibration's standard errors."""
    cal = {k: {"value": float(v), "stderr": float(cal_stderr.get(k, np.nan))}
           for k, v in report["calibrated_with_findings"].items()}
    effects = []
    for f, params in zip(report["findings"], final_params):
        params = {k: {"value": float(v["value"]), "stderr": float(v["stderr"])} for k, v in params.items()}
        if f["effect"] == "stiction":  # the doctor's Stribeck velocity, fixed (replay.MechMods.torque)
            params["stribeck_rad_s"] = {"value": STRIBECK_RAD_S, "stderr": 0.0}
        e = FittedEffect(f["effect"], form_of(f["effect"], params), dict(f["where"]), params)
        if (e.family, e.form) == ("line_dynamics", "delay_volume"):
            _split_line_volume(robot, e, cal)
        effects.append(e)
    d = report["diagnostics"]
    held = d.get("heldout_sources")
    return FittedModel(
        model=report["model"], calibration=cal, effects=effects,
        unexplained=[{k: u[k] for k in ("where", "regime", "share_of_residual", "evidence") if k in u}
                     for u in report["unexplained"]],
        fitted_on=[str(s) for s in d.get("train_sources", [])],
        heldout_on=[str(s) for s in held] if isinstance(held, list) else [str(held)],
        heldout_nrmse_after={k: float(v) for k, v in report["after"]["heldout_nrmse"].items()},
        pneumasim_version=pneumasim_version())


def _split_line_volume(robot, e: FittedEffect, cal: dict):
    """A tube (line_dynamics) adds its volume to the chamber's dead volume: the doctor fits
    the sum as the chamber's dead-volume scale.  In the file the tube keeps what grew past
    the nominal dead volume (volume_m3) and the chamber's scale at most 1, so the two add up
    to the fitted total and neither is counted twice."""
    key = f"dead_volume_scale.{e.place}"
    c = [f"{a}.{ch}" for a, ch in robot.chamber_names].index(e.place)
    nominal = float(robot.tables.dead_volume[c])
    scale = cal[key]["value"] if key in cal else 1.0
    se = cal[key]["stderr"] if key in cal else 0.0
    e.parameters["volume_m3"] = {"value": max(scale - 1.0, 0.0) * nominal, "stderr": se * nominal}
    if key in cal:
        cal[key] = {"value": min(scale, 1.0), "stderr": se if scale < 1.0 else 0.0}


def write_fitted_files(fm: FittedModel, out, robot) -> list[Path]:
    """model.toml and fitted.xml of ``fm`` in folder ``out``; ``robot`` the nominal model."""
    from pneumatics.fitted_mjcf import write_fitted_mjcf

    out = Path(out)
    return [write_fitted(fm, out / "model.toml"), write_fitted_mjcf(robot, fm, out / "fitted.xml")]


# -- replaying a loaded fitted model ------------------------------------------------------------
def replay_mods(robot) -> tuple[PneumaticMods, MechMods]:
    """The doctor's chamber and rigid-body modifications for the effects of ``robot.fitted``
    (a robot from ``load_robot(name, fitted=...)``, whose calibration is already in its model
    and fluid parameters, so the scales here stay nominal)."""
    fm = robot.fitted
    if fm is None:
        raise ConfigError(f"{robot.name}: not loaded with a fitted model (load_robot(name, fitted=...))")
    pmods = PneumaticMods.nominal(robot.tables.n_chambers)
    mmods = MechMods()
    hyps = pneumatic_hypotheses(robot)
    J = len(robot.joint_names)
    for e in fm.effects:
        if e.family == "pressure_sensor_offset" or (e.family, e.form) in _PNEUMATIC_FORMS:
            pmods = _apply_pneumatic(pmods, e, hyps, robot)
        elif e.family in _MECH:
            j = robot.joint_names.index(e.place)
            for name, attr in [(n, MECH_ATTRS[n]) for n in e.parameters if MECH_ATTRS.get(n)]:
                arr = getattr(mmods, attr)
                arr = np.zeros(J) if arr is None else arr
                arr[j] = arr[j] + e.value(name) if e.family != "angle_sensor_offset" else e.value(name)
                setattr(mmods, attr, arr)
            if e.family == "end_stop":
                mmods.end_stops[j] = (e.value("stop_rad"), e.value("side_sign"))
            elif e.form == "velocity_power":
                # a shape the file may leave out: the form's own default then (from_finding.FORMS)
                mmods.viscous_exponents[j] = (e.value("exponent") if "exponent" in e.parameters
                                              else get_family(e.family).params({}, e.form).exponent)
        else:
            raise ConfigError(f"{e.family} ({e.form}) at {e.place}: the doctor's replays have no such effect")
    return pmods, mmods


#: the mechanical effects: those the doctor's torque balance tests (the registry's doctor side);
#: each reported parameter goes to its MechMods attribute (search.MECH_ATTRS)
_MECH = {name for name, fam in FAMILIES.items() if fam.doctor == "torque_balance"}

#: the pneumatic forms and the hypothesis parameters they are fitted as (identification.doctor.valve_arm.hypotheses)
_PNEUMATIC_FORMS = {
    ("valve_leak", "symmetric"): ("leak_area_m2",),
    ("valve_leak", "asymmetric"): ("supply_leak_area_m2", "exhaust_leak_area_m2"),
    ("valve_leak", "underlap"): ("underlap_area_m2",),
    ("valve_leak", "clearance"): ("clearance_conductance_kg_s_pa",),
    ("external_leak", "orifice"): ("leak_area_m2",),
    ("piston_leak", "orifice"): ("leak_area_m2",),
    ("piston_leak", "laminar"): ("conductance_kg_s_pa",),
    ("valve_hysteresis", "play"): ("half_width_v",),
    ("valve_lag", "first_order"): ("time_constant_s",),
    ("valve_lag", "dead_time"): ("dead_time_s",),   # no hypothesis of its own: naming.line_named
    ("valve_lag", "slew_limit"): ("full_stroke_time_s",),
    ("line_dynamics", "delay_volume"): ("delay_s",),
    ("line_dynamics", "lumped_rc"): ("tube_volume_m3", "time_constant_s"),
    ("heat_transfer", "newton"): ("conductance_w_k",),
    ("pressure_sensor_offset", "additive"): ("offset_pa",),
    ("pressure_sensor_offset", "warm_up_drift"): ("offset_pa", "drift_pa", "time_constant_s"),
    ("supply_droop", "linear"): ("droop_pa_per_kg_s",),
    ("supply_droop", "reservoir"): ("droop_pa_per_kg_s", "time_constant_s"),
    ("supply_droop", "regulator_orifice"): ("droop_pa_per_kg2_s2", "time_constant_s"),
    ("supply_droop", "compressor_cycling"): ("receiver_volume_m3", "compressor_kg_s", "band_pa", "cut_out_pa",
                                             "leak_kg_s_pa"),
    ("backlash", "dead_zone"): ("gap_rad",),
}


def _apply_pneumatic(pmods: PneumaticMods, e: FittedEffect, hyps: list, robot) -> PneumaticMods:
    """e applied by the doctor's own hypothesis of that family, place and form (a valve dead
    time, which the doctor finds as a line without volume (naming.line_named), by its family's
    own hook)."""
    if (e.family, e.form) == ("valve_lag", "dead_time"):
        fam = get_family("valve_lag")
        return fam.apply_to_mods(pmods, robot, e.place, fam.params({"dead_time_s": e.value("dead_time_s")}, "dead_time"))
    names = _PNEUMATIC_FORMS.get((e.family, e.form))
    if names is None:
        raise ConfigError(f"{e.family} ({e.form}) at {e.place}: the doctor's replays have no such form")
    where = dict(e.where)
    if e.family == "pressure_sensor_offset" and "chamber" not in where:
        where["chamber"] = "a"  # an offset the replays could not place, carried on chamber a (sensor_offsets.offset_place)
    match = [h for h in hyps if h.family == e.family and h.where == where
             and tuple(p[0] for p in h.params) == names]
    if not match:
        raise ConfigError(f"{e.family} ({e.form}) at {e.place}: no such hypothesis on {robot.name}")
    pmods = match[0].apply(pmods, np.array([e.value(n) for n in names]))
    if e.family == "line_dynamics" and "volume_m3" in e.parameters:
        c = [f"{a}.{ch}" for a, ch in robot.chamber_names].index(e.place)
        extra = np.zeros(robot.tables.n_chambers) if pmods.extra_volume_m3 is None else pmods.extra_volume_m3.copy()
        extra[c] += e.value("volume_m3")
        pmods = pmods.copy(extra_volume_m3=extra)
    return pmods


def heldout_replay(robot, recordings) -> ReplayResult:
    """The doctor's coupled replays of ``recordings`` (the held-out ones) with the fitted model
    ``robot`` (from ``load_robot(name, fitted=...)``); ``.nrmse()`` is the report's
    ``after.heldout_nrmse`` when these are the run's held-out recordings."""
    held = pool([prepare(robot, r) for r in recordings])
    pmods, mmods = replay_mods(robot)
    return coupled_replay(held, pmods, mmods)
