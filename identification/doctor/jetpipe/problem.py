"""The jet-pipe doctor's least-squares problem: restarted replays of the traces, residuals per
channel weighted by their noise floors, and the pieces of evidence built from them (NRMSE,
time windows, bootstrap blocks, Ljung's residual tests)."""
from __future__ import annotations

import dataclasses

import numpy as np

from pneumatics.jetpipe.effects import JetpipeEffects

from identification.base import lsq
from identification.base.statistics import LB_LAGS, input_xcorr, ljung_box, ljung_box_p

from .hypotheses import ACT, CAL_BOUND, CALIBRATION, DIFF_STEP, UNEXPLAINED, calibrated_cfg, chamber_place
from .replay import measured, replay


class Problem:
    """The traces, the nominal config and the channel weights; residuals of a model."""

    def __init__(self, cfg0, train, held):
        self.cfg0, self.train, self.held = cfg0, train, held
        self.channels = [c for c in ("p_a", "p_b", "force", "jet") if all(c in measured(t) for t in train + held)]
        self.sigma = {c: 1.0 for c in self.channels}
        self.var = {c: max(float(np.var(np.concatenate([measured(t)[c][t.scored] for t in held]))), 1e-300)
                    for c in self.channels}
        self.last_nrmse = float("nan")
        self.calls = 0

    def residuals(self, traces, dev, fx) -> dict:
        """channel -> (M,) measured - model over the scored samples of all ``traces``."""
        cfg = calibrated_cfg(self.cfg0, dev)
        out = {c: [] for c in self.channels}
        for tr in traces:
            pred, meas = replay(tr, cfg, fx), measured(tr)
            self.calls += 1
            for c in self.channels:
                out[c].append((meas[c] - pred[c])[tr.scored])
        return {c: np.concatenate(v) for c, v in out.items()}

    def vector(self, traces, dev, fx) -> np.ndarray:
        r = self.residuals(traces, dev, fx)
        v = np.concatenate([r[c] / self.sigma[c] for c in self.channels])
        return np.where(np.isfinite(v), v, 1e6)

    def score(self, traces, dev, fx) -> tuple[float, dict]:
        """(J, per-channel mean square / sigma^2) on ``traces``."""
        r = self.residuals(traces, dev, fx)
        per = {c: float(np.mean(r[c] ** 2) / self.sigma[c] ** 2) for c in self.channels}
        self.last_nrmse = float(np.sqrt(np.mean([np.mean(r[c] ** 2) / self.var[c] for c in self.channels])))
        return float(sum(per.values())), per


def effects_with(base: JetpipeEffects, hyps, values) -> JetpipeEffects:
    changes = {h.field: getattr(base, h.field) + v for h, v in zip(hyps, values)}
    return dataclasses.replace(base, **changes)


def fit_joint(prob, hyps, x_eff, dev0, base):
    """Refit effect parameters (scaled) and the calibration deviations together."""
    n = len(hyps)
    lo = [h.lower / h.unit for h in hyps] + [-CAL_BOUND] * len(CALIBRATION)
    hi = [h.upper / h.unit for h in hyps] + [CAL_BOUND] * len(CALIBRATION)
    x0 = np.clip(np.concatenate([x_eff, dev0]), lo, hi)
    names = [h.name for h in hyps] + [c[0] for c in CALIBRATION]
    fun = lambda x: prob.vector(prob.train, x[n:], effects_with(base, hyps, x[:n] * np.array([h.unit for h in hyps])))
    return lsq.nonlinear(fun, x0, names, lo, hi, diff_step=DIFF_STEP, max_nfev=12)


def noise_floor(res: dict) -> dict:
    """Per channel: std of the residual's second difference / sqrt(6) (white noise; the smooth
    model error cancels), floored at a millionth of the residual's scale."""
    out = {}
    for c, r in res.items():
        s = float(np.std(np.diff(r, 2)) / np.sqrt(6.0))
        out[c] = max(s, 1e-6 * float(np.std(r)) + 1e-30)
    return out


def channel_nrmse(traces, res: list[dict], channel, mask=None) -> float:
    """NRMSE of ``channel`` over the scored samples (those of them in ``mask``), from per-trace
    residuals (:func:`_sample_residuals`), normalised by the measured channel's s.d."""
    r = scored_samples(traces, [x[channel] for x in res])
    meas = scored_samples(traces, [measured(t)[channel] for t in traces])
    return float(np.sqrt(np.mean((r if mask is None else r[mask]) ** 2)) / max(np.std(meas), 1e-300))


