"""Model-based PIDF (paper 002 §V-C, eqs. 16-17): PIDF plus the fitted inverse dynamics.

The PID effort e_i (eq. 13) is a desired pressure difference; the model adds its prediction
d^_i of the pressure difference the reference motion needs (eq. 5 of
:mod:`identification.inverse_dynamics`, evaluated on the reference's q*, qd*, qdd*)::

    dbar_i = e_i + d^_i                                            (eq. 16)
    u_i^+  = 5 + dbar_i - d_i,    u_i^- = 5 - dbar_i + d_i         (eq. 17)

With our PIDF's units (e in V, k_F in V/bar) this reads u^+- = 5 +- (e + k_F (d^ - d)),
so the feedback gains are those of the PIDF (as in the paper).  If tracking is perfect
(e = 0) the model still commands the pressure difference the motion needs, which PID and
PIDF cannot.  ``lead_s`` optionally evaluates d^ a little ahead of t to anticipate the air's
lag (0 = the paper's law).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pneumatics.config import spec
from pneumatics.errors import ConfigError
from pneumatics.sim import Observation

from .pid import BAR, PIDF, PIDFCfg, valve_commands


@dataclass(frozen=True, kw_only=True)
class ModelBasedCfg:
    """Model-based PIDF: the PIDF gains and how the feedforward is evaluated."""

    pidf: PIDFCfg = spec(doc="feedback gains (k_F must be > 0: d^ is a pressure-difference target)")  # noqa: RUF009
    lead_s: float = spec(0.0, "evaluate the model at t + lead_s on the reference", "s", 0.0, 0.5)

    def build(self, reference, null_v, model) -> ModelBasedPIDF:
        """``reference`` needs ``reference(t)`` and ``derivatives(t_array)`` (a
        :class:`controllers.reference.JointReference`); ``model`` an
        :class:`identification.inverse_dynamics.InverseDynamics`."""
        if model is None:
            raise ConfigError("model-based PIDF: needs a fitted inverse-dynamics model "
                              "(identification.inverse_dynamics.fit)")
        if np.any(np.asarray(self.pidf.kf_v_per_bar, float) <= 0):
            raise ConfigError("model-based PIDF: kf_v_per_bar must be > 0 (the model's prediction is "
                              f"a pressure-difference target), got {self.pidf.kf_v_per_bar}")
        if not hasattr(reference, "derivatives"):
            raise ConfigError("model-based PIDF: the reference must provide derivatives(t) -> (q, qd, qdd)")
        return ModelBasedPIDF(self.pidf, reference, np.asarray(null_v, float), model=model, lead_s=self.lead_s)


def feedforward_table(reference, model) -> tuple[np.ndarray, np.ndarray]:
    """(time (N,), d^ (N, 2) [Pa]) of the model on the reference's own time grid."""
    t = np.asarray(reference.time, float)
    q, qd, qdd = reference.derivatives(t)
    return t, model.pressure_difference(q, qd, qdd)


@dataclass
class ModelBasedPIDF(PIDF):
    """Eqs. 16-17; ``feedforward_pa(t)`` is d^ at t [Pa]."""

    model: object = None
    lead_s: float = 0.0
    _table: tuple = field(default=None, init=False)

    def feedforward_pa(self, t: float) -> np.ndarray:
        if self._table is None:
            self._table = feedforward_table(self.ref, self.model)
        tt, dd = self._table
        ts = t + self.lead_s
        return np.array([np.interp(ts, tt, dd[:, j]) for j in range(dd.shape[1])])

    def desired_pressure_difference_pa(self, t: float, obs: Observation) -> np.ndarray:
        """dbar of eq. 16 in Pa (e converted by k_F); advances the PID states."""
        e = self.effort(t, obs)
        return e / self.kf(e.size) * BAR + self.feedforward_pa(t)

    def __call__(self, t: float, obs: Observation) -> np.ndarray:
        e = self.effort(t, obs)
        kf = self.kf(e.size)
        d_err_bar = (self.feedforward_pa(t) - (obs.p_a - obs.p_b)) / BAR
        return valve_commands(self.null_v, e + kf * d_err_bar)
