"""Name: Coulomb friction or stiction, from the torque a stuck joint holds.

The torque balance's friction terms are functions of the measured velocity, and a joint that
really sticks shows none: while it is stuck the friction holds whatever net torque acts on it,
up to the static level F_s, and the joint moves off when that torque exceeds F_s (Karnopp 1985,
ASME JDSMC 107:100; Armstrong-Helouvry, Dupont, Canudas de Wit 1994, Automatica 30:1083, sec.
2).  A smooth Stribeck term of the filtered velocity takes up little of it (LuGre's or
Karnopp's sticking in a recording projects onto the Coulomb level, and a Stribeck curve fitted
to the filtered velocity dips below F_c near zero instead of rising), so the search names
Coulomb friction; this module then looks at the stick phases themselves.  In them the equation
error, friction excluded, is the torque the friction held: its high quantile (HOLD_QUANTILE of
the stuck samples' short means), less what sensor noise adds to such a quantile, over the
sliding level F_c is the holding ratio, a lower bound of F_s / F_c.  Coulomb friction holds
about F_c (a tanh-regularised law creeps below it; Dahl's presliding spring saturates at it).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


#: a joint slower than this [rad/s] counts as stuck: the velocity of the doctor's parallel
#: filter wanders by ~0.01-0.02 rad/s on a joint held still, so a narrower band breaks one
#: stick phase into pieces
STUCK_RAD_S = 0.05
#: the shortest stick phase that counts [s]: a velocity reversal passes the band in less
STICK_MIN_S = 0.03
#: the stuck samples reach past the phase's end by this much [s]: the filtered velocity leaves
#: the band one or two samples after the joint moved off, at the holding torque's peak
LOOK_AFTER_S = 0.02
#: a joint faster than this [rad/s] slides: past the Stribeck velocities of the literature
#: (0.001-0.1 rad/s, Armstrong-Helouvry et al. 1994), where friction is its sliding level plus
#: a viscous part
SLIDING_RAD_S = 0.2
#: the fewest stick phases the test needs
MIN_PHASES = 10
#: the holding torque is a mean over this long [s] (5 samples at 100 Hz), against sensor noise
HOLD_MEAN_S = 0.05
#: and its HOLD_QUANTILE over the stuck samples is what the joint held: only the phases where
#: it really stuck reach F_s (most dwells are reversals passing the band), and a joint sticks
#: for a small share of the record
HOLD_QUANTILE = 0.99
#: white noise of standard deviation s raises that quantile by up to NOISE_Z s (the half-normal
#: distribution's 99 % point): subtracted, so a noisy Coulomb joint reads a ratio of 1 or less
NOISE_Z = 2.58
#: torque the model leaves out besides friction (the calibration's parameter errors) raises it
#: too: the ERROR_QUANTILE of the equation error where the joint slides, friction removed, is
#: subtracted instead when it is the larger (a weak Coulomb friction, 0.024 N m, beside 3 %
#: errors read 1.43 against the noise alone, 0.17 against this)
ERROR_QUANTILE = 0.9
#: stiction is named when the joint holds this many times its sliding friction or more (and
#: significantly above 1: Breakaway.stiction).  Set on development recordings of the random-form
#: generator (runs 5-9, 50 friction cases): its Coulomb-family friction (tanh Coulomb, Dahl,
#: pressure-dependent seals) read 0.67-1.02, LuGre with F_s 1.35-1.67 F_c 1.01-1.28; its
#: stiction, alone in a case, Karnopp 1.79-2.78, LuGre with F_s 2.7-3.8 F_c 1.36-2.26, Stribeck
#: curves peaking at 1.89-2.14 F_c 1.44-1.70, those whose tanh regularisation kept the peak at
#: 1.35-1.76 F_c 0.90-1.22.  Between 1.4 and 2 F_c a name means little: the generator
#: (variantsim-6) draws Coulomb-family LuGre up to 1.4 F_c and stiction from a 2 F_c hold on.
#: pneumasim's own friction (arm2 blind benchmark seeds 102, 1000-1005): Coulomb 0.17-0.85,
#: Stribeck stiction 2.47-3.37.
STICTION_HOLDING_RATIO = 1.3
#: and its excess over 1 this many standard errors or more.  Fewer than the keep rule's MIN_T:
#: the test adds no parameter to the fit, it chooses between two families the fit accepts
#: alike, and the bootstrap over phases is wide where a few phases held the most (a Karnopp
#: joint read 2.20 +/- 0.31)
STICTION_T = 2.0


@dataclass
class Breakaway:
    """The stick-phase test at one joint."""

    ratio: float
    """the holding ratio, a lower bound of F_s / F_c (breakaway_test)"""
    ratio_stderr: float
    """its standard error (bootstrap over the stick phases)"""
    phases: int
    """how many stick phases it was measured on"""
    coulomb_nm: float
    """the sliding level F_c it is measured against [N m] (sliding_level)"""

    @property
    def stiction(self) -> bool:
        """At or past the stiction ratio, and an excess over 1 of STICTION_T standard errors or
        more (noise on a weak friction scatters the ratio)."""
        return bool(self.phases >= MIN_PHASES and self.ratio >= STICTION_HOLDING_RATIO
                    and self.ratio - 1.0 >= STICTION_T * self.ratio_stderr)

    def evidence(self) -> str:
        return (f"the stuck joint holds {self.ratio:.2f} +/- {self.ratio_stderr:.2f} times its sliding "
                f"friction (over {self.phases} stick phases, stiction from {STICTION_HOLDING_RATIO:g} on)")


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(starts, ends) of the runs of True in ``mask`` (ends exclusive)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return edges[0::2], edges[1::2]


def stick_phases(qd: np.ndarray, ok: np.ndarray, rate_hz: float) -> list[tuple[int, int]]:
    """(start, end) sample ranges where |qd| < STUCK_RAD_S for at least STICK_MIN_S on usable
    samples (``ok``), ending before the record's last samples (the breakaway must be seen)."""
    starts, ends = _runs((np.abs(qd) < STUCK_RAD_S) & ok)
    min_len = max(int(round(STICK_MIN_S * rate_hz)), 2)
    after = int(round(LOOK_AFTER_S * rate_hz))
    return [(int(a), int(b)) for a, b in zip(starts, ends) if b - a >= min_len and b + after < len(qd)]


