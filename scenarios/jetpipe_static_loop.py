"""Paper 000 Sec. III-B, Figs. 6a and 9: the static force/current hysteresis loop of the jet-pipe
actuator, and the paper's identification of the discharge coefficient, the jet offset and the
piston leakage from it by downhill simplex.

The current is ramped slowly up and down between the force saturation points (major loop), then
twice around two minor loops.  As in the paper, the fit uses the measured jet position loop
(what the PSD sees, without the offset) and the measured force loop: the model is the steady
force F(x_jp + x_offset; C_d, C_dm A, C_dc A) of eqs. 4-13, the parameters minimise the squared
force error (scipy Nelder-Mead) from a deliberately wrong start.  We have no copy of the paper's
data, so the "measurement" is this simulator's run with the paper's values: the fit shows
how well a static model describes a slow dynamic loop and what the loop can identify.  The
steady pressures depend only on ratios of effective areas, so C_d and the two leak areas are
identifiable only as leak/C_d ratios (the paper obtained the leakage "in combination with" the
discharge coefficient); the offset is identifiable.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from pneumatics.jetpipe.chambers import piston_force, static_pressures
from pneumatics.jetpipe.sim import JetpipeSim, OpenLoopCurrent
from pneumatics.jetpipe.statics import static_curve

from .common import main, plt

SUMMARY = "Figs. 6a/9: force/current major and minor hysteresis loops; C_d, offset, leak by Nelder-Mead"

LOW_A, HIGH_A = -0.05, 0.10           # past the force saturation points (0 N and ~57 N), far
                                       # enough for every play operator to be dragged
MINOR_A = [(0.045, 0.025), (0.040, 0.010)]   # (reversal on the way down, turning point on the way up)


def waypoints(minor_loops):
    """(M,) current turning points: up-down major loop, then each minor loop twice, each
    entered from below so that both cycles start from a top reached on the way up."""
    pts = [0.0, LOW_A, HIGH_A, LOW_A]
    for top, bottom in minor_loops:
        pts += [bottom, top, bottom, top, bottom, top]
    return np.array(pts)


def profile(rate_a_per_s: float, minor_loops):
    """Piecewise-linear current command: (fn(t), knot times (M,), duration)."""
    pts = waypoints(minor_loops)
    times = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(pts)) / rate_a_per_s)])
    return (lambda t: float(np.interp(t, times, pts))), times, float(times[-1])


def model_force(params, x_jp, cfg, warm):
    cd, off, slope, lo = params
    c = cfg.replace("ports", discharge_coefficient=float(np.clip(cd, 0.05, 1.0))).replace(
        "leak", slope_m2=slope * 1e-7, offset_m2=max(lo * 1e-7, 0.0))
    p1, p2 = static_pressures(x_jp + off * 1e-4, c, iterations=60, p0=warm.get("p"))
    warm["p"] = np.stack([p1, p2])
    return np.maximum(piston_force(p1, p2, c), 0.0)


def run(ctx):
    sim = JetpipeSim()
    cfg = sim.cfg
    # A/s: slow against the chamber time constant (~0.07-0.2 s), as the paper's slow ramps
    rate = 0.05 if ctx.fast else 0.004
    minor = MINOR_A[:1] if ctx.fast else MINOR_A
    fn, knots, duration = profile(rate, minor)
    sim.reset(None)
    rec = sim.run(OpenLoopCurrent(fn), duration, record_hz=100.0)
    t, i_cmd, force, x_jp = rec.time, rec["i_cmd.piston"], rec["force.piston"], rec["x_jet.piston"]
    major = (t >= knots[1]) & (t <= knots[3])  # the major loop, up then down
    n_fit = 30 if ctx.fast else 120
    idx = np.nonzero(major)[0]
    idx = idx[np.linspace(0, idx.size - 1, n_fit).astype(int)]
    truth = np.array([cfg.ports.discharge_coefficient, cfg.jet.offset_m / 1e-4,
                      cfg.leak.slope_m2 / 1e-7, cfg.leak.offset_m2 / 1e-7])
    res, fitted = _fit_static_model(cfg, x_jp[idx], force[idx], truth, ctx.fast)
    rmse = float(np.sqrt(np.mean((fitted - force[idx]) ** 2)))
    # hysteresis widths: jet loop (Fig. 6a) and force loop, between the up and down branches
    up = major & (np.gradient(i_cmd) > 0)
    down = major & (np.gradient(i_cmd) < 0)
    grid = np.linspace(-0.005, 0.005, 11)  # about the centre (x_st = 0), where the paper measures

    def branch(mask, y):
        o = np.argsort(i_cmd[mask])
        return np.interp(grid, i_cmd[mask][o], y[mask][o])

    jet_gap = branch(down, x_jp) - branch(up, x_jp)
    jet_half_width_pct = float(np.median(jet_gap) / 2 / (2 * cfg.jet.saturation_m) * 100)
    # minor loops close: after each cycle the force returns to the same point at the top
    closure = []
    for k in range(len(minor)):
        k0 = 5 + 6 * k  # index in waypoints of this loop's first top
        ends = [np.interp(knots[k0 + 2 * c], t, force) for c in (1, 2)]  # tops after cycles 1, 2
        closure.append(float(abs(ends[1] - ends[0])))
    _plot(ctx, cfg, i_cmd, force, x_jp, idx, fitted, rmse, jet_half_width_pct)
    return {
        "loop_fit_rmse_n": rmse,
        "cd_fit": float(res.x[0]), "cd_true": float(truth[0]),
        "offset_fit_mm": float(res.x[1] * 0.1), "offset_true_mm": float(truth[1] * 0.1),
        "leak_slope_fit_mm2": float(res.x[2] * 0.1), "leak_slope_true_mm2": float(truth[2] * 0.1),
        "leak_offset_fit_mm2": float(res.x[3] * 0.1), "leak_offset_true_mm2": float(truth[3] * 0.1),
        # steady pressures depend only on area ratios: C_d and the leak areas are identifiable
        # only together (the paper: leak "obtained in combination with" C_d); the ratio is
        "leak_offset_over_cd_fit_mm2": float(0.1 * res.x[3] / res.x[0]),
        "leak_offset_over_cd_true_mm2": float(0.1 * truth[3] / truth[0]),
        "fit_iterations": int(res.nit),
        "jet_hysteresis_half_width_pct": jet_half_width_pct,
        "force_loop_max_gap_n": float(np.max(branch(down, force) - branch(up, force))),
        "minor_loop_closure_n": float(max(closure)),  # force gap between passes of a loop's top
        "max_force_n": float(np.max(force)),
    }


def _fit_static_model(cfg, x_jp, force, truth, fast: bool):
    """The static model's (C_d, jet offset, leak slope, leak offset) fitted to the loop's
    (x_jp, force) samples by the downhill simplex, as the paper did; (result, fitted force)."""
    start = truth * np.array([0.8, 0.5, 0.6, 1.4])
    warm = {}

    def sse(p):
        return float(np.sum((model_force(p, x_jp, cfg, warm) - force) ** 2))

    # downhill simplex, restarted at its own minimum as Numerical Recipes (the paper's [24])
    # advises, since a collapsed simplex can stop short of the minimum
    options = {"maxfev": 120 if fast else 1000, "xatol": 1e-4, "fatol": 1e-3}
    res = minimize(sse, start, method="Nelder-Mead", options=options)
    for _ in range(0 if fast else 3):
        again = minimize(sse, res.x, method="Nelder-Mead", options=options)
        improved = again.fun < res.fun * (1 - 1e-4)
        again.nit += res.nit
        res = again if again.fun <= res.fun else res
        if not improved:
            break
    warm.clear()
    return res, model_force(res.x, x_jp, cfg, warm)


def _plot(ctx, cfg, i_cmd, force, x_jp, idx, fitted, rmse, jet_half_width_pct):
    """Figs. 9a, 6a and 9b side by side."""
    curve = static_curve(cfg)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    ax = axes[0]
    ax.plot(i_cmd * 1e3, force, lw=0.8, label="simulated (major + minor loops)")
    ax.plot(curve.current_a * 1e3, curve.force_n, "k--", lw=1, label="midpoint line f (no hysteresis)")
    ax.set_xlabel("current [mA]")
    ax.set_ylabel("actuator force [N]")
    ax.set_title("Fig. 9a: force vs current")
    ax.legend(fontsize=8)
    ax = axes[1]
    ax.plot(i_cmd * 1e3, x_jp * 1e3, lw=0.8)
    ax.set_xlabel("current [mA]")
    ax.set_ylabel("jet position x_jp [mm]")
    ax.set_title(f"Fig. 6a: jet vs current (half-width {jet_half_width_pct:.1f} %)")
    ax = axes[2]
    ax.plot(x_jp[idx] * 1e3, force[idx], ".", label="'measured' major loop")
    o = np.argsort(x_jp[idx])
    ax.plot(x_jp[idx][o] * 1e3, fitted[o], "-", label=f"fitted static model (rmse {rmse:.2f} N)")
    ax.set_xlabel("jet position x_jp [mm]")
    ax.set_ylabel("actuator force [N]")
    ax.set_title("Fig. 9b: force vs jet, Nelder-Mead fit")
    ax.legend(fontsize=8)
    for a in axes:
        a.grid(alpha=0.3)
    ctx.savefig(fig, "static_loop.png")


if __name__ == "__main__":
    main(__name__)