def finding_windows(prob, traces, dev, fx_before, fx_after, channel, width_s=1.0):
    """Held-out 1 s windows [t0, t1] where the finding cut the channel's residual most."""
    out = []
    cfg = calibrated_cfg(prob.cfg0, dev)
    for tr in traces:
        a = measured(tr)[channel] - replay(tr, cfg, fx_before)[channel]
        b = measured(tr)[channel] - replay(tr, cfg, fx_after)[channel]
        edges = np.arange(tr.time[0], tr.time[-1] + 1e-9, width_s)
        gains = []
        for t0 in edges:
            m = (tr.time >= t0) & (tr.time < t0 + width_s) & tr.scored
            if m.sum() > 10:
                gains.append((float(np.mean(a[m] ** 2) - np.mean(b[m] ** 2)), float(t0)))
        if gains:
            top = max(g for g, _ in gains)
            out += [[t0, min(t0 + width_s, float(tr.time[-1]))] for g, t0 in gains if top > 0 and g >= 0.5 * top]
    return out[:10]


def where_of(channel):
    return {"p_a": chamber_place("a"), "p_b": chamber_place("b"), "force": ACT,
            "jet": {"actuator": "piston", "sensor": "jet"}}[channel]


def sample_residuals(prob, traces, dev, fx) -> list[dict]:
    """Per trace: channel -> (N,) measured - model (every sample; ``trace.scored`` marks the scored)."""
    cfg = calibrated_cfg(prob.cfg0, dev)
    out = []
    for tr in traces:
        pred, meas = replay(tr, cfg, fx), measured(tr)
        out.append({c: meas[c] - pred[c] for c in prob.channels})
    return out


def weighted(prob, res: list[dict], channels=None) -> list[np.ndarray]:
    """Per trace: (N,) sum over ``channels`` of r_c^2 / sigma_c^2 (the doctor's J per sample)."""
    chans = channels or prob.channels
    return [sum(r[c] ** 2 / prob.sigma[c] ** 2 for c in chans) for r in res]


def scored_samples(traces, per_trace: list[np.ndarray]) -> np.ndarray:
    return np.concatenate([x[t.scored] for t, x in zip(traces, per_trace)])


def block_sums(traces, per_trace: list[np.ndarray], block_s: float) -> np.ndarray:
    """(B,) sums of a per-sample quantity over the scored samples of consecutive ``block_s`` blocks."""
    out = []
    for tr, x in zip(traces, per_trace):
        b = np.floor((tr.time - tr.time[0]) / block_s).astype(int)[tr.scored]
        n = np.bincount(b)
        out.append(np.bincount(b, weights=x[tr.scored])[n > 0])
    return np.concatenate(out)


def residual_tests(prob, traces, res: list[dict]) -> tuple[dict, dict]:
    """Ljung's tests on the held-out residual per channel: ({channel: {"q", "p"}} Ljung-Box over
    lags 1..LB_LAGS, {channel: input cross-correlation with the current command})."""
    lb, xc = {}, {}
    dt = float(np.median(np.diff(traces[0].time)))
    for c in prob.channels:
        r = [x[c][t.scored] for t, x in zip(traces, res)]
        q = ljung_box(np.concatenate(r), LB_LAGS)
        lb[c] = {"q": q, "p": ljung_box_p(q)}
        xc[c] = input_xcorr(r, [t.command_a[t.scored] for t in traces], dt)
    return lb, xc


def worst_windows(prob, traces, dev, fx, channel, width_s=1.0):
    cfg = calibrated_cfg(prob.cfg0, dev)
    out = []
    for tr in traces:
        r = measured(tr)[channel] - replay(tr, cfg, fx)[channel]
        for t0 in np.arange(tr.time[0], tr.time[-1], width_s):
            m = (tr.time >= t0) & (tr.time < t0 + width_s) & tr.scored
            if m.sum() > 10 and np.mean(r[m] ** 2) > UNEXPLAINED * prob.sigma[channel] ** 2:
                out.append([float(t0), float(min(t0 + width_s, tr.time[-1]))])
    return out[:10]
