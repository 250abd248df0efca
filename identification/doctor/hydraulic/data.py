"""Read and check recordings of the hydraulic elbow for the doctor, and hold out a part.

Columns (DESIGN.md names; what ``pneumatics.hydraulics.runner.run_measured`` writes; extra
columns are kept and ignored)::

    time         s, strictly increasing, evenly sampled (the replay steps the recorded current)
    i.elbow      valve current [A], applied from this row's time to the next  (required)
    q.elbow      vane angle (motor-side encoder) [rad], 0 = forearm hanging    (required)
    p_a.elbow    chamber a pressure [Pa abs] (a turns the joint positive)      (required)
    p_b.elbow    chamber b pressure [Pa abs]                                   (required)
    tau.elbow    joint torque sensor [N m] (optional: without it the shaft is taken as stiff
                 and shaft_compliance and force_sensor_offset are not tested)

A recording whose sidecar says ``"braced": true`` was made with the load locked by the steel
brace (paper 001 Fig. 2a, §3.2.2): the valve works against the blocked vane and its shaft, so
the pressures show the chambers' volumes and the angle and torque the shaft's stiffness
directly.  Braced recordings are given among the fitted and the held-out ones alike.
"""
from __future__ import annotations

import numpy as np

import models
from pneumatics.errors import RecordingError
from pneumatics.hydraulics.config import HydraulicCfg, load_hydraulic_cfg
from pneumatics.recording import Recording
from pneumatics.recording_checks import check_pressures

from .replay import BURN_IN_S, Trace, make_trace

HOLDOUT = 0.3            # share of each recording held out (its end) without held-out files
REQUIRED = ("i.elbow", "q.elbow", "p_a.elbow", "p_b.elbow")
OPTIONAL = ("tau.elbow",)
MIN_SECONDS = 10 * BURN_IN_S
MAX_JITTER = 0.05        # sample spacing may vary by this share of its median
MAX_RATE_HZ = 5000.0


def load_model_cfg(model: str) -> HydraulicCfg:
    kind = models.model_kind(model)
    if kind != "hydraulic":
        raise RecordingError(f"hydraulic doctor: model {model!r} is of kind {kind!r}, not 'hydraulic'")
    return load_hydraulic_cfg(models.fluid_path(model))


def check(rec: Recording, model: str, cfg: HydraulicCfg):
    """Raise a :class:`RecordingError` naming the file and column for anything the doctor cannot use."""
    if rec.meta.get("model") not in (None, model):
        raise RecordingError(f"{rec.source}: recorded for model {rec.meta['model']!r} (sidecar), diagnosed as {model!r}")
    missing = [c for c in REQUIRED if c not in rec]
    if missing:
        raise RecordingError(f"{rec.source}: missing column(s) {', '.join(missing)}; a hydraulic elbow recording "
                             f"needs time, i.elbow [A], q.elbow [rad], p_a.elbow and p_b.elbow [Pa abs] "
                             f"(tau.elbow [N m] optional)")
    t = rec.time
    if t.size < 100 or t[-1] - t[0] < MIN_SECONDS:
        raise RecordingError(f"{rec.source}: {t.size} rows over {t[-1] - t[0]:.3g} s; need at least 100 rows and "
                             f"{MIN_SECONDS:g} s")
    dt = np.diff(t)
    med = float(np.median(dt))
    if np.max(np.abs(dt - med)) > MAX_JITTER * med or 1.0 / med > MAX_RATE_HZ:
        row = int(np.argmax(np.abs(dt - med))) + 2
        raise RecordingError(f"{rec.source}: column time: rows must be evenly spaced at <= {MAX_RATE_HZ:g} Hz "
                             f"(median step {med:.4g} s, row {row} steps {dt[row - 2]:.4g} s); resample the recording")
    for c in (*REQUIRED, *OPTIONAL):
        if c in rec and not np.all(np.isfinite(rec[c])):
            row = int(np.argmin(np.isfinite(rec[c])))
            raise RecordingError(f"{rec.source}: column {c} row {row + 1}: not a finite number")
    i_sat = cfg.hysteresis.saturation_current_a
    if np.max(np.abs(rec["i.elbow"])) > 10 * i_sat:
        raise RecordingError(f"{rec.source}: column i.elbow reaches {np.max(np.abs(rec['i.elbow'])):.4g}; the valve "
                             f"saturates at ±{i_sat:g} A: a current in mA? (A expected)")
    check_pressures(rec, cfg.power.tank_pa, cfg.power.pump_pa, ("p_a.elbow", "p_b.elbow"))
    if np.max(np.abs(rec["q.elbow"])) > 2.0:
        raise RecordingError(f"{rec.source}: column q.elbow reaches {np.max(np.abs(rec['q.elbow'])):.4g}; the vane "
                             "travels ±1.65 rad: degrees? (rad expected)")


def to_trace(rec: Recording) -> Trace:
    return make_trace(rec.time, rec["i.elbow"], rec["q.elbow"], rec["p_a.elbow"], rec["p_b.elbow"],
                      rec.columns.get("tau.elbow"), source=rec.source, braced=bool(rec.meta.get("braced", False)))


def load_traces(model: str, recordings, holdouts=(), holdout_fraction: float = HOLDOUT):
    """(cfg, fitted traces, held-out traces, source names): the held-out files, or the last
    ``holdout_fraction`` of each recording.  Every trace has a torque column, or none has."""
    if not recordings:
        raise RecordingError("hydraulic doctor: no recordings given")
    cfg = load_model_cfg(model)
    for r in [*recordings, *holdouts]:
        check(r, model, cfg)
    with_tau = {r.source: "tau.elbow" in r for r in [*recordings, *holdouts]}
    if len(set(with_tau.values())) > 1:
        raise RecordingError(f"hydraulic doctor: column tau.elbow is in some recordings and not in others "
                             f"({', '.join(f'{k}: {v}' for k, v in with_tau.items())}); give it in all or none")
    if holdouts:
        train, held = list(recordings), list(holdouts)
        braced_train = any(r.meta.get("braced", False) for r in train)
        braced_held = any(r.meta.get("braced", False) for r in held)
        if braced_train != braced_held:
            which = "fitted" if braced_train else "held-out"
            named = ", ".join(r.source for r in [*train, *held] if r.meta.get("braced"))
            raise RecordingError(f"hydraulic doctor: a braced recording (sidecar \"braced\": true) is among the "
                                 f"{which} recordings only ({named}); give one to fit and one to hold out, or none")
    else:
        if not 0.05 <= holdout_fraction <= 0.8:
            raise RecordingError(f"hydraulic doctor: holdout_fraction = {holdout_fraction}; expected 0.05-0.8")
        train, held = [], []
        for r in recordings:
            tc = r.time[0] + (1.0 - holdout_fraction) * (r.time[-1] - r.time[0])
            train.append(r.slice(r.time[0], tc))
            held.append(r.slice(tc, r.time[-1] + 1.0))
    return cfg, [to_trace(r) for r in train], [to_trace(r) for r in held], [r.source for r in [*recordings, *holdouts]]
