"""A shared supply's pressure held along each recording, so that a candidate at one cylinder is
fitted on that cylinder alone.

Under a drooping supply (supply_droop: linear, regulator-orifice or reservoir form) or a
compressor's receiver, every chamber's supply pressure follows the flow all chambers draw, and a
replay of one cylinder needs all the others (pneumatic.chambers_independent).  A candidate's fit
beside the chamber calibration (screening.fit_pneumatic) then replays and refits every chamber
at every step of its least squares: on humanoid38's supply-droop case 686488861 (development,
profiled 2026-12-07) each of 37 candidates took 30-35 s, most of a 24.8 min doctor run.

A candidate at a cylinder hardly moves the total flow of 38 cylinders, so the supply pressure
each window sees can be held at the path the model gives it at the measured chamber pressures:
the total flow the valves draw there (receiver.measured_supply_flow, drawn from the path itself
on a second pass, as receiver.receiver_trajectory draws a compressor's), low-passed in the
reservoir form, through the droop law (effects.supply_droop.droop_pa, below the receiver's path
where there is one).  :func:`with_held_supply` returns the chamber model with that path in
place of its supply's laws; the chambers are then independent and the candidate's cylinder is
fitted alone; :func:`with_supply_of` puts the laws back into the fitted model.
"""
from __future__ import annotations

import numpy as np

from pneumatics.effects import effect_set
from pneumatics.effects.supply_droop import droop_pa

from .data import Experiment
from .pneumatic import ChamberModel, chambers_independent, effective_commands, has_droop, reservoir_flow
from .pneumatic_mods import PneumaticMods
from .receiver import experiment_key, measured_supply_flow, receiver_trajectory

#: the chamber model's fields that make up its supply: the droop's and the compressor's laws (the
#: effect set's supply fields) and the paths held along the recordings
SUPPLY_FIELDS = (*effect_set.SUPPLY_FIELDS, "receiver_paths", "supply_paths")


def supply_path(exp: Experiment, mods: PneumaticMods) -> np.ndarray:
    """(F,) the supply pressure [Pa] along ``exp`` on the 1 ms grid under ``mods``'s supply, the
    valves drawing their flows at the measured chamber pressures: the receiver's path (or the
    table's supply) less the droop of the total flow drawn from it."""
    model = ChamberModel(exp.robot, mods, 1)
    u_fine = effective_commands(exp, mods)
    source = receiver_trajectory(exp, model, u_fine)
    source = model.tab.supply_pa if source is None else source
    if not has_droop(mods):
        return np.broadcast_to(source, exp.fine_t.shape).astype(float)
    path = source
    for _ in range(2):  # drawn at the table's supply first, then at the path's
        total = reservoir_flow(measured_supply_flow(exp, model, u_fine, path), mods.supply_droop_tau_s)
        path = source - droop_pa(total, mods.supply_droop_pa_per_kg_s, mods.supply_droop_pa_per_kg2_s2)
    return np.asarray(path, float)


def with_held_supply(mods: PneumaticMods, exps) -> PneumaticMods:
    """``mods`` with its supply's laws replaced by the pressure path they give along each of
    ``exps`` (:func:`supply_path`); ``mods`` itself where its chambers are independent already."""
    if chambers_independent(mods, exps):
        return mods
    paths = {experiment_key(e): supply_path(e, mods) for e in exps}
    return mods.copy(supply_droop_pa_per_kg_s=0.0, supply_droop_pa_per_kg2_s2=0.0, supply_droop_tau_s=0.0,
                     supply_receiver_m3=0.0, receiver_paths=None, supply_paths=paths)


def with_supply_of(fitted: PneumaticMods, source: PneumaticMods) -> PneumaticMods:
    """``fitted`` (a model fitted under :func:`with_held_supply`) with ``source``'s supply laws
    back in place of the held path."""
    return fitted.copy(**{name: getattr(source, name) for name in SUPPLY_FIELDS})
