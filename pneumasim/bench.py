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
step over bare time per step (1.0 = the fluid layer is free).  The same run also times the
paths of :mod:`pneumasim.bench_paths` against MuJoCo's own C loop (``ratio_vs_c``,
``closed_loop_ratio_vs_c``) and the doctor's chamber replays.
"""
from __future__ import annotations

import json
import os
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

from pneumasim.bench_paths import bench_doctor_replay, bench_paths
from pneumatics.io import OutputFolder, atomic_write_json
from workflow.progress import Progress
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
            from workflow.rerun_log import RerunLogger
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
    from identification.doctor.valve_arm.diagnose import diagnose
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


def _noop_case(case: dict) -> dict:
    """A case that costs nothing: what is left is the sweep's own cost per case."""
    return {"i": case["i"]}


def bench_sweep(quick: bool) -> dict:
    """Cases per second of :func:`workflow.sweep.sweep` on 1 and 2 local workers and on Ray
    (local, 2 CPUs), each case a closed-loop arm2 run (``arm2_domain_sweep.track``, 10 s
    simulated, nominal parameters).  Workers are warmed first (imports, numba compilation:
    paid once per worker process, reported as ``worker_warmup_s``); then the three set-ups
    are timed ``repeats`` times, interleaved, best kept.  Other processes load this machine;
    the 1-minute load average is recorded beside the numbers."""
    from workflow.sweep import connect_ray, cpu_count, sweep
    from scenarios.arm2_domain_sweep import track

    try:
        import ray
    except ImportError:  # pragma: no cover
        ray = None
    n, repeats = (8, 2) if quick else (16, 3)
    cases = [{"supply_pa": 7e5, "area_scale": 1.0, "seconds": 10.0, "seed": 100 + i} for i in range(n)]
    noop = [{"i": i} for i in range(200)]
    out = {"cases": n, "case_simulated_s": 10.0, "cpus": cpu_count(), "load_average_1min": os.getloadavg()[0]}
    t0 = time.perf_counter()
    sweep(track, cases[:2], workers=2, progress=False)  # warm both workers
    out["worker_warmup_s"] = time.perf_counter() - t0
    setups = {"1": {"workers": 1}, "2": {"workers": 2}}
    started = False
    if ray is not None:
        started = not ray.is_initialized()
        t0 = time.perf_counter()
        connect_ray(None, 2)
        out["ray_start_s"] = time.perf_counter() - t0
        sweep(track, cases[:4], backend="ray", workers=2, progress=False)  # warm Ray's workers
        setups["ray"] = {"backend": "ray", "workers": 2}
    best = dict.fromkeys(setups, np.inf)
    for _ in range(repeats):
        for key, opts in setups.items():
            t0 = time.perf_counter()
            sweep(track, cases, progress=False, **opts)
            best[key] = min(best[key], time.perf_counter() - t0)
    out["cases_per_s_1_worker"] = n / best["1"]
    out["cases_per_s_2_workers"] = n / best["2"]
    out["speedup_2_workers"] = best["1"] / best["2"]
    for key, opts in setups.items():
        if key != "1":
            t0 = time.perf_counter()
            sweep(_noop_case, noop, progress=False, **opts)
            out[f"{'ray' if key == 'ray' else 'process'}_overhead_ms_per_case"] = \
                1e3 * (time.perf_counter() - t0) / len(noop)
    if ray is not None:
        out["ray_cases_per_s_2_workers"] = n / best["ray"]
        out["ray_overhead"] = best["ray"] / best["2"] - 1.0  # Ray local time over process-pool time, minus 1
        if started:
            ray.shutdown()
    out["load_average_1min_end"] = os.getloadavg()[0]
    return out


