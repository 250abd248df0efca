"""The main job: simulate arm2 tracking a hand-moved reference with PIDF control, show it,
then let the doctor find a concealed effect in a freshly made recording.

Writes a recording (CSV, the format of DESIGN.md), PNG plots of tracking and chamber
pressures, and a Rerun file (``demo.rrd``; open it with ``rerun demo.rrd``).  Then makes a new
60 s recording (+ 30 s held out) of an arm2 whose parameters are a few per cent off and which
hides one effect, runs ``pneumasim doctor`` on the CSV files alone, prints its ten-second
summary and writes its report to ``doctor/``.
"""
from __future__ import annotations

import numpy as np

from controllers.pid import ARM2_PIDF
from controllers.reference import hand_moved
from pneumatics.robot import load_robot
from pneumatics.runner import run as run_loop
from pneumatics.sim import Simulation

from .common import main, plt

SUMMARY = "main job: arm2 tracks a hand-moved reference under PIDF; recording, plots and a Rerun file"


def run(ctx):
    duration = 6.0 if ctx.fast else 30.0
    robot = load_robot("arm2")
    ref = hand_moved(robot.joint_names, robot.joint_range(), duration, seed=7)
    sim = Simulation(robot)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=4.0e5)
    if ctx.rerun_path is None and not ctx.spawn:
        ctx.rerun_path = ctx.out / "demo.rrd"
    logger = ctx.rerun_logger(robot, "arm2 demo")
    rec = run_loop(sim, ARM2_PIDF.build(ref, robot.tables.valve[:, 0]), duration, seed=7, logger=logger,
                   record_force=True)
    if logger is not None:
        logger.close()
    ctx.save_recording(rec, "arm2_demo.csv")

    t = rec.time
    fig, axes = plt.subplots(3, 2, figsize=(12, 8), sharex=True)
    metrics = {}
    for col, j in enumerate(robot.joint_names):
        q, r = np.degrees(rec[f"q.{j}"]), np.degrees(rec[f"ref.{j}"])
        axes[0, col].plot(t, r, "k--", lw=1, label="reference")
        axes[0, col].plot(t, q, lw=1.2, label="measured")
        axes[0, col].set_ylabel(f"{j} [deg]")
        axes[0, col].legend(fontsize=8, loc="upper right")
        axes[1, col].plot(t, rec[f"p_a.{j}"] / 1e5, label="chamber a")
        axes[1, col].plot(t, rec[f"p_b.{j}"] / 1e5, label="chamber b")
        axes[1, col].set_ylabel("pressure [bar abs]")
        axes[1, col].legend(fontsize=8, loc="upper right")
        axes[2, col].plot(t, rec[f"u_a.{j}"], lw=0.8, label="valve a")
        axes[2, col].plot(t, rec[f"u_b.{j}"], lw=0.8, label="valve b")
        axes[2, col].set_ylabel("command [V]")
        axes[2, col].set_xlabel("time [s]")
        axes[2, col].legend(fontsize=8, loc="upper right")
        metrics[f"rms_err_deg_{j}"] = float(np.sqrt(np.mean((q - r) ** 2)))
    fig.suptitle("arm2 under PIDF control (paper 002 eq. 15), 100 Hz, sensor noise and DAQ averaging")
    fig.tight_layout()
    ctx.savefig(fig, "arm2_demo.png")
    p = rec.matrix("p_a", robot.actuator_names)
    metrics.update({"duration_s": duration, "max_pressure_pa": float(p.max()), "min_pressure_pa": float(p.min())})
    metrics.update(doctor_demo(ctx))
    return metrics


def doctor_demo(ctx) -> dict:
    """A fresh recording with a hidden effect, and the doctor on it."""
    from identification.doctor.valve_arm.diagnose import diagnose
    from identification.doctor.valve_arm.report import summary, write
    from pneumatics.recording import read_csv

    from ._cases import make_case

    seconds, held = (30.0, 15.0) if ctx.fast else (60.0, 30.0)
    case_dir = ctx.out / "doctor_case"
    print(f"demo: making a {seconds:.0f} s recording with a hidden effect in {ctx.shown(case_dir)} ...")
    truth = make_case(case_dir, 2024, ["valve_hysteresis"], seconds=seconds, heldout_seconds=held, name="mystery")
    print(f"demo: pneumasim doctor --model arm2 {ctx.shown(truth['recordings']['main'])} "
          f"--holdout {ctx.shown(truth['recordings']['heldout'])} --out {ctx.shown(ctx.out / 'doctor')}")
    robot = load_robot("arm2")
    report = diagnose(robot, [read_csv(truth["recordings"]["main"])], [read_csv(truth["recordings"]["heldout"])])
    write(report, ctx.out / "doctor", robot)
    print(summary(report))
    hidden = truth["effects"][0]
    print(f"demo: the hidden truth was {hidden['family']} at {hidden['where']} {hidden['parameters']}")
    named = [f["effect"] for f in report["findings"]]
    where = [f["where"] for f in report["findings"]]
    return {"doctor_named": ",".join(named) or "nothing",
            "doctor_correct": int(named == [hidden["family"]] and where == [hidden["where"]]),
            "doctor_seconds": report["diagnostics"]["seconds"]}


if __name__ == "__main__":
    main(__name__)
