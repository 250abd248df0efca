"""Paper 000 Sec. III-A "Static Characteristics", Fig. 6(b-c): the jet pipe's position against
the force on its tip, and the tip force against the coil current.

The paper: (b) forces applied directly to the tip by hanging masses (downwards only) showed
"a significant amount of hysteresis in the position/force relationship as well", with the major
loop's halves "almost constant" 0.16 mm apart (8 % of the 1 mm range); (c) the force/current
curve "shows only a slight amount of hysteresis and is linear within the actuator's rated
current limits of +-0.4 A", k_m = 1.946 N/A.  Since (c) is nearly hysteresis-free, the
hysteresis of Fig. 6(a) sits between tip force and position.

The model puts it exactly there (:mod:`pneumatics.jetpipe.hysteresis` acting on F = k_m i,
then the static nonlinearity f3, eq. 2), so this scenario shows the model's statics, quasi-
statically (no dynamics): a slow force cycle to the jet's saturation and back, and the
force/current line over the rated current.  Every number here is an input or follows from
inputs: ``position_loop_gap_mm`` (the distance between the branches at zero force, paper
0.16 mm), ``gap_spread_mm`` (how constant it is over the middle of the range),
``force_constant_n_per_a`` (the slope of (c)).
"""
from __future__ import annotations

import numpy as np

import models
from pneumatics.jetpipe.hysteresis import PlayHysteresis
from pneumatics.jetpipe.params import load_jetpipe_cfg
from pneumatics.jetpipe.valve import static_position, tip_force

from .common import main, plt

SUMMARY = "Fig. 6(b-c): jet position vs tip force (hysteresis) and tip force vs current (linear)"


def force_cycle(max_force_n: float, n: int):
    """Tip force [N] (2n,): 0 -> +max -> -max -> +max, the last two legs being the major loop."""
    up = np.linspace(0.0, max_force_n, n // 2)
    down = np.linspace(max_force_n, -max_force_n, n)
    return np.concatenate([up, down, -down])


def run(ctx):
    cfg = load_jetpipe_cfg(models.fluid_path("jetpipe"))
    n = 400 if ctx.fast else 2000
    f_max = 3.0 * cfg.jet.saturation_force_n  # tanh(3) = 0.995: into saturation
    force = force_cycle(f_max, n)
    hyst = PlayHysteresis(cfg.hysteresis_half_width_n, cfg.hysteresis.n_operators)
    x = static_position(hyst.trace(force), cfg.jet)
    leg = n // 2 + n  # the rising leg starts here
    f_down, x_down = force[n // 2:leg][::-1], x[n // 2:leg][::-1]
    f_up, x_up = force[leg:], x[leg:]
    grid = np.linspace(-0.5, 0.5, 21) * cfg.jet.saturation_force_n  # the middle of the range
    gap = np.interp(grid, f_down, x_down) - np.interp(grid, f_up, x_up)
    current = np.linspace(-cfg.driver.current_limit_a, cfg.driver.current_limit_a, 81)
    f_tip = tip_force(current, cfg.driver)
    slope = float(np.polyfit(current, f_tip, 1)[0])
    metrics = {"position_loop_gap_mm": float(1e3 * (np.interp(0.0, f_down, x_down) - np.interp(0.0, f_up, x_up))),
               "gap_spread_mm": float(1e3 * np.ptp(gap)), "force_constant_n_per_a": slope,
               "position_range_mm": float(1e3 * np.ptp(x))}

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    axes[0].plot(f_up * 1e3, x_up * 1e3, "C0-", label="force rising")
    axes[0].plot(f_down * 1e3, x_down * 1e3, "C3-", label="force falling")
    axes[0].set_xlabel("tip force [mN]")
    axes[0].set_ylabel("jet position [mm]")
    axes[0].set_title(f"(b) position vs tip force: branches {metrics['position_loop_gap_mm']:.3f} mm apart "
                      "(paper 0.16)", fontsize=10)
    axes[1].plot(current, f_tip * 1e3, "k-")
    axes[1].set_xlabel("coil current [A]")
    axes[1].set_ylabel("tip force [mN]")
    axes[1].set_title(f"(c) tip force vs current: k_m = {slope:.3f} N/A (paper 1.946)", fontsize=10)
    for a in axes:
        a.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Fig. 6(b-c): the model's jet-pipe statics (hysteresis between tip force and position)")
    fig.tight_layout()
    ctx.savefig(fig, "jet_statics.png")
    return metrics


if __name__ == "__main__":
    main(__name__)
