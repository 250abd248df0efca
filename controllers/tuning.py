"""Automatic gain tuning by the nonlinear simplex method (paper 002 §V-B).

"We implemented a function whose arguments specify the feedback gains.  This function applies
the corresponding control law to the robot (on a 10 second trajectory), measures the tracking
error, and returns it ... we used the nonlinear simplex method ... the evaluation function
returned a large error whenever the robot hit any of the joint limits at high speed."

Here the robot is the simulated arm2 (with its sensor noise, so the cost is noisy as on the
real robot, which is why a simplex rather than finite differences).  The gains are searched
in log space (they stay positive and span decades); there are plenty of local minima, so the
search is restarted from several starting points, each restart one case of
:func:`workflow.sweep.sweep` (processes, or Ray).

Families: ``pid`` (k_P, k_D per joint, one k_I; k_F = 0), ``pidf`` (the same plus k_F per
joint), ``model_based`` (PIDF gains with the inverse-dynamics feedforward, eqs. 16-17).
"""
from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
from scipy.optimize import minimize

from pneumatics.errors import PneumasimError

from .pid import ARM2_PID, ARM2_PIDF, PIDFCfg

FAMILIES = ("pid", "pidf", "model_based")
#: a joint within this of its limit while faster than LIMIT_SPEED counts as hitting it at speed
LIMIT_MARGIN_RAD = np.radians(1.0)
LIMIT_SPEED_RAD_S = np.radians(100.0)
#: cost [deg] added when a limit is hit at speed ("a large error"); added rather than returned
#: alone so that the simplex still sees which of two limit-hitting gain sets tracks better
LIMIT_PENALTY_DEG = 100.0


def gains_to_x(cfg: PIDFCfg, family: str) -> np.ndarray:
    """Log-gain vector of a configuration: [kp_s, kp_e, kd_s, kd_e, ki (, kf_s, kf_e)]."""
    g = cfg.as_vector(2)
    x = [*g[0], *g[1], g[2].mean()]
    if family != "pid":
        x += [*g[3]]
    return np.log(np.maximum(x, 1e-6))


def x_to_gains(x: np.ndarray, family: str, base: PIDFCfg = ARM2_PIDF) -> PIDFCfg:
    g = np.exp(np.asarray(x, float))
    kf = (0.0, 0.0) if family == "pid" else (float(g[5]), float(g[6]))
    return replace(base, kp_v_per_rad=(float(g[0]), float(g[1])), kd_v_s_per_rad=(float(g[2]), float(g[3])),
                   ki_v_per_rad_s=(float(g[4]), float(g[4])), kf_v_per_bar=kf)


def start_gains(family: str) -> PIDFCfg:
    return ARM2_PID if family == "pid" else ARM2_PIDF


def tracking_cost(rec, joint_range: np.ndarray) -> tuple[float, bool]:
    """(mean absolute error [deg] over joints and time, hit a limit at speed?)."""
    names = [c.split(".", 1)[1] for c in rec.columns if c.startswith("q.")]
    q = rec.matrix("q", names)
    r = rec.matrix("ref", names)
    qd = np.gradient(q, rec.time, axis=0)
    near = (q < joint_range[:, 0] + LIMIT_MARGIN_RAD) | (q > joint_range[:, 1] - LIMIT_MARGIN_RAD)
    hit = bool(np.any(near & (np.abs(qd) > LIMIT_SPEED_RAD_S)))
    return float(np.degrees(np.abs(q - r)).mean()), hit


def evaluate(cfg: PIDFCfg, family: str, *, duration_s: float = 10.0, ref_seed=3, speed: float = 1.0,
             noise_seed: int = 0, model=None) -> dict:
    """Run the controller on arm2 over a ``duration_s`` hand-moved reference; the cost.

    ``ref_seed`` may be a list: the cost is then the mean over those references (one 10 s
    trajectory, as in the paper, lets the simplex overfit it; see docs/arm2_control.md)."""
    seeds = list(ref_seed) if isinstance(ref_seed, (list, tuple)) else [ref_seed]
    runs = [_evaluate_one(cfg, family, duration_s, s, speed, noise_seed, model) for s in seeds]
    mae = float(np.mean([r[0] for r in runs]))
    hit = any(r[1] for r in runs)
    return {"mae_deg": mae, "hit_limit": hit, "cost": mae + (LIMIT_PENALTY_DEG if hit else 0.0)}


def _evaluate_one(cfg, family, duration_s, ref_seed, speed, noise_seed, model):
    from controllers.reference import hand_moved
    from pneumatics.robot import load_robot
    from pneumatics.runner import run
    from pneumatics.sim import Simulation

    robot = load_robot("arm2")
    ref = hand_moved(robot.joint_names, robot.joint_range(), duration_s, seed=int(ref_seed), speed=speed)
    sim = Simulation(robot)
    sim.reset(qpos=ref.reference(0.0), pressure_pa=4.0e5)
    null = robot.tables.valve[:, 0]
    if family == "model_based":
        from .model_based import ModelBasedCfg

        ctrl = ModelBasedCfg(pidf=cfg).build(ref, null, model)
    else:
        ctrl = cfg.build(ref, null)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = run(sim, ctrl, duration_s, seed=noise_seed)
    return tracking_cost(rec, robot.joint_range())