def run_bench(quick: bool = False, out: str | Path = "runs/bench", scaling: bool = False) -> dict:
    """Run the benchmarks; ``out`` is checked first and replaced whole at the end.  ``scaling``:
    also the cost per step against the number of chambers and the doctor's time against the
    recording length (:mod:`pneumasim.bench_scaling`; scaling.png beside bench.json)."""
    steps = 20_000 if quick else 100_000
    results = {}
    with OutputFolder(out) as folder, Progress("bench", live=False) as progress:
        for name in ("arm2", "humanoid38"):
            if name not in models.available(models.VALVE_ARM):
                continue
            n = steps if name == "arm2" else steps // 4
            progress.say(f"simulation step, {name} ({n} steps)")
            results[name] = bench_model(name, n, repeats=3)
            progress.say(f"paths against MuJoCo's C loop, {name}")
            results[name].update(bench_paths(name, n * 1e-3 / 2, repeats=3))
        progress.say("doctor replays")
        results["doctor_replay"] = bench_doctor_replay(10.0 if quick else 30.0)
        progress.say("doctor")
        results["doctor"] = bench_doctor(quick)
        if scaling:  # before the sweep: measured after Ray had run, its figures came out up to twice as slow
            from pneumasim.bench_scaling import run_scaling

            progress.say("scaling: chambers and recording length")
            results["scaling"] = run_scaling(folder.path)
        progress.say("sweep overheads")
        results["sweep"] = bench_sweep(quick)
        _print_table(results)
        atomic_write_json(folder.path / "bench.json", results)
    print(f"wrote {Path(out) / 'bench.json'}")
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
    Console(width=132).print(table)
    paths = Table(title="against MuJoCo's C loop (mujoco.rollout), commands changing at 100 Hz")
    for col in ("model", "C steps/s", "Python mj_step", "open loop (play)", "its Python loop", "closed loop (PIDF)",
                "ratio_vs_c", "closed_loop_ratio_vs_c"):
        paths.add_column(col, justify="right")
    for name, r in results.items():
        if "bare_c_steps_per_s" in r:
            paths.add_row(name, f"{r['bare_c_steps_per_s']:,.0f}", f"{r['bare_py_steps_per_s']:,.0f}",
                          f"{r['full_open_loop_steps_per_s']:,.0f}", f"{r['full_open_loop_python_steps_per_s']:,.0f}",
                          f"{r['full_closed_loop_steps_per_s']:,.0f}", f"{r['ratio_vs_c']:.2f}",
                          f"{r['closed_loop_ratio_vs_c']:.2f}")
    Console(width=132).print(paths)
    if "doctor_replay" in results:
        r = results["doctor_replay"]
        print(f"doctor chamber replays: {1e3 * r['seconds_per_data_second']:.1f} ms per second of arm2 data")
    if "doctor" in results:
        d = results["doctor"]
        print(f"doctor: {d['recording_seconds']:.0f} s + {d['heldout_seconds']:.0f} s held out of arm2 at 100 Hz "
              f"diagnosed in {d['seconds']:.0f} s (named: {d['named']})")
    if "sweep" in results:
        s = results["sweep"]
        print(f"sweep: {s['cases']} arm2 runs of {s['case_simulated_s']:.0f} s: {s['cases_per_s_1_worker']:.2f} cases/s "
              f"on 1 worker, {s['cases_per_s_2_workers']:.2f} on 2 ({s['speedup_2_workers']:.2f}x, {s['cpus']} CPUs, "
              f"load average {s['load_average_1min']:.1f}); worker warm-up {s['worker_warmup_s']:.0f} s")
        if "ray_overhead" in s:
            print(f"sweep on Ray (local, 2 CPUs): {s['ray_cases_per_s_2_workers']:.2f} cases/s, "
                  f"{s['ray_overhead']:+.0%} vs the process pool; {s['ray_overhead_ms_per_case']:.1f} ms/case "
                  f"overhead (process pool {s['process_overhead_ms_per_case']:.1f}); Ray start {s['ray_start_s']:.0f} s")


if __name__ == "__main__":
    print(json.dumps(run_bench(quick=True), indent=1))
