"""Recordings of the jet-pipe actuator with hidden physics, made by pneumasim itself: the jet-pipe
doctor's blind cases (scenarios/doctor_blind_benchmark_jetpipe.py).

A case = a seed -> no effect, one, or a few of different families of
pneumatics/jetpipe/effects.py (family, place and magnitude drawn), +-3 % errors in the nominal
parameters the doctor calibrates (C_d, both dead volumes, the jet offset), sensor noise; the actuator on its stopper under the
feedforward + proportional force controller (controllers/force.py, k_p = 20, 1 kHz) tracking a
random reference (a sum of sines on smoothed random steps within 15-60 N); a recording to fit
and a different held-out one.  **Concealed**: the effects are halved (together) until the nominal
model without them (true parameters) still reaches held-out R^2 >= 0.9 on every channel with restarted
replays.  The doctor sees only the CSV files; the truth is written beside them.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from controllers.force import ForceCfg
from identification.doctor.jetpipe.replay import make_trace, measured, replay
from pneumatics.effects.registry import families_of, get_family
from pneumatics.errors import PneumasimError, UnknownNameError
from pneumatics.io import atomic_write_json
from pneumatics.jetpipe.effects import JetpipeEffects
from pneumatics.jetpipe.sim import JetpipeSim, build
from pneumatics.jetpipe.statics import static_curve

PARAM_ERROR = 0.03
#: sensor noise, 1 sigma: pressure transducers, load cell, current shunt, jet PSD
NOISE = {"p_a.piston": 300.0, "p_b.piston": 300.0, "force.piston": 0.05, "i.piston": 1e-4, "x_jet.piston": 1e-6}
R2_CONCEALED = 0.9

#: family -> list of (JetpipeEffects field, where, draw(rng) -> SI value).  The jet-pipe plant keeps
#: its own effect models (pneumatics/jetpipe/effects.py); its family names are the registry's
#: (pneumatics/effects/registry.py, families whose ``plants`` include "jetpipe": checked below)
FAMILIES = {
    "pressure_sensor_offset": [
        ("pressure_sensor_offset_a_pa", {"actuator": "piston", "chamber": "a"}, lambda r: r.choice([-1, 1]) * r.uniform(5e3, 1.5e4)),
        ("pressure_sensor_offset_b_pa", {"actuator": "piston", "chamber": "b"}, lambda r: r.choice([-1, 1]) * r.uniform(5e3, 1.5e4))],
    "force_sensor_offset": [("force_sensor_offset_n", {"actuator": "piston"}, lambda r: r.choice([-1, 1]) * r.uniform(1.0, 3.0))],
    "external_leak": [("external_leak_a_m2", {"actuator": "piston", "chamber": "a"}, lambda r: r.uniform(1e-8, 3e-8)),
                      ("external_leak_b_m2", {"actuator": "piston", "chamber": "b"}, lambda r: r.uniform(1e-8, 3e-8))],
    "piston_leak": [("piston_leak_m2", {"actuator": "piston"}, lambda r: r.uniform(5e-8, 1.5e-7))],
    "valve_lag": [("valve_lag_s", {"actuator": "piston"}, lambda r: r.uniform(2e-3, 6e-3))],
    "supply_droop": [("supply_droop_pa_per_kg_s", {"supply": "all"}, lambda r: r.uniform(3e7, 8e7))],
    "valve_hysteresis": [("hysteresis_extra_half_width_m", {"actuator": "piston"},
                          lambda r: r.choice([-1, 1]) * r.uniform(3e-5, 6e-5))],
}

_unregistered = [f for f in FAMILIES if "jetpipe" not in get_family(f).plants]
if _unregistered:
    raise PneumasimError(f"jet-pipe case maker: families {_unregistered} are not registered for the jet-pipe plant "
                         f"(pneumatics/effects/registry.py: {[f.name for f in families_of('jetpipe')]})")


def perturbed_cfg(cfg, rng):
    """The 'true' bench: the nominal parameters the doctor calibrates, each off by up to +-3 %."""
    f = lambda: float(1 + rng.uniform(-PARAM_ERROR, PARAM_ERROR))
    cfg = cfg.replace("ports", discharge_coefficient=cfg.ports.discharge_coefficient * f())
    cfg = cfg.replace("cylinder", dead_volume_1_m3=cfg.cylinder.dead_volume_1_m3 * f(),
                      dead_volume_2_m3=cfg.cylinder.dead_volume_2_m3 * f())
    return cfg.replace("jet", offset_m=cfg.jet.offset_m * f())


def reference(rng, seconds: float):
    """F_d(t) [N]: smoothed random steps (every 1-3 s, 50 ms first-order smoothing) plus three
    sines of 0.2-3 Hz, clipped to 15-60 N (piston stays on the stopper, jet inside its range)."""
    times, levels, t = [0.0], [rng.uniform(25, 50)], 0.0
    while t < seconds + 5:
        t += rng.uniform(1.0, 3.0)
        times.append(t)
        levels.append(rng.uniform(22, 52))
    times, levels = np.array(times), np.array(levels)
    freqs, amps, phases = rng.uniform(0.2, 3.0, 3), rng.uniform(1.0, 4.0, 3), rng.uniform(0, 2 * np.pi, 3)
    tau = 0.05

    def fd(time_s: float) -> float:
        k = int(np.searchsorted(times, time_s, side="right")) - 1
        level = levels[k]
        if k > 0:  # the step from levels[k-1] decays with tau
            level = levels[k] + (levels[k - 1] - levels[k]) * math.exp(-(time_s - times[k]) / tau)
        v = level + float(np.sum(amps * np.sin(2 * np.pi * freqs * time_s + phases)))
        return min(max(v, 15.0), 60.0)
    return fd


def record(cfg, fx: JetpipeEffects, rng, seconds: float):
    """One noisy closed-loop recording of the true bench with effects ``fx``."""
    sim = JetpipeSim(build(cfg), effects=fx)
    nominal_curve = static_curve(build().cfg)  # the controller knows the nominal model only
    ref = reference(rng, seconds)
    ctl = ForceCfg(kp=20.0, static_gain_n_per_a=nominal_curve.slope_n_per_a(40.0)).build(ref, nominal_curve.inverse)
    sim.reset(ref(0.0))
    rec = sim.run(ctl, seconds, record_hz=1000.0)
    for c, s in NOISE.items():
        rec.columns[c] = rec.columns[c] + rng.normal(0.0, s, rec.time.size)
    rec.meta.pop("generator", None)
    return rec


def r2_nominal(rec, cfg) -> dict:
    """Held-out R^2 per channel of the model without the effect (true parameters), restarted replays."""
    tr = make_trace(rec.time, rec["i_cmd.piston"], rec["p_a.piston"], rec["p_b.piston"], rec["force.piston"],
                    rec["x_jet.piston"], float(np.median(rec["q.piston"])), float(rec["i.piston"][0]))
    pred, meas = replay(tr, cfg, JetpipeEffects()), measured(tr)
    m = tr.scored
    return {c: float(1 - np.mean((meas[c] - pred[c])[m] ** 2) / np.var(meas[c][m])) for c in meas}


def make_case(folder: Path, seed: int, family, seconds: float = 30.0, heldout_seconds: float = 15.0) -> dict:
    """Write ``main.csv``, ``heldout.csv`` and ``truth.json`` into ``folder``; returns the truth.

    ``family``: None (a null case), one family name, or a list of families (one place and
    magnitude drawn for each; with two, all are halved together until concealed)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    families = [] if family is None else [family] if isinstance(family, str) else list(family)
    for f in families:
        if f not in FAMILIES:
            raise UnknownNameError("jet-pipe effect family", f, FAMILIES)
    if len(set(families)) != len(families):
        raise ValueError(f"jet-pipe case: families {families} repeat; one effect per family")
    rng = np.random.default_rng(seed)
    cfg = perturbed_cfg(build().cfg, rng)
    drawn = []
    for fam in families:
        places = FAMILIES[fam]
        field, where, draw = places[int(rng.integers(0, len(places)))]
        drawn.append((fam, field, where, float(draw(rng))))
    scale, fx = 1.0, JetpipeEffects()
    for _ in range(8 if drawn else 1):  # conceal: halve until the model without them keeps R^2 >= 0.9
        fx = dataclasses.replace(JetpipeEffects(), **{field: v * scale for _, field, _, v in drawn})
        held = record(cfg, fx, np.random.default_rng(seed + 1), heldout_seconds)
        r2 = r2_nominal(held, cfg)
        if min(r2.values()) >= R2_CONCEALED:
            break
        scale *= 0.5
    effects = [{"family": fam, "where": where, "parameters": {field: v * scale}, "r2_nominal": r2}
               for fam, field, where, v in drawn]
    main = record(cfg, fx, np.random.default_rng(seed + 2), seconds)
    main.to_csv(folder / "main.csv")
    held.to_csv(folder / "heldout.csv")
    truth = {"seed": seed, "families": families or ["none"], "effects": effects, "r2_nominal_heldout": r2,
             "parameter_errors": {"discharge_coefficient": cfg.ports.discharge_coefficient,
                                  "dead_volume_1_m3": cfg.cylinder.dead_volume_1_m3,
                                  "dead_volume_2_m3": cfg.cylinder.dead_volume_2_m3, "jet_offset_m": cfg.jet.offset_m},
             "recordings": {"main": str(folder / "main.csv"), "heldout": str(folder / "heldout.csv")}}
    atomic_write_json(folder / "truth.json", truth)
    return truth