def tune_case(case: dict) -> dict:
    """One Nelder-Mead restart (a picklable sweep case).

    case keys: family, x0 (log gains), maxfev, duration_s, ref_seed, speed, model (dict of
    InverseDynamics for model_based, optional).
    """
    family = case["family"]
    if family not in FAMILIES:
        raise PneumasimError(f"tuning: unknown family {family!r}; valid: {', '.join(FAMILIES)}")
    model = None
    if case.get("model") is not None:
        from identification.inverse_dynamics import InverseDynamics

        model = InverseDynamics.from_dict(case["model"])
    kw = {k: case[k] for k in ("duration_s", "ref_seed", "speed") if k in case}
    calls = []

    def cost(x):
        r = evaluate(x_to_gains(x, family), family, model=model, noise_seed=len(calls), **kw)
        calls.append(r["cost"])
        return r["cost"]

    x0 = np.asarray(case["x0"], float)
    res = minimize(cost, x0, method="Nelder-Mead",
                   options={"maxfev": int(case.get("maxfev", 60)), "initial_simplex": _simplex(x0, 0.4),
                            "xatol": 0.02, "fatol": 0.05})
    cfg = x_to_gains(res.x, family)
    return {"x": res.x.tolist(), "cost": float(res.fun), "start_cost": float(calls[0]), "nfev": int(res.nfev),
            "gains": {k: list(getattr(cfg, k)) for k in ("kp_v_per_rad", "kd_v_s_per_rad", "ki_v_per_rad_s",
                                                          "kf_v_per_bar")}}


def _simplex(x0, step):
    return np.vstack([x0, x0 + step * np.eye(x0.size)])


def restart_cases(family: str, restarts: int, *, seed: int = 0, spread: float = 0.7, maxfev: int = 60,
                  duration_s: float = 10.0, ref_seed=3, speed: float = 1.0, model=None) -> list[dict]:
    """Sweep cases: the first from the shipped gains, the others log-uniformly jittered."""
    rng = np.random.default_rng(seed)
    x_start = gains_to_x(start_gains(family), family)
    cases = []
    for k in range(restarts):
        x0 = x_start if k == 0 else x_start + rng.uniform(-spread, spread, x_start.size)
        cases.append({"family": family, "x0": x0.tolist(), "maxfev": maxfev, "duration_s": duration_s,
                      "ref_seed": ref_seed, "speed": speed,
                      "model": None if model is None else model.to_dict()})
    return cases


def tune(family: str, restarts: int = 4, *, backend: str = "process", workers=None, **kw) -> dict:
    """Nelder-Mead from ``restarts`` starting points through the sweep API; the best result.

    Returns {"best": tune_case result, "restarts": [...], "cfg": PIDFCfg}."""
    cases = restart_cases(family, restarts, **kw)
    try:
        from workflow.sweep import sweep
    except ImportError:  # the sweep module is being written alongside; run in this process
        warnings.warn("workflow.sweep is not available: running the restarts one after another",
                      stacklevel=2)
        results = [tune_case(c) for c in cases]
    else:
        out = sweep(tune_case, cases, backend=backend, workers=workers, progress=False)
        failed = [r for r in out if r.error]
        if len(failed) == len(out):
            raise PneumasimError(f"tuning: every restart failed; first error: {failed[0].error}")
        results = [r.result for r in out if not r.error]
    best = min(results, key=lambda r: r["cost"])
    return {"best": best, "restarts": results, "cfg": x_to_gains(np.array(best["x"]), family)}


def main(argv=None):
    """``python -m controllers.tuning pid|pidf [--restarts N] [--maxfev N] [--backend B]``."""
    import argparse
    import json

    ap = argparse.ArgumentParser(prog="python -m controllers.tuning", description=__doc__.split("\n")[0])
    ap.add_argument("family", choices=[f for f in FAMILIES if f != "model_based"])
    ap.add_argument("--restarts", type=int, default=4)
    ap.add_argument("--maxfev", type=int, default=60)
    ap.add_argument("--backend", default="process", choices=("inline", "process", "ray"))
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--speed", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=0, help="seed of the restarts' starting points")
    ap.add_argument("--ref-seeds", type=int, nargs="+", default=[3],
                    help="hand_moved seeds of the 10 s tuning trajectories (cost = mean over them)")
    args = ap.parse_args(argv)
    res = tune(args.family, args.restarts, backend=args.backend, workers=args.workers, maxfev=args.maxfev,
               speed=args.speed, seed=args.seed, ref_seed=args.ref_seeds)
    print(json.dumps({"best": res["best"], "restarts": res["restarts"]}, indent=1))


if __name__ == "__main__":
    main()
