"""Valve hysteresis between the command u [V] and the spool position [V], applied once per
10 ms row (the command is held over the row): four published operators, each an object with
its own state, ``__call__(u) -> spool`` and ``reset(u)``.  The spool is u - z, z the
operator's lag, so that every form is centred on the command and bounded by its width.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Play:
    """The play (backlash) operator of half width r [V] (Krasnosel'skii & Pokrovskii 1989,
    Systems with Hysteresis, Springer; Visintin 1994): the spool stays put until the command
    is r away, then follows it at that distance."""

    half_width_v: float
    y: float = 5.0

    def reset(self, u: float):
        self.y = u

    def __call__(self, u: float) -> float:
        self.y = min(u + self.half_width_v, max(u - self.half_width_v, self.y))
        return self.y


@dataclass
class BoucWen:
    """Bouc-Wen (Wen 1976, ASCE J Eng Mech Div 102:249) with n = 1, beta = gamma = 1/(2H):
    dz = du (1 - |z|/H) while |z| grows, dz = du while it shrinks; spool = u - z."""

    half_width_v: float
    z: float = 0.0
    u_prev: float = 5.0

    def reset(self, u: float):
        self.z, self.u_prev = 0.0, u

    def __call__(self, u: float) -> float:
        d = u - self.u_prev
        self.u_prev = u
        H, z = self.half_width_v, self.z
        if d != 0.0:
            sg = 1.0 if d > 0 else -1.0
            rem = abs(d)
            if z * sg < 0:                 # reversal: z follows the command back to 0
                step = min(rem, abs(z))
                z += sg * step
                rem -= step
            z = sg * H - (sg * H - z) * math.exp(-rem / H)
            self.z = z
        return u - self.z


@dataclass
class Preisach:
    """A discrete Preisach model (Mayergoyz 1991, Mathematical Models of Hysteresis,
    Springer): N relays, relay i switching up at alpha_i and down at beta_i < alpha_i, with
    centres spread evenly over -0.5..10.5 V and half widths (alpha - beta)/2 = r (1 + spread
    x_i), x_i in [-1, 1] fixed by ``seed``; the spool is the weighted sum of the relays,
    -0.5 V + sum w (R + 1)/2, w = 11 V / N.  A density along one line alpha - beta = 2r would
    be a play; the scattered widths round the loop's corners."""

    half_width_v: float
    spread: float = 0.5
    seed: int = 0
    n_relays: int = 250
    state: np.ndarray = field(default=None)

    def __post_init__(self):
        x = np.random.default_rng(self.seed).uniform(-1.0, 1.0, self.n_relays)
        centre = np.linspace(-0.5, 10.5, self.n_relays)
        half = self.half_width_v * (1.0 + self.spread * x)
        self.alpha, self.beta = centre + half, centre - half
        self.weight = 11.0 / self.n_relays

    def reset(self, u: float):
        # the state a slow approach from below would leave; ambiguous relays split at their centre
        self.state = np.where(u >= 0.5 * (self.alpha + self.beta), 1.0, -1.0)

    def __call__(self, u: float) -> float:
        if self.state is None:
            self.reset(u)
        self.state = np.where(u >= self.alpha, 1.0, np.where(u <= self.beta, -1.0, self.state))
        return float(-0.5 + self.weight * np.sum(self.state + 1.0) / 2.0)


@dataclass
class JilesAtherton:
    """Jiles-Atherton (Jiles & Atherton 1986, J Magn Magn Mater 61:48) with the command
    deviation H = u - 5 V as the field and the spool deviation as the magnetisation M:
    M = c M_an + (1 - c) M_irr, M_an = 3 a L(H_e / a) (Langevin L, slope 1 at the origin),
    H_e = H + alpha M, dM_irr/dH = (M_an - M_irr) / (delta k - alpha (M_an - M_irr)), delta
    the sign of dH, and dM_irr = 0 when it would move away from M_an (the usual correction).
    Integrated in sub-steps of at most 0.02 V of command."""

    pinning_v: float                      #: k: the irreversible lag's width [V]
    reversible: float = 0.2               #: c
    shape_v: float = 15.0                 #: a (large: M_an nearly the identity over +-5 V)
    coupling: float = 0.01                #: alpha
    m_irr: float = 0.0
    h_prev: float = 0.0

    def reset(self, u: float):
        self.h_prev = u - 5.0
        self.m_irr = self._m_an(self.h_prev)

    def _m_an(self, he: float) -> float:
        x = he / self.shape_v
        lang = x / 3.0 if abs(x) < 1e-4 else 1.0 / math.tanh(x) - 1.0 / x
        return 3.0 * self.shape_v * lang

    def __call__(self, u: float) -> float:
        h_new = u - 5.0
        n = max(1, int(math.ceil(abs(h_new - self.h_prev) / 0.02)))
        dh = (h_new - self.h_prev) / n
        c, k, al = self.reversible, self.pinning_v, self.coupling
        m = c * self._m_an(self.h_prev) + (1 - c) * self.m_irr
        for i in range(n):
            h = self.h_prev + (i + 0.5) * dh
            man = self._m_an(h + al * m)
            diff = man - self.m_irr
            delta = 1.0 if dh > 0 else -1.0
            if diff * delta > 0:
                self.m_irr += dh * diff / (delta * k - al * diff)
            m = c * self._m_an(h + al * m) + (1 - c) * self.m_irr
        self.h_prev = h_new
        return 5.0 + m


def make(form: str, params: dict):
    """The operator of form ``form`` with effective parameters ``params``."""
    if form == "play_operator":
        return Play(params["half_width_v"])
    if form == "bouc_wen_valve":
        return BoucWen(params["half_width_v"])
    if form == "preisach_relays":
        return Preisach(params["half_width_v"], params["spread"], int(params["seed"]))
    if form == "jiles_atherton":
        return JilesAtherton(params["pinning_v"], params["reversible"], params["shape_v"], params["coupling"])
    raise KeyError(f"unknown valve hysteresis form {form!r}")
