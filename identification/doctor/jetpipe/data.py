"""Read and check jet-pipe recordings for the doctor, and split off the held-out part.

Columns (what ``JetpipeSim.run`` writes, DESIGN.md names; extra columns are ignored)::

    time            s, strictly increasing
    p_a.piston      chamber-1 pressure, Pa absolute        (required)
    p_b.piston      chamber-2 pressure, Pa absolute        (required)
    force.piston    rod force sensor, N                    (required)
    i_cmd.piston    current command, A  -- or i.piston, the measured coil current (one required)
    q.piston        piston position (chamber-1 length), m  (optional; default: on the stopper)
    x_jet.piston    jet position sensor, m                 (optional; a fourth channel)
"""
from __future__ import annotations

import numpy as np

import models
from pneumatics.errors import RecordingError
from pneumatics.jetpipe.params import JetpipeCfg, load_jetpipe_cfg
from pneumatics.recording import Recording
from pneumatics.recording_checks import check_pressures

from .replay import BURN_IN_S, Trace, make_trace

HOLDOUT = 0.3             # share of each recording held out (its end) without held-out files
MAX_PISTON_TRAVEL_M = 5e-4  # the replay holds the piston still: it must stay on the stopper
REQUIRED = ("p_a.piston", "p_b.piston", "force.piston")


def load_model_cfg(model: str) -> JetpipeCfg:
    kind = models.model_kind(model)
    if kind != "jetpipe":
        raise RecordingError(f"jet-pipe doctor: model {model!r} is of kind {kind!r}, not 'jetpipe'")
    return load_jetpipe_cfg(models.folder(model) / "fluid.toml")


def check(rec: Recording, model: str, cfg: JetpipeCfg):
    """Raise a :class:`RecordingError` naming the file and column for anything the doctor cannot use."""
    if rec.meta.get("model") not in (None, model):
        raise RecordingError(f"{rec.source}: recorded for model {rec.meta['model']!r} (sidecar), diagnosed as {model!r}")
    missing = [c for c in REQUIRED if c not in rec]
    if "i_cmd.piston" not in rec and "i.piston" not in rec:
        missing.append("i_cmd.piston (or i.piston)")
    if missing:
        raise RecordingError(f"{rec.source}: missing column(s) {', '.join(missing)}; a jet-pipe recording needs "
                             f"time, p_a.piston, p_b.piston [Pa abs], force.piston [N] and i_cmd.piston or i.piston [A]")
    t = rec.time
    if t.size < 50 or t[-1] - t[0] < 5 * BURN_IN_S:
        raise RecordingError(f"{rec.source}: {t.size} rows over {t[-1] - t[0]:.3g} s; need at least 50 rows and "
                             f"{5 * BURN_IN_S:g} s")
    for c in [*REQUIRED, "i_cmd.piston", "i.piston", "q.piston", "x_jet.piston"]:
        if c in rec and not np.all(np.isfinite(rec[c])):
            row = int(np.argmin(np.isfinite(rec[c])))
            raise RecordingError(f"{rec.source}: column {c} row {row + 1}: not a finite number")
    # the chambers vent to the room and are fed from the supply: gauge values or another unit
    check_pressures(rec, cfg.supply.room_pa, cfg.supply.supply_pa, ("p_a.piston", "p_b.piston"))
    if "q.piston" in rec and np.ptp(rec["q.piston"]) > MAX_PISTON_TRAVEL_M:
        raise RecordingError(f"{rec.source}: column q.piston moves {1e3 * np.ptp(rec['q.piston']):.2f} mm; the "
                             f"jet-pipe doctor handles the stopper bench (piston held, <= {1e3 * MAX_PISTON_TRAVEL_M:g} mm)")


def to_trace(rec: Recording, cfg: JetpipeCfg) -> Trace:
    cmd = rec["i_cmd.piston"] if "i_cmd.piston" in rec else rec["i.piston"]
    q = float(np.median(rec["q.piston"])) if "q.piston" in rec else cfg.cylinder.chamber1_length_m
    jet = rec.columns.get("x_jet.piston")  # optional channel
    i0 = float(rec["i.piston"][0]) if "i.piston" in rec else None  # the driver's state at the start
    return make_trace(rec.time, cmd, rec["p_a.piston"], rec["p_b.piston"], rec["force.piston"], jet, q, i0)


def load_traces(model: str, recordings, holdouts=(), holdout_fraction: float = HOLDOUT):
    """(cfg, fitted traces, held-out traces, source names): the held-out files, or the last
    ``holdout_fraction`` of each recording."""
    if not recordings:
        raise RecordingError("jet-pipe doctor: no recordings given")
    cfg = load_model_cfg(model)
    for r in [*recordings, *holdouts]:
        check(r, model, cfg)
    if holdouts:
        train, held = list(recordings), list(holdouts)
    else:
        if not 0.05 <= holdout_fraction <= 0.8:
            raise RecordingError(f"jet-pipe doctor: holdout_fraction = {holdout_fraction}; expected 0.05-0.8")
        train, held = [], []
        for r in recordings:
            tc = r.time[0] + (1.0 - holdout_fraction) * (r.time[-1] - r.time[0])
            train.append(r.slice(r.time[0], tc))
            held.append(r.slice(tc, r.time[-1] + 1.0))
    return cfg, [to_trace(r, cfg) for r in train], [to_trace(r, cfg) for r in held], \
        [r.source for r in [*recordings, *holdouts]]
