"""``pneumasim bench``: the cost of the fluid layer and of Rerun logging, measured side by side.

For each model, from the same initial state (``home``, chambers at 4 bar, valves at null):

* bare: a Python loop of ``mujoco.mj_step`` replaying the forces the full run produced
  (``ctrl`` set once per control period), so both runs do the same rigid-body work (joint
  limits and contacts cost MuJoCo time) — what the rigid body alone costs a user;
* full: :meth:`Simulation.step` (fluid layer + forces into ``ctrl`` + step), controller off,
  in control periods of 10 steps as in a 100 Hz run;
* rerun: the same as full with a Rerun frame logged every control period, to a file.

Each is timed ``repeats`` times, interleaved, and the best time is kept (the usual rule for
micro-benchmarks on a shared machine: noise only ever adds time).  ``ratio`` is full time per
step over bare time per step (1.0 = the fluid layer is free).
"""
from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

from pneumatics.io import atomic_write_json
from pneumatics.robot import load_robot
from pneumatics.sim import Simulation

import models

PERIOD = 10  # physics steps per control period (1 kHz physics, 100 Hz control)


def _prepare(sim: Simulation):
    sim.reset(pressure_pa=4.0e5)
    sim.set_command(sim.tables.valve[:, 0])


def bench_model(name: str, steps: int, repeats: int = 3, with_rerun: bool = True) -> dict:
    robot = load_robot(name)
    sim = Simulation(robot)
    _prepare(sim)
    sim.step(PERIOD)  # compile
    bare_data = mujoco.MjData(robot.model)
    periods = steps // PERIOD
    best = {"bare": np.inf, "full": np.inf, "rerun": np.inf}
    logger = None
    tmpdir = tempfile.TemporaryDirectory()
    if with_rerun:
        try:
            from pneumatics.rerun_log import RerunLogger
        except ImportError:  # pragma: no cover
            with_rerun = False
    _prepare(sim)  # the forces of the full run, once per control period, for the bare replay
    forces = np.empty((periods, robot.model.nu))
    for i in range(periods):
        forces[i] = sim.data.ctrl
        sim.step(PERIOD)
    for _ in range(repeats):
        # bare
        _prepare(sim)
        mujoco.mj_resetData(robot.model, bare_data)
        bare_data.qpos[:] = sim.data.qpos
        m, d, step = robot.model, bare_data, mujoco.mj_step
        ctrl = d.ctrl
        t0 = time.perf_counter()
        for i in range(periods):
            ctrl[:] = forces[i]
            for _ in range(PERIOD):
                step(m, d)
        best["bare"] = min(best["bare"], time.perf_counter() - t0)
        # full
        _prepare(sim)
        t0 = time.perf_counter()
        for _ in range(periods):
            sim.step(PERIOD)
        best["full"] = min(best["full"], time.perf_counter() - t0)
        # full + rerun at 100 Hz
        if with_rerun:
            _prepare(sim)
            logger = RerunLogger(robot, path=Path(tmpdir.name) / f"{name}.rrd")
            t0 = time.perf_counter()
            for _ in range(periods):
                sim.step(PERIOD)
                logger.log_frame(sim)
            logger.close()
            best["rerun"] = min(best["rerun"], time.perf_counter() - t0)
    tmpdir.cleanup()
    n = periods * PERIOD
    out = {
        "bare_steps_per_s": n / best["bare"],
        "full_steps_per_s": n / best["full"],
        "ratio": best["full"] / best["bare"],
        "realtime_factor": n * robot.model.opt.timestep / best["full"],
        "bare_us_per_step": 1e6 * best["bare"] / n,
        "full_us_per_step": 1e6 * best["full"] / n,
        "chambers": robot.tables.n_chambers,
        "steps": n,
    }
    if with_rerun:
        out["rerun_overhead"] = best["rerun"] / best["full"] - 1.0
    return out


def bench_doctor(quick: bool) -> dict:
    """Wall time of ``pneumasim doctor`` on a 60 s, 100 Hz arm2 recording (+ 30 s held out),
    made fresh with a hidden Coulomb friction (``--quick``: 20 s + 10 s)."""
    from identification.doctor import diagnose
    from scenarios._cases import make_case

    seconds, held = (20.0, 10.0) if quick else (60.0, 30.0)
    with tempfile.TemporaryDirectory() as tmp:
        truth = make_case(Path(tmp), 7, ["coulomb_friction"], seconds=seconds, heldout_seconds=held, conceal=False)
        from pneumatics.recording import read_csv
        recs = [read_csv(truth["recordings"]["main"])], [read_csv(truth["recordings"]["heldout"])]
        t0 = time.perf_counter()
        report = diagnose(load_robot("arm2"), *recs)
        secs = time.perf_counter() - t0
    return {"recording_seconds": seconds, "heldout_seconds": held, "seconds": secs,
            "named": ",".join(f["effect"] for f in report["findings"]) or "nothing"}


def run_bench(quick: bool = False, out: str | Path = "runs/bench") -> dict:
    steps = 20_000 if quick else 100_000
    results = {}
    for name in ("arm2", "humanoid38"):
        if name not in models.available(models.VALVE_ARM):
            continue
        n = steps if name == "arm2" else steps // 4
        results[name] = bench_model(name, n, repeats=3)
    results["doctor"] = bench_doctor(quick)
    _print_table(results)
    path = Path(out) / "bench.json"
    atomic_write_json(path, results)
    print(f"wrote {path}")
    return results


def _print_table(results: dict):
    from rich.console import Console
    from rich.table import Table

    table = Table(title="pneumasim bench (best of 3, this machine)")
    for col in ("model", "chambers", "bare steps/s", "full steps/s", "ratio", "realtime x", "rerun overhead"):
        table.add_column(col, justify="right")
    for name, r in results.items():
        if "bare_steps_per_s" not in r:
            continue
        table.add_row(name, str(r["chambers"]), f"{r['bare_steps_per_s']:,.0f}", f"{r['full_steps_per_s']:,.0f}",
                      f"{r['ratio']:.2f}", f"{r['realtime_factor']:.0f}",
                      f"{r['rerun_overhead']:+.0%}" if "rerun_overhead" in r else "-")
    Console().print(table)
    if "doctor" in results:
        d = results["doctor"]
        print(f"doctor: {d['recording_seconds']:.0f} s + {d['heldout_seconds']:.0f} s held out of arm2 at 100 Hz "
              f"diagnosed in {d['seconds']:.0f} s (named: {d['named']})")


if __name__ == "__main__":
    print(json.dumps(run_bench(quick=True), indent=1))
