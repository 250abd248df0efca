"""Recordings of the SARCOS hydraulic elbow with hidden physics, made by pneumasim's hydraulic
simulator: the cases of scenarios/doctor_benchmark_sarcos.py.

A case = a seed -> no effect, one, or two of different families of
pneumatics/hydraulics/effects.py (family, place and magnitude drawn), +-3 % errors in the
nominal parameters the doctor calibrates (the valve's port width, the forearm's mass: its
weight moment, and its inertia, which the doctor does not calibrate), sensor noise of fluid.toml's ``[sensors]``; the free forearm under a
proportional position loop on the vane angle (4 A/rad at 1 kHz) tracking a random reference
(three sines of 0.05-0.3 Hz on smoothed random steps, within +-1 rad; it starts away from
the hanging pose, so the arm moves from the first second); a recording to fit and
a different held-out one, sampled at 1 kHz; and, as paper 001 §3.2.2 identifies the elbow,
a braced recording of each (the load locked by the steel brace, open-loop currents of three
sines; sidecar ``"braced": true``), where the pressures show the chambers' volumes and the
angle and torque the shaft's stiffness.  **Concealed**: the effects are halved (together)
until the nominal model without them (true parameters) keeps a held-out R^2 >= 0.9 on every
pressure channel (restarted oil replays, free and braced) and on the hydraulic torque (D_v P_L
against the rigid-body equation).  The doctor sees only the CSV files; the truth is written beside them.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from identification.doctor.hydraulic.replay import make_trace, replay_oil
from pneumatics.errors import UnknownNameError
from pneumatics.hydraulics.effects import HydraulicEffects, add_sensor_offsets, build_sim
from pneumatics.hydraulics.runner import run_measured
from pneumatics.io import atomic_write_json

PARAM_ERROR = 0.03
R2_CONCEALED = 0.9
KP_A_PER_RAD = 4.0
RATE_HZ = 1000.0

_sign = lambda r: float(r.choice([-1, 1]))  # noqa: E731
JOINT, ACT = {"joint": "elbow"}, {"actuator": "elbow"}
#: family -> list of (HydraulicEffects field, where, draw(rng) -> SI value)
FAMILIES = {
    "valve_hysteresis": [("hysteresis_extra_k0_a", ACT, lambda r: r.uniform(0.03, 0.06))],
    "valve_null_shift": [("null_shift_a", ACT, lambda r: _sign(r) * r.uniform(0.015, 0.03))],
    "valve_leak": [("valve_leak_m3_per_pa_s", ACT, lambda r: r.uniform(1.5e-13, 4e-13))],
    "piston_leak": [("vane_leak_m3_per_pa_s", ACT, lambda r: r.uniform(3e-13, 8e-13))],
    "line_dynamics": [("line_volume_extra_a_m3", {"actuator": "elbow", "chamber": "a"}, lambda r: r.uniform(4e-6, 1e-5)),
                      ("line_volume_extra_b_m3", {"actuator": "elbow", "chamber": "b"}, lambda r: r.uniform(4e-6, 1e-5))],
    "supply_droop": [("pump_droop_pa_s_per_m3", {"supply": "all"}, lambda r: r.uniform(1e11, 3e11))],
    "coulomb_friction": [("coulomb_extra_nm", JOINT, lambda r: r.uniform(0.5, 1.2))],
    "viscous_friction": [("viscous_extra_nm_s_per_rad", JOINT, lambda r: r.uniform(1.0, 3.0))],
    "shaft_compliance": [("shaft_compliance_extra_rad_per_nm", {"joint": "shaft"}, lambda r: r.uniform(5e-5, 1.2e-4))],
    "pressure_sensor_offset": [
        ("pressure_sensor_offset_a_pa", {"actuator": "elbow", "chamber": "a"}, lambda r: _sign(r) * r.uniform(6e4, 1.5e5)),
        ("pressure_sensor_offset_b_pa", {"actuator": "elbow", "chamber": "b"}, lambda r: _sign(r) * r.uniform(6e4, 1.5e5))],
    "angle_sensor_offset": [("angle_sensor_offset_rad", JOINT, lambda r: _sign(r) * r.uniform(0.05, 0.1))],
    "force_sensor_offset": [("torque_sensor_offset_nm", JOINT, lambda r: _sign(r) * r.uniform(0.4, 1.0))],
}


def perturbed(rng) -> tuple:
    """(fluid cfg, load mass factor): the 'true' elbow, each calibrated parameter off by up to +-3 %."""
    import models
    from pneumatics.hydraulics.config import load_hydraulic_cfg

    f = lambda: float(1 + rng.uniform(-PARAM_ERROR, PARAM_ERROR))  # noqa: E731
    cfg = load_hydraulic_cfg(models.fluid_path("sarcos_elbow"))
    cfg = dataclasses.replace(cfg, servovalve=dataclasses.replace(cfg.servovalve, port_width_m=cfg.servovalve.port_width_m * f()))
    return cfg, f()


def reference(rng, seconds: float):
    """theta_ref(t) [rad]: smoothed random steps (every 2-5 s, 0.2 s smoothing) plus three sines."""
    times, levels, t = [0.0], [0.0], 0.0
    while t < seconds + 5:
        t += rng.uniform(2.0, 5.0)
        times.append(t)
        levels.append(rng.uniform(-0.5, 0.5))
    times, levels = np.array(times), np.array(levels)
    freqs, amps, phases = rng.uniform(0.05, 0.3, 3), rng.uniform(0.1, 0.25, 3), rng.uniform(0, 2 * np.pi, 3)

    def ref(time_s: float) -> float:
        k = int(np.searchsorted(times, time_s, side="right")) - 1
        level = levels[k] + (levels[k - 1] - levels[k]) * math.exp(-(time_s - times[k]) / 0.2) if k > 0 else levels[0]
        return float(np.clip(level + np.sum(amps * np.sin(2 * np.pi * freqs * time_s + phases)),
                             -1.0, 1.0))
    return ref


def true_elbow(cfg, mass_factor: float, fx: HydraulicEffects = HydraulicEffects()):
    """The true elbow: fluid ``cfg``, the load's mass and inertia scaled by ``mass_factor``, effects ``fx``."""
    sim = build_sim(fx, cfg=cfg)
    load = sim.model.body("load").id
    sim.model.body_mass[load] *= mass_factor
    sim.model.body_inertia[load] *= mass_factor
    return sim


