"""How far a bench cylinder's friction fit predicts: a seal at a pressure it was not fitted at.

The bench doctor (:mod:`identification.doctor.bench.diagnose`) fits the rod force left after the
pressure force p_g A with Coulomb friction growing linearly with the gauge pressure
(:mod:`pneumatics.effects.seal_friction`) plus a constant part (load-cell offset or a
direction asymmetry, which one constant-speed run cannot tell apart)::

    F - p_g A = (F_c + k_c p_g) sgn(v) + c0 [+ c1 p_g]

Here one pressure's file is left out, the law is fitted on the seal's other files, and the
held-out file's whole force trace is predicted from its own displacement and pressure.  The
terms are fixed beforehand (no choice made on the held-out file):

* ``growth+offset``: F_c, k_c, c0;
* ``growth+offset_per_bar``: F_c, k_c, c0, c1.

Each prediction is scored by the NRMSE of the force (RMS error / standard deviation of the
measured force) beside the nominal p_g A alone and beside Coulomb + offset fitted on the
held-out file itself (the best this law can do on that file: a floor, not a prediction).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.base import lsq

from .common import nrmse
from .cylinder_fit import CylData

TERMS = {"growth+offset": ["coulomb_n", "coulomb_n_per_bar", "offset_n"],
         "growth+offset_per_bar": ["coulomb_n", "coulomb_n_per_bar", "offset_n", "offset_n_per_bar"]}
IN_FILE_TERMS = ["coulomb_n", "offset_n"]
MOVING_M_S = 2e-3


@dataclass
class HeldOutPrediction:
    """One held-out file's force predicted by each law (NRMSE), and the direction means of
    F - p_g A (the thesis's 'friction', q growing / falling) measured and predicted [N]."""

    gauge_bar: float
    nrmse_nominal: float
    nrmse_in_file: float
    nrmse: dict                # law -> NRMSE of the predicted force
    friction_up_down_n: tuple  # measured (q growing, q falling)
    predicted_up_down_n: dict  # law -> (q growing, q falling)
    parameters: dict           # law -> {term: value}


def direction_means(data: CylData, residual: np.ndarray) -> tuple[float, float]:
    """Mean of ``residual`` while the rod moves with q growing and with q falling [N]."""
    return float(np.mean(residual[data.v > MOVING_M_S])), float(np.mean(residual[data.v < -MOVING_M_S]))


def predict_held_out(cfg, train_recs, held_rec) -> HeldOutPrediction:
    """Fit each law of :data:`TERMS` on ``train_recs`` and predict ``held_rec``."""
    tr, ho = CylData(cfg, list(train_recs)), CylData(cfg, [held_rec])
    scores, means, params = {}, {}, {}
    for law, terms in TERMS.items():
        fit = lsq.linear(tr.regressors(terms), tr.residual, terms)
        pred = ho.regressors(terms) @ fit.values
        scores[law] = nrmse(ho.nominal + pred, ho.force)
        means[law] = direction_means(ho, pred)
        params[law] = dict(zip(terms, map(float, fit.values)))
    own = lsq.linear(ho.regressors(IN_FILE_TERMS), ho.residual, IN_FILE_TERMS)
    return HeldOutPrediction(float(np.median(ho.bar)), nrmse(ho.nominal, ho.force),
                             nrmse(ho.nominal + ho.regressors(IN_FILE_TERMS) @ own.values, ho.force),
                             scores, direction_means(ho, ho.residual), means, params)
