"""The jet pipe's position/current frequency response and its third-order fit (paper 000 Sec. III-A,
"Dynamic Characteristics", Fig. 7).

The paper drove the valve coil with a swept sine, measured the jet tip with a position-sensitive
detector and fitted the third-order model of eq. 3,

    X(s) / I(s) = G * w1 / (s + w1) * w2^2 / (s^2 + 2 zeta w2 s + w2^2),

finding w1 = 973.8 rad/s, w2 = 1856.7 rad/s, zeta = 0.419 and a good fit below ~700 Hz.

Here the "measured" response is that of the whole nonlinear valve of :mod:`.valve` and
:mod:`.hysteresis`: the first-order current driver (1122 Hz), the tip force k_m i, the
Prandtl-Ishlinskii hysteresis, the static tanh nonlinearity f3 and the jet dynamics of eq. 3.
Every frequency of the stepped sine is integrated at once (one column per frequency) with
classical RK4 at a fixed step far below every time constant; the play operators' memory is
held over each step and advanced at its end, while their output follows the current at every
RK4 stage (so the static path has no half-step delay).  The fundamental of input and output over
whole periods after settling gives the complex gain (:func:`.freqresp.fundamental`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..errors import PneumasimError
from .freqresp import fundamental
from .hysteresis import play_radii
from .params import JetpipeCfg
from .valve import driver_omega, jet_matrices, static_position

#: RK4 step [s]: h * 7050 rad/s (driver pole) = 0.14 and 2 pi 1 kHz * h = 0.06 rad per step
STEP_S = 2e-5


@dataclass
class JetResponse:
    """Complex gains x_jp / i_cmd [m/A] (F,) at ``freq_hz`` (F,), from one stepped-sine run."""

    freq_hz: np.ndarray
    gain_m_per_a: np.ndarray
    amplitude_a: float
    mean_a: float
    hysteresis: bool


def jet_frequency_response(cfg: JetpipeCfg, freq_hz, amplitude_a: float, mean_a: float = 0.0, *,
                           hysteresis: bool = True, settle_periods: float = 3.0,
                           periods: float = 2.0) -> JetResponse:
    """Stepped-sine response of the jet position to the current command i = mean + amp sin(w t).

    All frequencies run in parallel for the time the lowest one needs; each is analysed over its
    last ``periods`` whole periods (at least ``settle_periods`` periods after the start)."""
    f = np.asarray(freq_hz, float)
    if f.ndim != 1 or f.size == 0 or np.any(f <= 0):
        raise PneumasimError(f"jet frequency response: frequencies must be positive, got {freq_hz!r}")
    if not 0 < amplitude_a <= cfg.driver.current_limit_a:
        raise PneumasimError(f"jet frequency response: amplitude {amplitude_a} A outside (0, "
                             f"{cfg.driver.current_limit_a}] A, the driver's rated current")
    duration = (settle_periods + periods) / f.min()
    n = int(np.ceil(duration / STEP_S))
    w = 2 * np.pi * f
    a_jet, b_jet = jet_matrices(cfg.jet)
    wd, km = driver_omega(cfg.driver), cfg.driver.force_constant_n_per_a
    limit = cfg.driver.current_limit_a
    radii = play_radii(cfg.hysteresis_half_width_n if hysteresis else 0.0, cfg.hysteresis.n_operators)
    # steady start at the mean current: driver, plays and jet states at their static values
    cur = np.full(f.size, mean_a)
    plays = np.full((f.size, radii.size), km * mean_a)
    z = np.tile(np.array([1.0, 1.0, 0.0]), (f.size, 1)) * float(static_position(km * mean_a, cfg.jet))
    z[:, 2] = 0.0
    record_from = np.maximum(duration - periods / f, settle_periods / f)
    t_rec = np.arange(n + 1) * STEP_S
    x_out = np.empty((n + 1, f.size))
    x_out[0] = z[:, 1]

    def rates(t, i, zz):
        # the plays' memory is held over the step; their output follows the stage's current
        force = km * i[:, None]
        x_static = static_position(np.clip(plays, force - radii, force + radii).mean(axis=1), cfg.jet)
        cmd = np.clip(mean_a + amplitude_a * np.sin(w * t), -limit, limit)
        return wd * (cmd - i), zz @ a_jet.T + b_jet[None, :] * x_static[:, None]

    for k in range(n):
        t = k * STEP_S
        k1 = rates(t, cur, z)
        k2 = rates(t + STEP_S / 2, cur + STEP_S / 2 * k1[0], z + STEP_S / 2 * k1[1])
        k3 = rates(t + STEP_S / 2, cur + STEP_S / 2 * k2[0], z + STEP_S / 2 * k2[1])
        k4 = rates(t + STEP_S, cur + STEP_S * k3[0], z + STEP_S * k3[1])
        cur = cur + STEP_S / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        z = z + STEP_S / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        np.clip(plays, km * cur[:, None] - radii, km * cur[:, None] + radii, out=plays)
        x_out[k + 1] = z[:, 1]
    gains = np.empty(f.size, complex)
    for j in range(f.size):
        keep = (t_rec >= record_from[j]) & (t_rec <= record_from[j] + periods / f[j])
        t = t_rec[keep]
        g_in = fundamental(t, mean_a + amplitude_a * np.sin(w[j] * t), f[j])
        gains[j] = fundamental(t, x_out[keep, j], f[j]) / g_in
    return JetResponse(f, gains, amplitude_a, mean_a, hysteresis)


def third_order(freq_hz, gain: float, omega1: float, omega2: float, zeta: float) -> np.ndarray:
    """Eq. 3 with a DC gain [m/A]: G w1/(s + w1) w2^2/(s^2 + 2 zeta w2 s + w2^2) at s = j 2 pi f."""
    s = 2j * np.pi * np.asarray(freq_hz, float)
    return gain * omega1 / (s + omega1) * omega2 ** 2 / (s * s + 2 * zeta * omega2 * s + omega2 ** 2)


@dataclass
class ThirdOrderFit:
    """Eq. 3's parameters fitted to a response, and how well they describe it below ``max_hz``."""

    gain_m_per_a: float
    omega1_rad_s: float
    omega2_rad_s: float
    zeta: float
    r2: float          # 1 - sum|H - H_fit|^2 / sum|H - mean H|^2 over the fitted band (complex)
    r2_db: float       # the same on the magnitude in dB
    max_hz: float

    def predict(self, freq_hz) -> np.ndarray:
        return third_order(freq_hz, self.gain_m_per_a, self.omega1_rad_s, self.omega2_rad_s, self.zeta)


