"""How the cost grows: time per physics step against the number of chambers, and the doctor's
time against the recording's length (``pneumasim bench --scaling``; docs/performance.md).

The chamber counts come from arm2 (4), humanoid38 (76) and a synthetic *cylinder bank*: n
copies of arm2's shoulder cylinder, each driving a pendulum of its own through a fixed moment
arm, so the rigid body stays cheap and what grows is the fluid layer (n = 1 .. 100 actuators,
2 .. 200 chambers).  Every point is timed like ``pneumasim bench``'s open loop (valve commands
changing every control period, best of ``repeats``) beside MuJoCo stepping the same forces in
its own C loop (:mod:`pneumasim.bench_paths`).
"""
from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import mujoco
import numpy as np

import models
from pneumatics.params import load_fluid
from pneumatics.robot import Robot, assemble_robot, load_robot
from pneumatics.sim import Simulation

PERIOD = 10            # physics steps per control period
GEAR_M = 0.03          # the bank's moment arm [m]: arm2's shoulder
BANK_SIZES = (1, 2, 5, 10, 25, 50, 100)


def cylinder_bank(n_act: int) -> Robot:
    """n copies of arm2's shoulder cylinder (fluid parameters from models/arm2/fluid.toml), each
    turning a 1 kg pendulum through GEAR_M, the pendulums side by side and not touching."""
    fluid = load_fluid(models.fluid_path("arm2"))
    proto = fluid.actuators[0]
    fluid = dataclasses.replace(fluid, actuators=tuple(dataclasses.replace(proto, name=f"cyl{i}")
                                                       for i in range(n_act)))
    bodies = "".join(
        f'<body name="link{i}" pos="{0.2 * i} 0 1"><joint name="cyl{i}" axis="0 1 0" range="-1 1" damping="0.05"/>'
        f'<geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.02" mass="1" contype="0" conaffinity="0"/></body>'
        for i in range(n_act))
    motors = "".join(f'<motor name="cyl{i}" joint="cyl{i}" gear="{GEAR_M}"/>' for i in range(n_act))
    xml = (f'<mujoco model="cylinder_bank"><compiler angle="radian"/><option timestep="0.001"/>'
           f'<worldbody>{bodies}</worldbody><actuator>{motors}</actuator></mujoco>')
    return assemble_robot(f"cylinder_bank_{n_act}", mujoco.MjModel.from_xml_string(xml), fluid, None)


def step_costs(robot: Robot, seconds: float = 2.0, repeats: int = 3) -> dict:
    """µs per physics step of the open loop (commands: each valve a sine about its null, a
    different frequency per chamber, set every control period) and of MuJoCo's C loop
    stepping the forces that run produced."""
    from pneumasim.bench_paths import ctrl_sequence, reset_bench_state, time_bare_c, time_open_loop

    sim = Simulation(robot)
    n_ch = robot.tables.n_chambers
    periods = int(round(seconds * 1000 / PERIOD))
    t = np.arange(periods)[:, None] * PERIOD * 1e-3
    commands = robot.tables.valve[:, 0] + 2.0 * np.sin(2 * np.pi * (0.5 + 0.1 * np.arange(n_ch)) * t)
    reset_bench_state(sim)
    sim.step(PERIOD)  # compile
    ctrl, state0 = ctrl_sequence(sim, commands)
    best_full = best_c = np.inf
    for _ in range(repeats):
        best_full = min(best_full, time_open_loop(sim, commands))
        best_c = min(best_c, time_bare_c(sim.model, state0, ctrl))
    n = periods * PERIOD
    return {"chambers": n_ch, "us_per_step": 1e6 * best_full / n, "c_us_per_step": 1e6 * best_c / n,
            "ratio_vs_c": best_full / best_c}


def doctor_costs(lengths_s=(15.0, 30.0, 60.0)) -> list[dict]:
    """Wall time of the arm2 doctor on fresh recordings of each length (and half that held
    out) with a hidden Coulomb friction, as ``pneumasim bench``'s doctor figure."""
    import tempfile

    from identification.doctor.valve_arm.diagnose import diagnose
    from pneumatics.recording import read_csv
    from scenarios._cases import make_case

    out = []
    for seconds in lengths_s:
        with tempfile.TemporaryDirectory() as tmp:
            truth = make_case(Path(tmp), 7, ["coulomb_friction"], seconds=seconds, heldout_seconds=seconds / 2,
                              conceal=False)
            recs = [read_csv(truth["recordings"]["main"])], [read_csv(truth["recordings"]["heldout"])]
            t0 = time.perf_counter()
            report = diagnose(load_robot("arm2"), *recs)
            out.append({"recording_seconds": seconds, "heldout_seconds": seconds / 2,
                        "seconds": time.perf_counter() - t0,
                        "named": ",".join(f["effect"] for f in report["findings"]) or "nothing"})
    return out


def run_scaling(folder: Path, bank_sizes=BANK_SIZES, doctor_lengths=(15.0, 30.0, 60.0)) -> dict:
    """Every point of the study into ``folder``: scaling.json and scaling.png."""
    points = [{"model": "arm2", **step_costs(load_robot("arm2"))},
              {"model": "humanoid38", **step_costs(load_robot("humanoid38"), seconds=1.0)}]
    points += [{"model": f"cylinder_bank_{n}", **step_costs(cylinder_bank(n))} for n in bank_sizes]
    result = {"steps": points, "doctor": doctor_costs(doctor_lengths)}
    _plot(result, folder / "scaling.png")
    return result


def _plot(result: dict, path: Path):
    from identification.base.reporting import pyplot, save_figure

    plt = pyplot()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4))
    bank = [p for p in result["steps"] if p["model"].startswith("cylinder_bank")]
    named = [p for p in result["steps"] if not p["model"].startswith("cylinder_bank")]
    ax.plot([p["chambers"] for p in bank], [p["us_per_step"] for p in bank], "o-", label="cylinder bank, fluid layer + MuJoCo")
    ax.plot([p["chambers"] for p in bank], [p["c_us_per_step"] for p in bank], "s--", label="cylinder bank, MuJoCo alone (C loop)")
    for k, p in enumerate(named):
        ax.plot(p["chambers"], p["us_per_step"], "k^", label="shipped model, fluid layer + MuJoCo" if k == 0 else None)
        ax.plot(p["chambers"], p["c_us_per_step"], "kv", label="shipped model, MuJoCo alone (C loop)" if k == 0 else None)
        ax.annotate(f"{p['model']} ({p['ratio_vs_c']:.2f}x)", (p["chambers"], p["us_per_step"]),
                    textcoords="offset points", xytext=(5, 5), fontsize=8)
    ax.set_xlabel("chambers")
    ax.set_ylabel("time per physics step [µs]")
    ax.set_title("cost per step against the number of chambers")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    d = result["doctor"]
    bx.plot([x["recording_seconds"] for x in d], [x["seconds"] for x in d], "o-")
    bx.set_xlabel("fitted recording [s] (plus half as much held out)")
    bx.set_ylabel("doctor wall time [s]")
    bx.set_title("arm2 doctor time against recording length")
    bx.grid(alpha=0.3)
    save_figure(fig, path)
