"""Name: Coulomb friction or stiction, from the torque at which a stuck joint breaks away.

The torque balance's friction terms are functions of the measured velocity, and a joint that
really sticks shows none: while it is stuck the friction holds whatever net torque acts on it,
up to the static level F_s, and the joint moves off when that torque exceeds F_s (Karnopp 1985,
ASME JDSMC 107:100; Armstrong-Helouvry, Dupont, Canudas de Wit 1994, Automatica 30:1083, sec.
2).  A smooth Stribeck term of the filtered velocity takes up little of it (LuGre's or
Karnopp's sticking in a recording projects onto the Coulomb level), so the search names
Coulomb friction; this module then looks at the stick phases themselves.  At the end of every
stick phase the equation error, friction excluded, is the torque that broke the joint loose:
its median over the phases, less what sensor noise adds to such a peak (the same statistic in
windows where the joint slides), over the sliding level F_c is the breakaway ratio F_s / F_c.
Plain Coulomb friction breaks away at about F_c (a tanh-regularised law creeps below it).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rules import MIN_T

#: a joint slower than this [rad/s] counts as stuck: the velocity of the doctor's parallel
#: filter wanders by ~0.01-0.02 rad/s on a joint held still, so a narrower band breaks one
#: stick phase into pieces
STUCK_RAD_S = 0.05
#: the shortest stick phase that counts [s]: a velocity reversal passes the band in less
STICK_MIN_S = 0.03
#: where the breakaway torque is looked for [s]: the end of the stick phase and just after
#: it (the filtered velocity leaves the band one or two samples after the joint moved off)
LOOK_BEFORE_S, LOOK_AFTER_S = 0.05, 0.02
#: a joint faster than this [rad/s] slides: past the Stribeck velocities of the literature
#: (0.001-0.1 rad/s, Armstrong-Helouvry et al. 1994), where friction is its sliding level plus
#: a viscous part
SLIDING_RAD_S = 0.2
#: the fewest stick phases the test needs
MIN_PHASES = 10
#: stiction is named when the joint breaks away at this many times its sliding friction or
#: more (and significantly above 1: Breakaway.stiction).  Set on development recordings: of
#: the random-form generator's Coulomb-family friction (tanh Coulomb, Dahl, pressure-dependent
#: seals, LuGre with F_s 1.3-1.8 F_c) 12 read 0.62-1.19; of its stiction (Karnopp, LuGre with F_s
#: 2.5-4 F_c, Stribeck curves with an exponent) 12 read 0.98-1.84, the five Stribeck curves
#: 0.98-1.33 (their tanh regularisation keeps the peak at 1.3-1.9 F_c); pneumasim's own
#: Coulomb friction 0.83-1.34 (the last one insignificant: noise 4 times the friction), its
#: Stribeck stiction 2.1-2.8.  The ratio reads low (tests/test_breakaway.py: 2.0 for 2.5).
STICTION_BREAKAWAY_RATIO = 1.25


@dataclass
class Breakaway:
    """The stick-phase test at one joint."""

    ratio: float
    """F_s / F_c: 1 + (median breakaway peak - median sliding peak) / F_c (breakaway_test)"""
    ratio_stderr: float
    """its standard error (bootstrap over the stick phases)"""
    phases: int
    """how many stick phases it was measured on"""
    coulomb_nm: float
    """the sliding level F_c it is measured against [N m] (sliding_level)"""

    @property
    def stiction(self) -> bool:
        """At or past the stiction ratio, and an excess over 1 of MIN_T standard errors or more
        (the doctor's keep rule for a parameter: noise on a weak friction scatters the ratio)."""
        return bool(self.phases >= MIN_PHASES and self.ratio >= STICTION_BREAKAWAY_RATIO
                    and self.ratio - 1.0 >= MIN_T * self.ratio_stderr)

    def evidence(self) -> str:
        return (f"the joint breaks away at {self.ratio:.2f} +/- {self.ratio_stderr:.2f} times its sliding "
                f"friction (median over {self.phases} stick phases, stiction from {STICTION_BREAKAWAY_RATIO:g} on)")


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


def breakaway_torques(residual: np.ndarray, phases: list, rate_hz: float) -> np.ndarray:
    """The largest |residual| (a three-sample mean, against the sensor noise) near the end of
    each stick phase: the torque the friction held when the joint moved off [N m]."""
    smooth = np.abs(np.convolve(residual, np.ones(3) / 3, "same"))
    before, after = int(round(LOOK_BEFORE_S * rate_hz)), int(round(LOOK_AFTER_S * rate_hz))
    return np.array([smooth[max(a, b - before):b + after].max() for a, b in phases])


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


def sliding_peaks(residual: np.ndarray, qd: np.ndarray, sliding: np.ndarray, viscous: float,
                  rate_hz: float) -> np.ndarray:
    """The statistic of :func:`breakaway_torques` where friction is known to be at its sliding
    level: the largest |three-sample mean| of residual - b qd in windows of the same length
    inside sliding stretches [N m].  Their median is F_c plus what sensor noise adds to a
    window's maximum: the breakaway is measured against it, so noise alone reads a ratio of 1."""
    smooth = np.abs(np.convolve(residual - viscous * qd, np.ones(3) / 3, "same"))
    n = int(round(LOOK_BEFORE_S * rate_hz)) + int(round(LOOK_AFTER_S * rate_hz))
    out = []
    for a, b in zip(*_runs(sliding)):
        out += [smooth[k:k + n].max() for k in range(a + 1, b - n, n)]  # off the run's ends
    return np.array(out)


def breakaway_test(residual: np.ndarray, qd: np.ndarray, ok: np.ndarray, rate_hz: float,
                   seed: int = 0) -> Breakaway:
    """The stick-phase test of one joint: ``residual`` (N,) its torque-balance equation error
    with the friction term left out [N m], ``qd`` (N,) its velocity [rad/s], ``ok`` (N,) the
    usable samples.  Ratio = 1 + (median breakaway peak - median sliding peak) / F_c."""
    phases = stick_phases(qd, ok, rate_hz)
    coulomb_nm, viscous, sliding = sliding_fit(residual, qd, ok)
    if len(phases) < 2 or not coulomb_nm > 0:
        return Breakaway(np.nan, np.nan, len(phases), coulomb_nm)
    peaks = breakaway_torques(residual, phases, rate_hz)
    ref = sliding_peaks(residual, qd, sliding, viscous, rate_hz)
    if ref.size < 2:
        return Breakaway(np.nan, np.nan, len(phases), coulomb_nm)
    rng = np.random.default_rng(seed)
    boot = (np.median(rng.choice(peaks, size=(200, peaks.size)), axis=1)
            - np.median(rng.choice(ref, size=(200, ref.size)), axis=1))
    ratio = 1.0 + (np.median(peaks) - np.median(ref)) / coulomb_nm
    return Breakaway(float(ratio), float(np.std(boot) / coulomb_nm), len(phases), float(coulomb_nm))
