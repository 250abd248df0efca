"""A twin of the recordings made by the calibrated chamber model itself: how much a flexible
mass-flow correction (:mod:`.flexible`) pays at each chamber when nothing is missing.

The doctor reads each chamber's mass-flow balance from DAQ samples (10 ms means at 100 Hz).
Where a cylinder's pressure moves faster than the samples resolve (a rotary joint of
humanoid38 reversing under its limit cycle: 5 kPa rms of unresolved transients against a
sensor noise of 0.5 kPa), the balance's error carries the reconstruction's own error, which a
flexible correction partly fits: on the nominal humanoid38 with no effect and no noise its
best group paid 0.46-0.71 at five cylinders (docs/humanoid_doctor.md, "The chambers'
mass-flow balance under the limit cycle").  No fixed floor tells that from an effect.

The twin asks the model the same question under the same motion: its pressures are the
calibrated chamber model's replays, restarted every second from the measured pressures and
driven by the measured commands and motion, sampled as the DAQ samples, with the sensors'
noise added; its flexible corrections find only what the sampling and the noise make.  A
chamber of the real recording counts as paying only TWIN_MARGIN above its twin's gain
(flexible.paying), and the supply's change in time only SUPPLY_TIME_TWIN_MARGIN above its
twin's (supply_time).  This is a parametric bootstrap of the correction's null distribution,
one draw (Efron & Tibshirani, *An Introduction to the Bootstrap*, Chapman & Hall 1993, ch. 6).
"""
from __future__ import annotations

import numpy as np

from .data import Experiment, with_pressures
from .flexible import corrections
from .pneumatic import Windows, replay
from .pneumatic_mods import PneumaticMods
from .supply_time import SupplyInTime, supply_in_time

#: the twin's replays restart from the measured pressures this often [s] (as the published
#: samples' concealment check replays their recordings: each truth.json's "concealment")
TWIN_RESTART_S = 1.0
#: the twin's noise is drawn from this seed: the doctor gives the same report for the same data
TWIN_SEED = 0


def model_pressures(exp: Experiment, mods: PneumaticMods) -> np.ndarray:
    """(N, C) [Pa] the chamber model's pressures over each pooled recording of ``exp``, as the
    DAQ would record them: replays restarted from the measured pressures every TWIN_RESTART_S,
    so that the model's pressures stay where the recording's are (replayed over a whole
    recording, a model that lacks a valve hysteresis drifted 17 kPa rms from the published
    sample's elbow b, where its twin's correction then paid 0.37 instead of 0.12)."""
    p = exp.p.copy()
    horizon = max(1, int(round(TWIN_RESTART_S * exp.rate_hz)))
    bounds = (0, *exp.breaks, exp.p.shape[0])
    for a, b in zip(bounds[:-1], bounds[1:]):
        starts = np.arange(a, b - 1, horizon)
        whole, last = starts[starts + horizon <= b - 1], starts[starts + horizon > b - 1]
        if whole.size:
            predicted, _ = replay(exp, Windows(whole, horizon), mods)
            for k, s in enumerate(whole):
                p[s + 1:s + 1 + horizon] = predicted[k]
        for s in last:  # the recording's end: a shorter window
            predicted, _ = replay(exp, Windows(np.array([s]), b - 1 - s), mods)
            p[s + 1:b] = predicted[0]
    return p


def twin(exp: Experiment, mods: PneumaticMods, sigma_pa: float, rng: np.random.Generator) -> Experiment:
    """``exp`` with its pressures replaced by the model's (:func:`model_pressures`) plus white
    sensor noise of standard deviation ``sigma_pa`` [Pa]."""
    p = model_pressures(exp, mods)
    p[1:] += rng.normal(0.0, sigma_pa, p[1:].shape)
    return with_pressures(exp, p)


def twin_gains(exp: Experiment, held: Experiment, mods: PneumaticMods, sigma_pa: float,
               block: int) -> tuple[dict, SupplyInTime | None]:
    """({(actuator, chamber): the best group's held-out gain of the chamber's flexible
    correction}, the supply-in-time check (supply_time.supply_in_time)) on the twins of ``exp``
    (fitted) and ``held`` (judged) under ``mods``."""
    rng = np.random.default_rng(TWIN_SEED)
    exp_t, held_t = twin(exp, mods, sigma_pa, rng), twin(held, mods, sigma_pa, rng)
    corrs, tr, ho = corrections(exp_t, held_t, mods, block)
    gains = {(c.where["actuator"], c.where["chamber"]): c.best_group_gain for c in corrs if "supply" not in c.where}
    return gains, supply_in_time(tr, ho, exp.rate_hz, held.rate_hz)
