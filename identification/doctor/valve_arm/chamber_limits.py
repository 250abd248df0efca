"""What the recordings could show at the chambers: per pneumatic family, the smallest size of its
parameter at each place whose replayed change would pay the keep rule on the held-out recording.

The pneumatic keep rule (rules.PNEU_KEEP) asks a finding to remove a share k of its chambers'
held-out squared replay residual.  With the held-out residual r (the calibrated model's restarted
replays against the measured pressures, in units of the pressure noise) and the change s of the
replays per unit of the parameter (one probe replay, screening's probe step), an effect of size
theta that the calibrated model lacks leaves r + s theta; fitted, it removes
|s theta|^2 / (|s theta|^2 + |r|^2) of it when r is independent of s.  So the smallest size that
can pass is theta = sqrt(k / (1 - k)) |r| / |s| -- the same approximation as the output-error
screen's limits at the joints (output_error_screen.detection_limit): the mismatch taken as
independent, the replay linear in the parameter over the probe step.  Below it a silent
chamber is no evidence that the effect is absent there.

A finding is fitted beside its chambers' calibration (screening.fit_pneumatic), and the
calibrated model the keep rule compares it with has taken up what the calibration can mimic of
it (a leak to the room is in part a larger exhaust area).  So s is first taken off its
projection on the calibration's own signatures at the same chambers (each chamber's supply
area, exhaust area and dead volume, one held-out probe replay each for all chambers at once: a
chamber's replay depends on its own parameters only): what is left is what only the effect can
do.  Without that step the limits were optimistic: a true external leak of humanoid38 at 1.8
times its stated limit, fitted right, removed 0.168 of its chamber's held-out error where the
keep rule asks 0.2 (development case 998117007).

The probes of one family at disjoint chambers share their replays (screening.probe_groups): a
few held-out replays in all, not one per place.
"""
from __future__ import annotations

import numpy as np

from .calibrate import chamber_params, with_chamber_params
from .hypotheses import pneumatic_hypotheses
from .hypothesis import place_of
from .pneumatic import replay
from .rules import PNEU_KEEP, DoctorRun, paying_size
from .screening import probe_groups


def first_forms(hyps) -> list:
    """Of each family at each place, the first screened hypothesis with one parameter (the
    library's first form: a valve leak's area, a valve lag's time constant, a line's delay)."""
    seen, out = set(), []
    for h in hyps:
        key = (h.family, place_of(h.where))
        if h.screened and len(h.params) == 1 and key not in seen:
            seen.add(key)
            out.append(h)
    return out


def chamber_detection_limits(run: DoctorRun) -> dict:
    """{family: {"parameter": its name and unit, "detection_limit": {place: smallest size}}} of
    the first form of every screened pneumatic family (:func:`first_forms`), on the held-out
    recording at the current model (``run.mods``); a place whose probe changes nothing gets inf."""
    hyps = first_forms(pneumatic_hypotheses(run.robot))
    pred, meas = replay(run.held, run.win_h, run.mods)
    r = (pred - meas) / run.sigma                                     # (W, H, C)
    cal = calibration_signatures(run, pred)                           # (3, W, H, C)
    out: dict = {}
    for group in probe_groups(hyps, r.shape[2]):
        h0 = group[0]
        name, start, _, _, probe = h0.params[0]
        mods = run.mods
        for h in group:
            mods = h.apply(mods, np.array([start + probe]))
        s = (replay(run.held, run.win_h, mods)[0] - pred) / run.sigma / probe
        entry = out.setdefault(h0.family, {"parameter": name, "detection_limit": {}})
        for h in group:
            own = [off_calibration(s[:, :, c], cal[:, :, :, c]) for c in h.chambers]
            entry["detection_limit"][place_of(h.where)] = paying_size(
                PNEU_KEEP, float(np.sqrt(np.sum(r[:, :, h.chambers] ** 2))), float(np.sqrt(sum(np.sum(o ** 2) for o in own))))
    return out


#: the calibration's probe step, on its log scales (calibrate.chamber_params)
CALIBRATION_PROBE = 0.05


def calibration_signatures(run: DoctorRun, pred: np.ndarray) -> np.ndarray:
    """(3, W, H, C) the held-out replays' change per unit log scale of each chamber's supply
    area, exhaust area and dead volume (in units of the pressure noise, as the residual), each
    parameter probed at every chamber at once."""
    x0 = chamber_params(run.mods)
    C = x0.size // 3
    out = np.empty((3, *pred.shape))
    for k in range(3):
        x = x0.copy()
        x[k * C:(k + 1) * C] += CALIBRATION_PROBE
        out[k] = (replay(run.held, run.win_h, with_chamber_params(run.mods, x))[0] - pred) / run.sigma / CALIBRATION_PROBE
    return out


def off_calibration(s: np.ndarray, cal: np.ndarray) -> np.ndarray:
    """Signature ``s`` (W, H) of an effect at one chamber less its least-squares projection on
    the calibration's signatures there ``cal`` (k, W, H): the part of the effect no calibration
    of that chamber can mimic.  Windows where any is not finite are left out."""
    ok = np.all(np.isfinite(s), axis=1) & np.all(np.isfinite(cal), axis=(0, 2))
    y, A = s[ok].ravel(), cal[:, ok].reshape(cal.shape[0], -1).T
    keep = np.linalg.norm(A, axis=0) > 0
    if not keep.any():
        return y
    coef, *_ = np.linalg.lstsq(A[:, keep], y, rcond=None)
    return y - A[:, keep] @ coef