def fit_third_order(resp: JetResponse, max_hz: float = 700.0, start=(973.8, 1856.7, 0.419)) -> ThirdOrderFit:
    """Least squares on the relative complex error (every frequency weighs alike, as on a Bode
    plot) over the frequencies up to ``max_hz`` (paper: the model fits 'for frequencies below
    ~700 Hz')."""
    keep = resp.freq_hz <= max_hz
    if keep.sum() < 5:
        raise PneumasimError(f"third-order fit: only {int(keep.sum())} frequencies below {max_hz} Hz; need 5")
    f, h = resp.freq_hz[keep], resp.gain_m_per_a[keep]
    g0 = float(np.abs(h[0]))

    def residual(theta):
        g, w1, w2, zeta = np.exp(theta[0]) * g0, np.exp(theta[1]), np.exp(theta[2]), theta[3]
        e = (third_order(f, g, w1, w2, zeta) - h) / np.abs(h)
        return np.concatenate([e.real, e.imag])

    theta0 = np.array([0.0, np.log(start[0]), np.log(start[1]), start[2]])
    sol = optimize.least_squares(residual, theta0, bounds=([-3, 3, 3, 0.01], [3, 12, 12, 3.0]))
    g, w1, w2, zeta = np.exp(sol.x[0]) * g0, np.exp(sol.x[1]), np.exp(sol.x[2]), sol.x[3]
    fit = third_order(f, g, w1, w2, zeta)
    r2 = 1 - np.sum(np.abs(h - fit) ** 2) / np.sum(np.abs(h - h.mean()) ** 2)
    db, db_fit = 20 * np.log10(np.abs(h)), 20 * np.log10(np.abs(fit))
    r2_db = 1 - np.sum((db - db_fit) ** 2) / np.sum((db - db.mean()) ** 2)
    return ThirdOrderFit(float(g), float(w1), float(w2), float(zeta), float(r2), float(r2_db), max_hz)
