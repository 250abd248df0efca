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

The probes of one family at disjoint chambers share their replays (screening.probe_groups): a
few held-out replays in all, not one per place.
"""
from __future__ import annotations

import numpy as np

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
            entry["detection_limit"][place_of(h.where)] = paying_size(
                PNEU_KEEP, float(np.sqrt(np.sum(r[:, :, h.chambers] ** 2))), float(np.sqrt(np.sum(s[:, :, h.chambers] ** 2))))
    return out
