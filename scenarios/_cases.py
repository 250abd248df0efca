"""Recordings of arm2 with hidden physics, made by pneumasim itself: the doctor's test cases.

A case = a seed, at most a couple of effects (family, place, parameters), small errors in the
nominal parameters (valve areas, dead volumes, link masses) and sensor noise; arm2 tracks a
hand-moved reference under PIDF; a 60 s recording to fit and a different 30 s one held out.
The doctor sees only the CSV files; the truth is written beside them.
"""
from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path

import numpy as np

from controllers.pid import ARM2_PIDF
from controllers.reference import hand_moved
from pneumatics.effects.effect_set import EffectSet
from pneumatics.effects.family import Family, where_of
from pneumatics.effects.registry import families_of, get_family
from pneumatics.io import atomic_write_json
from pneumatics.robot import load_robot
from pneumatics.runner import run
from pneumatics.sim import Simulation

CHAMBERS = ["shoulder.a", "shoulder.b", "elbow.a", "elbow.b"]
JOINTS = ["shoulder", "elbow"]

#: the families the case makers draw: every family of the arm simulator in the registry
#: (pneumatics/effects/registry.py: places, parameter ranges and EffectSet entries live there).
#: The first ones keep the order in which the blind benchmark assigned its seeds (seed 1000 + 3 i
#: for the i-th), so its cases stay the same; families added later follow in registry order.
_SEEDED_ORDER = ("coulomb_friction", "stiction", "viscous_friction", "valve_hysteresis", "valve_leak",
                 "external_leak", "piston_leak", "pressure_sensor_offset", "angle_sensor_offset", "supply_droop",
                 "valve_lag", "line_dynamics", "heat_transfer", "backlash", "end_stop")
_ARM = [f.name for f in families_of("valve_arm")]
FAMILIES = [n for n in _SEEDED_ORDER if n in _ARM] + [n for n in _ARM if n not in _SEEDED_ORDER]

#: the families the blind benchmark hides.  end_stop is left out: it cannot be concealed.  A
#: bumper the arm touches stops the arm where the model without it lets the joint run on, so
#: the restarted replays miss it by far (seed 2001: held-out R^2 0.41 after five halvings of
#: the intrusion); one it does not touch is no effect.  The doctor's end-stop hypothesis is
#: tested on unconcealed recordings instead (tests/test_doctor_new_effects.py).
BENCHMARK_FAMILIES = [f for f in FAMILIES if get_family(f).benchmark_ok]

_PLACES = {"joint": JOINTS, "chamber": CHAMBERS, "actuator": JOINTS, "supply": ["all"]}


def draw(family: str, rng: np.random.Generator) -> tuple[Family, str, object]:
    """One hidden effect of ``family``: (its family, a place, parameters from the family's ranges)."""
    fam = get_family(family)
    places = _PLACES[fam.place_kind]
    place = places[rng.integers(0, len(places))]
    return fam, place, fam.draw(rng)


def effects_of(drawn: list, k: float = 1.0) -> EffectSet:
    """The drawn effects [(family, place, parameters)] with every magnitude times k (Family.scaled:
    shapes such as Stribeck velocities keep their value, an end stop moves out towards the
    reference margin instead, beyond which the arm never goes)."""
    out = EffectSet()
    for fam, place, params in drawn:
        fam.add_to(out, place, fam.scaled(params, k))
    return out


def truth_of(drawn_effect, k: float = 1.0) -> dict:
    """The truth.json entry of one drawn effect at scale k: family, where, EffectSet parameters."""
    fam, place, params = drawn_effect
    return {"family": fam.name, "where": where_of(fam.place_kind, place),
            "parameters": _plain(fam.effect_set_entry(fam.scaled(params, k))), "scale": k}


def draw_effect(family: str, rng: np.random.Generator) -> tuple[dict, EffectSet]:
    """One hidden effect of ``family``: its truth entry (without scale) and an EffectSet holding it."""
    fam, place, params = draw(family, rng)
    effects = EffectSet()
    fam.add_to(effects, place, params)
    return {"family": family, "where": where_of(fam.place_kind, place),
            "parameters": _plain(fam.effect_set_entry(params))}, effects


def perturbed_valves(robot, f):
    """``robot`` with each valve's supply and exhaust area and each chamber's dead volume
    multiplied by a factor ``f()`` (drawn in actuator order: a's areas, b's, the dead volumes)."""
    acts = []
    for a in robot.fluid.actuators:
        va = dataclasses.replace(a.valve_a, supply_area_max_m2=a.valve_a.supply_area_max_m2 * f(),
                                 exhaust_area_max_m2=a.valve_a.exhaust_area_max_m2 * f())
        vb = dataclasses.replace(a.valve_b, supply_area_max_m2=a.valve_b.supply_area_max_m2 * f(),
                                 exhaust_area_max_m2=a.valve_b.exhaust_area_max_m2 * f())
        acts.append(dataclasses.replace(a, valve_a=va, valve_b=vb, dead_volume_a_m3=a.dead_volume_a_m3 * f(),
                                        dead_volume_b_m3=a.dead_volume_b_m3 * f()))
    return robot.with_fluid(dataclasses.replace(robot.fluid, actuators=tuple(acts)))


def perturbed_robot(rng: np.random.Generator, fraction: float):
    """arm2 with each valve area, dead volume and link mass off by up to +-fraction."""
    robot = load_robot("arm2")
    f = lambda: float(1 + rng.uniform(-fraction, fraction))  # noqa: E731
    factors = {}
    robot = perturbed_valves(robot, f)
    for b in ("upper_link", "forearm"):
        s = f()
        factors[f"mass_and_inertia.{b}"] = s
        i = robot.model.body(b).id
        robot.model.body_mass[i] *= s
        robot.model.body_inertia[i] *= s
    return robot, factors


