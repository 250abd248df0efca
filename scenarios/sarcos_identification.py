"""Paper 001 §3.2: identify D_v, the shaft stiffness, Coulomb friction and the vane leakage
from simulated recordings with sensor noise, by regression, as the paper does on the robot.

Three experiments, each recorded at 100 Hz with the white noise of fluid.toml [sensors]
(angles 3e-4 rad, pressures 20 kPa, torque 0.1 N m, graduated-cylinder readings):

1. **Shaft stiffness** (§3.2.2, Fig. 3): brace on, i = 0.3 sin(t).  The vane turns against the
   locked load by the twist of the shaft: joint torque vs motor angle is a straight line of
   slope k_s.  The twist is small (~0.2 deg at 30 N m), so the angle noise is not small
   against its range; regressing torque on angle would be biased low by the errors in the
   regressor (attenuation, ~5 % here).  The angle is regressed on the (relatively far less
   noisy) torque instead, k_s = 1 / slope.  The brace's own compliance biases it by ~1 %.
2. **Displacement and Coulomb friction** (§3.2.3, Fig. 4): brace on, i = 0.3 sin(t); the vane
   slides back and forth by the shaft's twist, so torque vs load pressure shows inclined
   segments of slope D_v (sliding) joined by horizontal ones (stuck).  On the sliding
   samples (|d tau/dt| large, from a Savitzky-Golay derivative of the measured torque; the
   vane velocity is dtau/dt / k_s) the vane equation (13)
       tau = D_v P_L - tau_c sign(omega_v)
   is fitted by least squares: slope D_v, and tau_c from the difference between the torque
   and D_v P_L ("the difference between the measured torque and the applied torque from
   pressure measurements is used to identify the Coulomb friction").  The viscous and inertial
   terms of eq. 13 are left out: the vane moves at ~3 mrad/s here, so b omega_v and
   J_v d omega_v/dt are below 0.01 N m, and a velocity regressor nearly collinear with
   sign(omega_v) would only trade off against tau_c.
   The paper ran this with the elbow free; our forearm's weight (3.7 N m) gives the free arm
   a torque range too small for a good slope, the braced test gives +-30 N m.
3. **Leakage coefficient** (§3.1-3.2.3): brace on, the manifold feeds port a from a pressure
   tap and routes port b into a graduated cylinder at tank pressure; the collected volume is
   read every 50 ms.  Leak flow = slope of volume vs time; R_l = least-squares slope of flow
   vs measured P_a - P_b over four tap pressures.

Metrics: the relative error of each estimate against the model's own value (D_v and R_l
from fluid.toml, k_s and tau_c from the MJCF), which the regressions never read.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import savgol_filter

from pneumatics.hydraulics import Port, load_hydraulic, run_current

from .common import main, plt

SUMMARY = "§3.2: regress D_v, shaft stiffness, Coulomb friction and vane leakage from noisy recordings"
CYLINDER_NOISE_M3 = 1e-8      # 0.01 cm^3 reading noise of the graduated cylinder
TAP_AREA_M2 = 2e-6            # manifold fittings: wide open compared to the leak
READ_PERIOD_S = 0.05


def fit_line(x, y):
    """Least squares y = a x + b; returns (a, b, standard error of a)."""
    A = np.column_stack([x, np.ones_like(x)])
    coef, res, *_ = np.linalg.lstsq(A, y, rcond=None)
    dof = max(len(x) - 2, 1)
    s2 = float(res[0]) / dof if res.size else 0.0
    cov = s2 * np.linalg.inv(A.T @ A)
    return float(coef[0]), float(coef[1]), float(np.sqrt(cov[0, 0]))


def identify_stiffness(rec):
    """(k_s, its standard error) from motor (vane) angle vs joint torque, load braced."""
    compliance, _, se = fit_line(rec["tau.elbow"], rec["q.elbow"])
    return 1.0 / compliance, se / compliance ** 2


def identify_displacement_friction(rec, k_s_est: float):
    """(D_v, tau_c, sliding mask) from torque vs load pressure (eq. 13 on sliding samples)."""
    dt = float(np.median(np.diff(rec.time)))
    tau = rec["tau.elbow"]
    p_l = rec["p_a.elbow"] - rec["p_b.elbow"]
    # vane velocity with the load braced: the shaft twist rate, d tau/dt / k_s
    omega_v = savgol_filter(tau, 31, 2, deriv=1, delta=dt) / k_s_est
    sliding = np.abs(omega_v) > 0.25 * np.abs(omega_v).max()
    A = np.column_stack([p_l, -np.sign(omega_v)])[sliding]
    coef, *_ = np.linalg.lstsq(A, tau[sliding], rcond=None)
    return float(coef[0]), float(coef[1]), sliding


def leak_test(sim, tap_pa: float, duration_s: float, rng):
    """One manifold test: returns (times, noisy cylinder volume, noisy mean P_a - P_b)."""
    sim.reset(braced=True)
    tank = sim.cfg.power.tank_pa
    sim.set_ports(Port("tap", tap_pa, TAP_AREA_M2), Port("tap", tank, TAP_AREA_M2))
    n_read = round(duration_s / READ_PERIOD_S)
    per_read = round(READ_PERIOD_S / sim.dt)
    times, volumes, dps = [], [], []
    for _ in range(n_read):
        sim.step(per_read)
        times.append(sim.time)
        volumes.append(sim.circuit.tap_volume_m3[1])
        dps.append(sim.pressures["a"] - sim.pressures["b"])
    noise_p = sim.cfg.sensors.pressure_noise_pa
    volumes = np.array(volumes) + rng.normal(0, CYLINDER_NOISE_M3, n_read)
    dps = np.array(dps) + rng.normal(0, noise_p * math.sqrt(2), n_read)
    sim.set_ports("valve", "valve")
    return np.array(times), volumes, dps


def identify_leak(tests):
    """R_l from [(times, volumes, dps)]: flow per test by regression, then flow vs dp."""
    flows, dps = [], []
    for times, volumes, dp in tests:
        keep = times >= times[0] + 0.1  # skip the fill transient of the first 0.1 s
        q, _, _ = fit_line(times[keep], volumes[keep])
        flows.append(q)
        dps.append(dp[keep].mean())
    flows, dps = np.array(flows), np.array(dps)
    r_l = float(flows @ dps / (dps @ dps))  # through the origin: no flow without a difference
    return r_l, flows, dps


def run(ctx):
    rng = np.random.default_rng(2026)
    sim = load_hydraulic("sarcos_elbow")
    truth = {"dv": sim.d_v, "ks": sim.shaft_stiffness_nm_per_rad, "coulomb": sim.coulomb_friction_nm,
             "leak": sim.cfg.vane.leak_coefficient_m3_per_pa_s}

    # 1 + 2: braced, i = 0.3 sin(t); fast: past the peak and through the swing back (4.2 s)
    duration = 4.2 if ctx.fast else 2 * 2 * math.pi
    sim.reset(braced=True)
    rec = run_current(sim, lambda t: 0.3 * math.sin(t), duration, noise=True, rng=rng,
                      name="locked_0.3a_noisy")
    ctx.save_recording(rec, "locked_noisy.csv")
    logger = ctx.rerun_logger(sim.rerun_robot(), "sarcos_identification")
    if logger is not None:
        logger.log_recording(rec, prefix="measured", bodies=True)
        logger.close()
    k_s, k_se = identify_stiffness(rec)
    d_v, tau_c, sliding = identify_displacement_friction(rec, k_s)

    # 3: leak tests at four tap pressures
    pressures = (5e6, 10e6, 15e6, 20e6)
    tests = [leak_test(sim, p + sim.cfg.power.tank_pa, 0.6 if ctx.fast else 2.0, rng) for p in pressures]
    r_l, _flows, _dps = identify_leak(tests)

    est = {"dv": d_v, "ks": k_s, "coulomb": tau_c, "leak": r_l}
    metrics = {f"{k}_rel_err": abs(est[k] - truth[k]) / truth[k] for k in truth}
    metrics.update({
        "dv_est_cm3_per_rad": d_v * 1e6, "ks_est_nm_per_rad": k_s, "ks_stderr_nm_per_rad": k_se,
        "coulomb_est_nm": tau_c,
        "leak_est_m3_per_mpa_s": r_l * 1e6, "sliding_fraction": float(sliding.mean()),
    })

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    ax = axes[0]
    ax.plot(np.degrees(rec["q.elbow"]), rec["tau.elbow"], ".", ms=2, label="recorded (noisy)")
    q = np.linspace(rec["q.elbow"].min(), rec["q.elbow"].max(), 2)
    ax.plot(np.degrees(q), k_s * (q - (rec["q.elbow"] - rec["tau.elbow"] / k_s).mean()), "r",
            label=f"k_s = {k_s:.0f} N m/rad (model {truth['ks']:.0f})")
    ax.set_xlabel("motor angle [deg]")
    ax.set_ylabel("joint torque [N m]")
    ax.set_title("shaft stiffness, load braced (paper Fig. 3)", fontsize=10)
    ax.legend(fontsize=8)
    ax = axes[1]
    p_l = (rec["p_a.elbow"] - rec["p_b.elbow"]) / 1e6
    ax.plot(p_l[~sliding], rec["tau.elbow"][~sliding], ".", ms=2, color="0.6", label="stuck / reversing")
    ax.plot(p_l[sliding], rec["tau.elbow"][sliding], ".", ms=2, label="sliding (fitted)")
    pl = np.linspace(p_l.min(), p_l.max(), 2)
    for s in (1, -1):
        ax.plot(pl, d_v * pl * 1e6 - s * tau_c, "r", lw=1)
    ax.set_xlabel("load pressure P_a - P_b [MPa]")
    ax.set_ylabel("joint torque [N m]")
    ax.set_title(f"D_v = {d_v * 1e6:.3f} cm^3/rad (model {truth['dv'] * 1e6:.2f}), "
                 f"tau_c = {tau_c:.2f} N m (model {truth['coulomb']:.2f})  (Fig. 4)", fontsize=9)
    ax.legend(fontsize=8)
    ax = axes[2]
    for (times, volumes, _), p in zip(tests, pressures):
        ax.plot(times - times[0], volumes * 1e6, ".", ms=3, label=f"tap {p / 1e6:.0f} MPa")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("collected volume [cm^3]")
    ax.set_title(f"vane leakage: R_l = {r_l * 1e6:.3g} m^3/(MPa s) (model "
                 f"{truth['leak'] * 1e6:.3g})", fontsize=10)
    ax.legend(fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    ctx.savefig(fig, "identification.png")
    return metrics


if __name__ == "__main__":
    main(__name__)