def record(cfg, mass_factor: float, fx: HydraulicEffects, rng, seconds: float, name: str):
    """One noisy closed-loop recording of the true elbow with effects ``fx``."""
    sim = true_elbow(cfg, mass_factor, fx)
    sim.reset()
    ref = reference(rng, seconds)
    rec = run_measured(sim, lambda t: KP_A_PER_RAD * (ref(t) - sim.vane_angle), seconds, rate_hz=RATE_HZ,
                       rng=rng, name=name)
    return add_sensor_offsets(rec, fx)


def braced_currents(rng):
    """i(t) [A] for a braced recording: three sines of 0.02-0.08 A at 0.3-3 Hz (the pressures
    stay well inside the supply and the tank; paper 001 §4 drives the braced elbow with sines)."""
    amps, freqs, phases = rng.uniform(0.02, 0.08, 3), rng.uniform(0.3, 3.0, 3), rng.uniform(0, 2 * np.pi, 3)
    return lambda t: float(np.sum(amps * np.sin(2 * np.pi * freqs * t + phases)))


def record_braced(cfg, mass_factor: float, fx: HydraulicEffects, rng, seconds: float, name: str):
    """One noisy braced recording of the true elbow with effects ``fx`` (sidecar "braced": true)."""
    sim = true_elbow(cfg, mass_factor, fx)
    sim.reset(braced=True)
    rec = run_measured(sim, braced_currents(rng), seconds, rate_hz=RATE_HZ, rng=rng, name=name)
    return add_sensor_offsets(rec, fx)


def r2_braced(rec, cfg, mech) -> dict:
    """Held-out R^2 of the model without the effects on a braced recording's chamber pressures."""
    tr = make_trace(rec.time, rec["i.elbow"], rec["q.elbow"], rec["p_a.elbow"], rec["p_b.elbow"], rec["tau.elbow"],
                    braced=True)
    pred = replay_oil(tr, cfg, HydraulicEffects(), shaft_compliance_rad_per_nm=1.0 / mech.k_s)
    return {f"braced_{c}": r2 for c, r2 in _pressure_r2(tr, pred).items()}


