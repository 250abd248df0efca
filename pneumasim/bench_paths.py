"""The paths a user's run takes, timed against MuJoCo stepping the same forces in C.

``pneumasim bench`` keeps its first figures (``bare`` = a Python loop of ``mj_step``,
``full`` = the fluid layer with the valve commands held); these add, side by side in one run,
interleaved, best of ``repeats`` (noise only ever adds time):

* ``bare_c``: MuJoCo's own C loop (``mujoco.rollout``, one thread) over the very ``ctrl``
  sequence the open-loop run below produced, one value per physics step — the limit of this
  design: the rigid body alone, with no Python per step;
* ``bare_py``: the same ``ctrl`` sequence through a Python loop of ``mj_step`` (what the
  older ``bare`` measures, with the forces changing every step instead of every period);
* ``full_open_loop``: the valve commands of a recorded PIDF run, changing every control period
  (100 Hz), played as a replay of a recording drives the simulator (:meth:`Simulation.play`,
  one compiled call for the whole sequence);
* ``full_open_loop_python``: the same commands through a Python loop of
  :meth:`Simulation.set_command` and :meth:`Simulation.step` (what a user's own loop pays);
* ``full_closed_loop``: :func:`pneumatics.runner.run` under the shipped PIDF at 100 Hz (DAQ
  averaging, sensor noise, the controller, the recording kept), on the compiled closed loop
  the built-in controllers get (:mod:`controllers.compiled_loop`);
* ``full_doctor_replay`` (arm2): the doctor's chamber replays (0.3 s windows restarted from
  the measured pressures, driven by the measured motion and commands) over a recording,
  reported as compute seconds per second of data.

``ratio_vs_c`` = full_open_loop time per step / bare_c time per step;
``python_loop_ratio_vs_c`` = full_open_loop_python / bare_c;
``closed_loop_ratio_vs_c`` = full_closed_loop / bare_c (DESIGN.md "Benchmarks").
"""
from __future__ import annotations

import time

import mujoco
import numpy as np
from mujoco import rollout

from pneumatics.robot import load_robot
from pneumatics.runner import run as run_loop
from pneumatics.sim import Simulation

PERIOD = 10          # physics steps per control period (1 kHz physics, 100 Hz control)
START_PA = 4.0e5     # chamber pressure at the start of every timed run


def shipped_controller(robot, seconds: float):
    """The PIDF a user of this model runs, on a hand-moved reference of ``seconds``.

    arm2: ``controllers.pid.ARM2_PIDF``.  humanoid38: the PIDF of ``humanoid38_tracking`` with
    its gains scaled per joint for a nominal range per volt, without the valve-linearising
    transform (whose calibration takes minutes; it adds one table look-up per chamber and
    period, which this figure then leaves out)."""
    from controllers.pid import ARM2_PIDF
    from controllers.reference import hand_moved

    ref = hand_moved(robot.joint_names, robot.joint_range(), seconds, seed=1)
    null_v = robot.tables.valve[:, 0]
    if robot.name == "arm2":
        return ARM2_PIDF.build(ref, null_v)
    from scenarios._humanoid import pidf_gains

    return pidf_gains(np.full(len(robot.joint_names), 0.5)).build(ref, null_v)


def reset_bench_state(sim: Simulation):
    """Every timed run starts here: the home pose, chambers at START_PA, valves at null."""
    sim.reset(pressure_pa=START_PA)
    sim.set_command(sim.tables.valve[:, 0])


def recorded_inputs(sim: Simulation, seconds: float):
    """(commands (P, C) [V] once per period, ctrl (P * PERIOD, nu) once per physics step,
    initial MuJoCo state) of a closed-loop run, for the open-loop and C replays."""
    rec = run_loop(sim, shipped_controller(sim.robot, seconds), seconds, noise=False)
    cols = [c for a in sim.robot.actuator_names for c in (f"u_a.{a}", f"u_b.{a}")]
    commands = np.stack([rec[c] for c in cols], axis=1)[:-1]
    ctrl, state0 = ctrl_sequence(sim, commands)
    return commands, ctrl, state0


def ctrl_sequence(sim: Simulation, commands):
    """(ctrl (P * PERIOD, nu): the actuator forces of every physics step of an open-loop run
    of ``commands`` (P, C) from the bench's start state, that start state as MuJoCo's full
    physics state), for replaying the same forces in MuJoCo alone."""
    reset_bench_state(sim)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(sim.model, spec))
    mujoco.mj_getState(sim.model, sim.data, state0, spec)
    ctrl = np.empty((len(commands) * PERIOD, sim.model.nu))
    for k, u in enumerate(commands):  # step by step: the ctrl each physics step saw
        sim.set_command(u)
        for s in range(PERIOD):
            ctrl[k * PERIOD + s] = sim.data.ctrl
            sim.step(1)
    return ctrl, state0


