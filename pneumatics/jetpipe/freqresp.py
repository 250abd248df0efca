"""Frequency responses by stepped sine, as a swept-sine analyser (HP 35665A, paper 000 Sec. IV)
measures them: one frequency at a time, let the response settle, then take the fundamental of
input and output by least squares (a + b sin + c cos) over whole periods.
"""
from __future__ import annotations

import numpy as np


def fundamental(time_s, signal, freq_hz) -> complex:
    """Complex amplitude (b_cos... as a phasor) of the ``freq_hz`` component of ``signal``."""
    w = 2 * np.pi * freq_hz * np.asarray(time_s, float)
    basis = np.column_stack([np.ones_like(w), np.sin(w), np.cos(w)])
    coef, *_ = np.linalg.lstsq(basis, np.asarray(signal, float), rcond=None)
    return complex(coef[1], coef[2])  # amplitude |.|, phase angle(.) relative to sin


def settle_and_window(freq_hz: float, settle_periods: float, periods: float, min_settle_s: float = 0.3):
    """(settle time, window length) [s] for one stepped-sine point."""
    period = 1.0 / freq_hz
    settle = max(settle_periods * period, min_settle_s)
    return settle, periods * period


def bandwidth_hz(freq_hz, gain, reference_gain: float | None = None) -> float:
    """-3 dB frequency [Hz]: the first crossing of |gain| below 1/sqrt(2) of ``reference_gain``
    (default: |gain| at the lowest frequency), log-interpolated; NaN if never crossed, the
    highest frequency tested is then a lower bound."""
    f = np.asarray(freq_hz, float)
    g = np.abs(np.asarray(gain))
    ref = g[0] if reference_gain is None else reference_gain
    m = g / ref
    below = np.nonzero(m < 1 / np.sqrt(2))[0]
    if below.size == 0:
        return float("nan")
    k = below[0]
    if k == 0:
        return float(f[0])
    lf = np.interp(np.log(1 / np.sqrt(2)), [np.log(m[k]), np.log(m[k - 1])], [np.log(f[k]), np.log(f[k - 1])])
    return float(np.exp(lf))


def sine_gain(sim, controller, freq_hz: float, input_column: str, reset_force_n: float | None,
              settle_periods: float = 2.0, periods: float = 2.0, record_hz: float = 2000.0):
    """Run one stepped-sine point on ``sim`` (a JetpipeSim) with ``controller`` and return
    (complex gain force/input at ``freq_hz``, recording).  The sim is reset to a steady
    ``reset_force_n`` first; the first ``settle_periods`` periods are discarded."""
    settle, window = settle_and_window(freq_hz, settle_periods, periods)
    sim.reset(reset_force_n)
    rec = sim.run(controller, settle + window, record_hz=record_hz)
    keep = rec.time >= rec.time[-1] - window
    t = rec.time[keep]
    g_in = fundamental(t, rec[input_column][keep], freq_hz)
    g_out = fundamental(t, rec["force.piston"][keep], freq_hz)
    return g_out / g_in, rec