def _pressure_r2(tr, pred) -> dict:
    """R^2 of each chamber pressure of trace ``tr`` against the replay ``pred``, scored samples."""
    m = tr.scored
    return {c: float(1 - np.mean((getattr(tr, c) - pred[c])[m] ** 2) / np.var(getattr(tr, c)[m])) for c in ("p_a", "p_b")}


def r2_nominal(rec, cfg, mech) -> dict:
    """Held-out R^2 of the model without the effects (true parameters): the restarted oil replay
    per chamber, the rigid-body equation for the hydraulic torque."""
    from identification.doctor.hydraulic.mechanics import channel_masks, equation_errors

    tr = make_trace(rec.time, rec["i.elbow"], rec["q.elbow"], rec["p_a.elbow"], rec["p_b.elbow"], rec["tau.elbow"])
    out = _pressure_r2(tr, replay_oil(tr, cfg, HydraulicEffects()))
    tr.torque = None
    e = equation_errors(tr, mech, HydraulicEffects())["rigid"]
    mk = channel_masks(tr, ["rigid"])["rigid"]
    hyd = mech.d_v * (tr.p_a - tr.p_b)
    out["torque"] = float(1 - np.mean(e[mk] ** 2) / np.var(hyd[mk]))
    return out


def make_case(folder: Path, seed: int, family, seconds: float = 20.0, heldout_seconds: float = 10.0,
              braced_seconds: float = 0.0, braced_heldout_seconds: float = 0.0) -> dict:
    """Write ``main.csv``, ``heldout.csv`` (and, with ``braced_seconds`` > 0, ``main_braced.csv``
    and ``heldout_braced.csv``) and ``truth.json`` into ``folder``; returns the truth.

    ``family``: None (a null case), one family name, or a list of families."""
    from identification.doctor.hydraulic.mechanics import from_model

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    families = [] if family is None else [family] if isinstance(family, str) else list(family)
    for f in families:
        if f not in FAMILIES:
            raise UnknownNameError("hydraulic effect family", f, FAMILIES)
    if len(set(families)) != len(families):
        raise ValueError(f"hydraulic case: families {families} repeat; one effect per family")
    rng = np.random.default_rng(seed)
    cfg, mass = perturbed(rng)
    drawn = []
    for fam in families:
        field, where, draw = FAMILIES[fam][int(rng.integers(0, len(FAMILIES[fam])))]
        drawn.append((fam, field, where, float(draw(rng))))
    mech = from_model(true_elbow(cfg, mass), cfg.vane.displacement_m3_per_rad)
    scale, fx = 1.0, HydraulicEffects()
    for _ in range(6 if drawn else 1):  # conceal: halve until the model without them keeps R^2 >= 0.9
        fx = HydraulicEffects(**{field: v * scale for _, field, _, v in drawn})
        held = record(cfg, mass, fx, np.random.default_rng(seed + 1), heldout_seconds, "heldout")
        r2 = r2_nominal(held, cfg, mech)
        if braced_seconds > 0:
            held_braced = record_braced(cfg, mass, fx, np.random.default_rng(seed + 3), braced_heldout_seconds,
                                        "heldout_braced")
            r2.update(r2_braced(held_braced, cfg, mech))
        if min(r2.values()) >= R2_CONCEALED:
            break
        scale *= 0.5
    effects = [{"family": fam, "where": where, "parameters": {field: v * scale}} for fam, field, where, v in drawn]
    main = record(cfg, mass, fx, np.random.default_rng(seed + 2), seconds, "main")
    main.to_csv(folder / "main.csv")
    held.to_csv(folder / "heldout.csv")
    recordings = {"main": str(folder / "main.csv"), "heldout": str(folder / "heldout.csv")}
    if braced_seconds > 0:
        record_braced(cfg, mass, fx, np.random.default_rng(seed + 4), braced_seconds, "main_braced").to_csv(
            folder / "main_braced.csv")
        held_braced.to_csv(folder / "heldout_braced.csv")
        recordings.update(main_braced=str(folder / "main_braced.csv"),
                          heldout_braced=str(folder / "heldout_braced.csv"))
    truth = {"seed": seed, "families": families or ["none"], "effects": effects, "r2_nominal_heldout": r2,
             "parameter_errors": {"port_width_m": cfg.servovalve.port_width_m,
                                  "load_mass_factor": mass},
             "recordings": recordings}
    atomic_write_json(folder / "truth.json", truth)
    return truth