def time_bare_c(model, state0, ctrl) -> float:
    """Seconds MuJoCo's own C loop (``mujoco.rollout``, one thread) takes to step ``ctrl``."""
    data = mujoco.MjData(model)
    spec = int(mujoco.mjtState.mjSTATE_CTRL)
    t0 = time.perf_counter()
    rollout.rollout(model, data, state0[None], ctrl[None], control_spec=spec)
    return time.perf_counter() - t0


def _time_bare_py(model, state0, ctrl) -> float:
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    step, c = mujoco.mj_step, data.ctrl
    t0 = time.perf_counter()
    for row in ctrl:
        c[:] = row
        step(model, data)
    return time.perf_counter() - t0


def time_open_loop(sim: Simulation, commands) -> float:
    """Seconds :meth:`Simulation.play` takes for ``commands`` (P, C), one per control period."""
    reset_bench_state(sim)
    t0 = time.perf_counter()
    sim.play(commands, PERIOD)
    return time.perf_counter() - t0


def time_open_loop_python(sim: Simulation, commands) -> float:
    """Seconds a Python loop of set_command and step takes for ``commands`` (P, C)."""
    reset_bench_state(sim)
    t0 = time.perf_counter()
    for u in commands:
        sim.set_command(u)
        sim.step(PERIOD)
    return time.perf_counter() - t0


def _time_closed_loop(sim: Simulation, seconds: float) -> float:
    controller = shipped_controller(sim.robot, seconds)
    reset_bench_state(sim)
    t0 = time.perf_counter()
    run_loop(sim, controller, seconds)
    return time.perf_counter() - t0


def bench_paths(name: str, seconds: float, repeats: int = 3) -> dict:
    """Every path of the module docstring for model ``name`` over ``seconds`` of simulated time."""
    sim = Simulation(load_robot(name))
    reset_bench_state(sim)
    sim.step(PERIOD)  # compile
    commands, ctrl, state0 = recorded_inputs(sim, seconds)
    n = ctrl.shape[0]
    m = sim.model
    timers = {"bare_c": lambda: time_bare_c(m, state0, ctrl),
              "bare_py": lambda: _time_bare_py(m, state0, ctrl),
              "full_open_loop": lambda: time_open_loop(sim, commands),
              "full_open_loop_python": lambda: time_open_loop_python(sim, commands),
              "full_closed_loop": lambda: _time_closed_loop(sim, seconds)}
    best = dict.fromkeys(timers, np.inf)
    for fn in timers.values():  # warm-up: first calls allocate and compile
        fn()
    for _ in range(repeats):
        for key, fn in timers.items():
            best[key] = min(best[key], fn())
    out = {f"{k}_steps_per_s": n / v for k, v in best.items()}
    out["ratio_vs_c"] = best["full_open_loop"] / best["bare_c"]
    out["closed_loop_ratio_vs_c"] = best["full_closed_loop"] / best["bare_c"]
    out["python_loop_ratio_vs_c"] = best["full_open_loop_python"] / best["bare_c"]
    out["bare_py_ratio_vs_c"] = best["bare_py"] / best["bare_c"]
    out["paths_steps"] = n
    return out


def bench_doctor_replay(seconds: float = 20.0, repeats: int = 3) -> dict:
    """The doctor's chamber replays over an arm2 recording of ``seconds``: compute seconds per
    second of data (nominal model, 0.3 s windows restarted every 0.3 s, as the calibration and
    the screening replay them)."""
    from identification.doctor.valve_arm.data import prepare
    from identification.doctor.valve_arm.pneumatic import Windows, replay
    from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods

    robot = load_robot("arm2")
    sim = Simulation(robot)
    reset_bench_state(sim)
    rec = run_loop(sim, shipped_controller(robot, seconds), seconds)
    exp = prepare(robot, rec)
    win = Windows.tile(exp.t.size, horizon=30)
    mods = PneumaticMods.nominal(robot.tables.n_chambers)
    replay(exp, win, mods)  # compile
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        replay(exp, win, mods)
        best = min(best, time.perf_counter() - t0)
    return {"recording_seconds": seconds, "windows": int(win.starts.size),
            "seconds_per_data_second": best / seconds}