def concealment_r2(robot, rec) -> dict:
    """Held-out R^2 per channel of the true model *without* the effects (coupled replays
    restarted every second): >= 0.9 everywhere means aggregate statistics hide the effect."""
    from identification.doctor.valve_arm.data import prepare
    from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
    from identification.doctor.valve_arm.replay import MechMods, coupled_replay

    exp = prepare(robot, rec)
    return coupled_replay(exp, PneumaticMods.nominal(robot.tables.n_chambers), MechMods()).r2()


def make_case(out: Path, seed: int, families: list[str], *, fraction: float = 0.03, seconds: float = 60.0,
              heldout_seconds: float = 30.0, name: str | None = None, conceal: bool = True) -> dict:
    """Write <name>.csv, <name>_heldout.csv and <name>.truth.json into ``out``; return the truth.

    With ``conceal`` the effects are halved (up to 4 times) until the true model without them
    still reaches R^2 >= 0.9 on every channel of the held-out recording."""
    rng = np.random.default_rng(seed)
    name = name or f"case_{seed}"
    drawn = [draw(fam, rng) for fam in families]
    robot, factors = perturbed_robot(rng, fraction)
    scale, history = 1.0, []
    for _ in range(5):
        effects = effects_of(drawn, scale)
        recs = _record(robot, effects, seed, seconds, heldout_seconds)
        r2 = concealment_r2(robot, recs["heldout"]) if (conceal and families) else {}
        history.append({"scale": scale, "min_r2": min(r2.values()) if r2 else None})
        if not r2 or min(r2.values()) >= 0.9:
            break
        scale *= 0.5
    truths = [truth_of(d, scale) for d in drawn]
    paths = _write(out, name, recs)
    truth = {"case": name, "seed": seed, "effects": truths, "families": families or ["none"],
             "parameter_factors": factors, "perturbation_fraction": fraction, "recordings": paths,
             "concealment": {"history": history, "r2_per_channel": r2 if families else {}}}
    atomic_write_json(Path(out) / f"{name}.truth.json", truth)
    return truth


def _write(out, name: str, recs: dict) -> dict:
    """<name>.csv and <name>_heldout.csv in ``out``; their paths by part."""
    paths = {}
    for part, rec in recs.items():
        path = Path(out) / f"{name}{'' if part == 'main' else '_heldout'}.csv"
        rec.to_csv(path)
        paths[part] = str(path)
    return paths


def _record(robot, effects, seed, seconds, heldout_seconds) -> dict:
    recs = {}
    for part, dur, s in (("main", seconds, 2 * seed + 1), ("heldout", heldout_seconds, 2 * seed + 2)):
        ref = hand_moved(robot.joint_names, robot.joint_range(), dur, seed=s)
        sim = Simulation(robot, effects=effects)
        sim.reset(qpos=ref.reference(0.0), pressure_pa=4.5e5)
        warm = ARM2_PIDF.build(ref, robot.tables.valve[:, 0])
        run(sim, warm, 1.0, seed=s)  # pre-roll: pressures settle under control
        sim.data.time = 0.0
        rec = run(sim, ARM2_PIDF.build(ref, robot.tables.valve[:, 0]), dur, seed=s + 7)
        rec.meta = {"model": "arm2", "rate_hz": 100.0, "daq_averaging": True}
        recs[part] = rec
    return recs


def _plain(d):
    return json.loads(json.dumps(d, default=float))


def make_spring_case(out: Path, seed: int, joint: str, stiffness_nm_per_rad: float, rest_rad: float = 0.3,
                     seconds: float = 60.0, heldout_seconds: float = 30.0) -> dict:
    """A case whose hidden physics is *outside* the effect library: a torsion spring on one
    joint (a hose or cable pulling on the link), torque -k (q - rest_rad), MuJoCo's own joint
    stiffness.  Halved (up to five times) until the model without it keeps held-out R^2 >= 0.9
    on every channel.  The doctor should report it as unexplained at that joint, not name a
    library effect that only takes up part of it (an angle offset takes up its preload)."""
    rng = np.random.default_rng(seed)
    robot, factors = perturbed_robot(rng, 0.03)
    jid = robot.model.joint(joint).id
    k, history = stiffness_nm_per_rad, []
    for _ in range(6):
        sprung = dataclasses.replace(robot, model=copy.copy(robot.model))
        sprung.model.jnt_stiffness[jid] = k
        sprung.model.qpos_spring[robot.model.jnt_qposadr[jid]] = rest_rad
        recs = _record(sprung, EffectSet(), seed, seconds, heldout_seconds)
        r2 = concealment_r2(robot, recs["heldout"])
        history.append({"stiffness_nm_per_rad": k, "min_r2": min(r2.values())})
        if min(r2.values()) >= 0.9:
            break
        k *= 0.5
    name = f"case_{seed}_spring"
    paths = _write(out, name, recs)
    truth = {"case": name, "seed": seed, "families": ["unexplained"],
             "effects": [{"family": "unexplained", "where": {"joint": joint}, "kind": "joint_spring",
                          "parameters": {"stiffness_nm_per_rad": k, "rest_rad": rest_rad}}],
             "parameter_factors": factors, "recordings": paths,
             "concealment": {"history": history, "r2_per_channel": r2}}
    atomic_write_json(Path(out) / f"{name}.truth.json", truth)
    return truth
