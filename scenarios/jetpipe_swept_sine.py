"""Paper 000 Sec. III-A "Dynamic Characteristics", Fig. 7: the jet pipe's swept-sine frequency
response (jet position / coil current) against the third-order model of eq. 3.

The "measured" response is the simulator's whole nonlinear valve: current driver (1122 Hz),
Prandtl-Ishlinskii hysteresis (8 % of the range), the tanh static nonlinearity and eq. 3's
dynamics (:mod:`pneumatics.jetpipe.jet_sweep`), driven by a stepped sine about zero current.
A third-order model (DC gain, w1, w2, zeta) is fitted to it below 700 Hz, as the paper did;
``model_fit_r2`` is the complex R^2 of that fit with hysteresis at the main amplitude (0.04 A,
~+-0.27 mm of jet travel, a quarter of the range).  The paper's own parameters are inputs of
the simulator, so the fitted w1, w2, zeta show what the driver and the hysteresis do to them.
The same fit on the hysteresis-free valve separates the two.
"""
from __future__ import annotations

import numpy as np

import models
from pneumatics.jetpipe.jet_sweep import fit_third_order, jet_frequency_response, third_order
from pneumatics.jetpipe.params import load_jetpipe_cfg

from .common import main, plt

SUMMARY = "Fig. 7: jet-pipe swept-sine response (nonlinear valve) against a fitted third-order model"

MAIN_AMPLITUDE_A = 0.04
PAPER = {"omega1_rad_s": 973.8, "omega2_rad_s": 1856.7, "zeta": 0.419}


def run(ctx):
    cfg = load_jetpipe_cfg(models.fluid_path("jetpipe"))
    if ctx.fast:
        freqs, amps = np.logspace(np.log10(30.0), np.log10(1000.0), 10), [MAIN_AMPLITUDE_A]
    else:
        freqs, amps = np.logspace(1.0, 3.0, 25), [0.02, MAIN_AMPLITUDE_A]
    cases = {}
    for amp in amps:
        for hyst in (True, False):
            resp = jet_frequency_response(cfg, freqs, amp, hysteresis=hyst)
            cases[(amp, hyst)] = (resp, fit_third_order(resp))
    resp, fit = cases[(MAIN_AMPLITUDE_A, True)]
    _, fit_nh = cases[(MAIN_AMPLITUDE_A, False)]
    metrics = {"model_fit_r2": fit.r2, "model_fit_r2_db": fit.r2_db,
               "fit_omega1_rad_s": fit.omega1_rad_s, "fit_omega2_rad_s": fit.omega2_rad_s,
               "fit_zeta": fit.zeta, "fit_dc_gain_mm_per_a": fit.gain_m_per_a * 1e3,
               "model_fit_r2_no_hysteresis": fit_nh.r2, "fit_omega1_rad_s_no_hysteresis": fit_nh.omega1_rad_s,
               "fit_omega2_rad_s_no_hysteresis": fit_nh.omega2_rad_s, "fit_zeta_no_hysteresis": fit_nh.zeta,
               "amplitude_a": MAIN_AMPLITUDE_A}
    for (amp, hyst), (_, ft) in cases.items():
        if amp != MAIN_AMPLITUDE_A:
            metrics[f"model_fit_r2_{amp * 1e3:.0f}ma{'' if hyst else '_no_hysteresis'}"] = ft.r2
    _plot(ctx, cases, resp, fit)
    return metrics


def _plot(ctx, cases, resp, fit):
    fine = np.logspace(np.log10(resp.freq_hz[0]), np.log10(resp.freq_hz[-1]), 300)
    fig, (ax_m, ax_p) = plt.subplots(2, 1, figsize=(7.5, 7), sharex=True)
    styles = {True: "o", False: "^"}
    for (amp, hyst), (r, _) in cases.items():
        label = f"simulated valve, {amp * 1e3:.0f} mA{'' if hyst else ', no hysteresis'}"
        ax_m.semilogx(r.freq_hz, 20 * np.log10(np.abs(r.gain_m_per_a) * 1e3), styles[hyst], ms=4,
                      mfc="none" if amp != MAIN_AMPLITUDE_A else None, label=label)
        ax_p.semilogx(r.freq_hz, np.degrees(np.unwrap(np.angle(r.gain_m_per_a))), styles[hyst], ms=4,
                      mfc="none" if amp != MAIN_AMPLITUDE_A else None)
    h_fit = fit.predict(fine)
    h_paper = third_order(fine, fit.gain_m_per_a, PAPER["omega1_rad_s"], PAPER["omega2_rad_s"], PAPER["zeta"])
    ax_m.semilogx(fine, 20 * np.log10(np.abs(h_fit) * 1e3), "k-",
                  label=f"third-order fit (< 700 Hz): w1 {fit.omega1_rad_s:.0f}, w2 {fit.omega2_rad_s:.0f} rad/s, "
                        f"zeta {fit.zeta:.2f}; R² {fit.r2:.3f}")
    ax_m.semilogx(fine, 20 * np.log10(np.abs(h_paper) * 1e3), "k--", lw=0.9,
                  label="eq. 3 with the paper's w1 973.8, w2 1856.7, zeta 0.419")
    ax_p.semilogx(fine, np.degrees(np.unwrap(np.angle(h_fit))), "k-")
    ax_p.semilogx(fine, np.degrees(np.unwrap(np.angle(h_paper))), "k--", lw=0.9)
    for a in (ax_m, ax_p):
        a.axvline(700, color="grey", lw=0.8, ls=":")
        a.grid(True, which="both", alpha=0.3)
    ax_m.set_ylabel("|x_jp / i| [dB re 1 mm/A]")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    ax_m.legend(fontsize=7, loc="lower left")
    ax_m.set_title("Fig. 7: jet-pipe frequency response, swept sine about 0 A")
    ctx.savefig(fig, "swept_sine.png")


if __name__ == "__main__":
    main(__name__)