def sliding_fit(residual: np.ndarray, qd: np.ndarray, ok: np.ndarray) -> tuple[float, float, np.ndarray]:
    """(F_c [N m], b [N m s/rad], the sliding samples) of residual = F_c sign(qd) + b qd on the
    samples with |qd| > SLIDING_RAD_S: the level the breakaway is compared with, free of how a
    regularised law spreads Coulomb friction over the slow samples (F_c NaN without sliding
    samples in both directions)."""
    sl = ok & (np.abs(qd) > SLIDING_RAD_S)
    if np.sum(sl & (qd > 0)) < 10 or np.sum(sl & (qd < 0)) < 10:
        return np.nan, np.nan, sl
    A = np.column_stack([np.sign(qd[sl]), qd[sl]])
    fc, b = np.linalg.lstsq(A, residual[sl], rcond=None)[0]
    return float(fc), float(b), sl


def sliding_level(residual: np.ndarray, qd: np.ndarray, ok: np.ndarray) -> float:
    """F_c [N m] of :func:`sliding_fit`."""
    return sliding_fit(residual, qd, ok)[0]


def white_noise_std(residual: np.ndarray, ok: np.ndarray) -> float:
    """The standard deviation of the white part of ``residual`` [N m]: from its second
    differences (robust median absolute deviation; white noise of std s gives s sqrt 6), which
    a torque slow beside the sample rate hardly changes."""
    use = ok[2:] & ok[1:-1] & ok[:-2]
    d = np.diff(residual, 2)[use]
    return float(np.median(np.abs(d - np.median(d))) / 0.6745 / np.sqrt(6.0)) if d.size else np.nan


def held_torques(residual: np.ndarray, phases: list, rate_hz: float) -> list[np.ndarray]:
    """|residual| averaged over HOLD_MEAN_S, in each stick phase and LOOK_AFTER_S past it: the
    torque the friction held, one array per phase [N m]."""
    w = max(int(round(HOLD_MEAN_S * rate_hz)), 1)
    held = np.abs(np.convolve(residual, np.ones(w) / w, "same"))
    after = int(round(LOOK_AFTER_S * rate_hz))
    return [held[a:b + after] for a, b in phases]


def breakaway_test(residual: np.ndarray, qd: np.ndarray, ok: np.ndarray, rate_hz: float,
                   seed: int = 0) -> Breakaway:
    """The stick-phase test of one joint: ``residual`` (N,) its torque-balance equation error
    with the friction term left out [N m], ``qd`` (N,) its velocity [rad/s], ``ok`` (N,) the
    usable samples.  Ratio = (HOLD_QUANTILE of the held torques - what noise and the model's
    other errors add to it) / F_c."""
    phases = stick_phases(qd, ok, rate_hz)
    coulomb_nm, viscous, sliding = sliding_fit(residual, qd, ok)
    if len(phases) < 2 or not coulomb_nm > 0:
        return Breakaway(np.nan, np.nan, len(phases), coulomb_nm)
    held = held_torques(residual, phases, rate_hz)
    w = max(int(round(HOLD_MEAN_S * rate_hz)), 1)
    other = np.convolve(residual - coulomb_nm * np.sign(qd) - viscous * qd, np.ones(w) / w, "same")[sliding]
    allowance = max(NOISE_Z * white_noise_std(residual, ok) / np.sqrt(w),
                    float(np.quantile(np.abs(other), ERROR_QUANTILE)))

    def ratio(groups) -> float:
        return float((np.quantile(np.concatenate(groups), HOLD_QUANTILE) - allowance) / coulomb_nm)

    rng = np.random.default_rng(seed)
    boot = [ratio([held[i] for i in rng.integers(0, len(held), len(held))]) for _ in range(200)]
    return Breakaway(ratio(held), float(np.std(boot)), len(phases), float(coulomb_nm))
