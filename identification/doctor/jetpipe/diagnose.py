"""The mismatch finder for the jet-pipe actuator (``pneumasim doctor --model jetpipe``).

Same report contract as :mod:`identification.doctor.valve_arm.diagnose` (DESIGN.md "The mismatch finder"), scaled
to this one-actuator bench (paper 000, Fig. 8: piston on the rod stopper, force sensor on the
rod, two chamber transducers, coil current, optionally the jet-position sensor):

1. **Read and check** (:mod:`identification.doctor.jetpipe.data`): columns, units, piston on the
   stopper; hold out the given files or the last 30 % of each recording.
2. **Calibrate first**: four nominal parameters (C_d, both dead volumes, the jet offset) within
   +-35 %, by least squares on restarted replays of (the first 8 s of) the fitted part
   (:mod:`identification.doctor.jetpipe.replay`: the simulator's own step driven by the recorded current
   command, pressures restarted from the measurement every second).
3. **Residuals per channel** (p_a, p_b, force, jet) with each channel's noise floor estimated from
   the data: the second difference of the calibrated model's residual, std / sqrt(6).
4. **Name**: every hypothesis (:data:`HYPOTHESES`, the families of
   pneumatics/jetpipe/effects.py at every place) is fitted together with the calibration on the
   fitted part (first round from the nominal parameters: a calibration fitted without the effect
   may have bent the wrong parameters to mimic it) and scored by the held-out noise-weighted mean
   square J = sum_c mean(r_c^2)/sigma_c^2.  The best is kept only when it cuts the baseline's
   held-out J by >= 20 % and by >= 1 (one noise variance) and its parameter is >= 4 standard
   errors from zero; then the next
   round (greedy), until nothing pays.  Hypotheses that buy >= 90 % of the best one's
   improvement are listed as not separable with these sensors (isolability).
5. **Unexplained**: channels whose held-out mean square stays above twice their noise floor^2,
   overall and in at least two 1 s windows (listed).
6. **Guards and regimes** (held-out data): each kept effect's bootstrap inclusion probability
   (block bootstrap over held-out blocks of whether its J reduction still passes the keep rule,
   :func:`identification.base.statistics.bootstrap_inclusion`); the regime where its squared-residual
   reduction concentrates (:mod:`identification.doctor.jetpipe.regimes`: command level, jet distance
   from centre, time since a command reversal or step, pressure levels, flow into each chamber,
   jet velocity), likewise for each unexplained entry; Ljung-Box Q of each channel's held-out
   residual and its cross-correlation with the current command, before and after the findings.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from pneumatics.jetpipe.effects import JetpipeEffects
from pneumatics.recording import Recording

from identification.base import lsq
from identification.base.statistics import LB_LAGS, bootstrap_inclusion

from .data import HOLDOUT, load_traces
from .hypotheses import (
    ALIKE,
    CAL_BOUND,
    CALIBRATION,
    DIFF_STEP,
    FIT_SECONDS,
    HYPOTHESES,
    KEEP,
    MIN_DJ,
    MIN_T,
    MIN_WINDOWS,
    UNEXPLAINED,
    calibrated_cfg,
    select_hypotheses,
)
from .problem import (
    Problem,
    block_sums,
    channel_nrmse,
    effects_with,
    finding_windows,
    fit_joint,
    noise_floor,
    residual_tests,
    sample_residuals,
    scored_samples,
    weighted,
    where_of,
    worst_windows,
)
from .regimes import concentrate, features
from .replay import RESTART_S, replay

__all__ = ["CALIBRATION", "HYPOTHESES", "calibrated_cfg", "diagnose_jetpipe", "fitted_effects"]


@dataclass
class Calibration:
    """The nominal parameters' calibration and the held-out J around it."""

    fit: lsq.Fit
    dev: np.ndarray
    """relative deviations of the CALIBRATION parameters the search starts from"""
    j_nominal: float
    j_base: float
    kept: bool
    """False: the calibrated model predicted the held-out data worse, the baseline stays nominal"""


@dataclass
class Search:
    """The greedy search's state: the model as it stands and what was kept."""

    prob: Problem
    held: list
    feats: dict
    """regime features of the held-out samples (regimes.features)"""
    block_s: float
    """bootstrap block length [s]"""
    res_base: list
    """held-out residuals of the calibrated model before any finding"""
    dev: np.ndarray
    j_now: float
    res_now: list
    fx: JetpipeEffects = field(default_factory=JetpipeEffects)
    kept: list = field(default_factory=list)
    findings: list = field(default_factory=list)
    regime_plots: list = field(default_factory=list)
    hypotheses_out: list = field(default_factory=list)


def diagnose_jetpipe(model: str, recordings: list[Recording], holdouts: list[Recording] = (),
                     holdout_fraction: float = HOLDOUT, progress=None, hypotheses=None,
                     fit_seconds: float = FIT_SECONDS) -> dict:
    """Diagnose jet-pipe recordings of ``model``; returns the report dict (report.write).

    ``hypotheses``: effect families or hypothesis names to test (default all of
    :data:`HYPOTHESES`); ``fit_seconds``: how much of the fitted part the fits use (its start)."""
    say = progress or (lambda msg: None)
    t_start = time.perf_counter()
    hyps = select_hypotheses(hypotheses)
    cfg0, train, held, sources = load_traces(model, recordings, holdouts, holdout_fraction)
    fit_s = [fit_seconds * (t.time[-1] - t.time[0]) / sum(u.time[-1] - u.time[0] for u in train) for t in train]
    train = [t.head(s) for t, s in zip(train, fit_s)]
    prob = Problem(cfg0, train, held)
    cal = _calibrate(prob, train, held, say)
    search = _start_search(prob, held, cal)
    for rnd in range(3):
        if not _search_round(search, hyps, rnd, say):
            break
    _, per_final = prob.score(held, search.dev, search.fx)
    unexplained = _unexplained(search, per_final)
    report = _report(model, search, cal, unexplained, per_final, train, sources, hyps)
    report["diagnostics"]["seconds"] = time.perf_counter() - t_start
    return report


def _calibrate(prob: Problem, train, held, say) -> Calibration:
    """Noise floors from the nominal model's residual (second differences: model error cancels),
    then the CALIBRATION parameters by least squares on the fitted part, then the floors again.
    An effect the nominal model lacks can bend the calibration: when the calibrated model
    predicts the held-out data worse than the nominal one, the baseline stays nominal."""
    none, zero = JetpipeEffects(), np.zeros(len(CALIBRATION))
    prob.sigma = noise_floor(prob.residuals(train, zero, none))
    say("calibrating the nominal parameters")
    fit = lsq.nonlinear(lambda d: prob.vector(train, d, none), zero, [c[0] for c in CALIBRATION],
                        np.full(zero.size, -CAL_BOUND), np.full(zero.size, CAL_BOUND), diff_step=DIFF_STEP, max_nfev=40)
    dev = fit.values
    prob.sigma = noise_floor(prob.residuals(train, dev, none))
    j_nominal, _ = prob.score(held, zero, none)
    j_base, _ = prob.score(held, dev, none)
    kept = j_base <= j_nominal
    if not kept:
        dev, j_base = zero.copy(), j_nominal
    return Calibration(fit, dev, j_nominal, j_base, kept)


def _start_search(prob: Problem, held, cal: Calibration) -> Search:
    """The search at the calibrated model, with the held-out regime features from the
    measurement and that model."""
    none = JetpipeEffects()
    dev_base = cal.dev.copy()
    res_base = sample_residuals(prob, held, dev_base, none)
    cfg_base = calibrated_cfg(prob.cfg0, dev_base)
    feats_per = [features(t.time, t.command_a, t.p_a, t.p_b, replay(t, cfg_base, none), cfg_base.jet.offset_m)
                 for t in held]
    feats = {k: np.concatenate([f[k][t.scored] for t, f in zip(held, feats_per)]) for k in feats_per[0]}
    held_s = sum(float(t.time[-1] - t.time[0]) for t in held)
    block_s = min(RESTART_S, held_s / 10.0)  # at least ten blocks to resample
    return Search(prob, held, feats, block_s, res_base, dev=cal.dev, j_now=cal.j_base, res_now=res_base)


def _search_round(s: Search, hyps, rnd: int, say) -> bool:
    """One greedy round: every hypothesis not kept yet refitted together with the calibration
    (an effect the nominal model lacks bends a calibration fitted without it: the two must move
    together; in the first round from the nominal parameters), judged on the held-out data; the
    best kept if it pays.  False: nothing left to try or nothing paid."""
    cands = [h for h in hyps if h.field not in {k.field for k in s.kept}]
    if not cands:
        return False
    dev_start = np.zeros(len(CALIBRATION)) if rnd == 0 else s.dev
    joint_scored = []
    for h in cands:
        say(f"round {rnd + 1}: {h.name} with the calibration")
        lo = h.lower / h.unit
        x0 = np.array([min(max(1.0, lo), h.upper / h.unit) if lo >= 0 else 0.0])
        joint = fit_joint(s.prob, [h], x0, dev_start, s.fx)
        fx_h = effects_with(s.fx, [h], joint.values[:1] * h.unit)
        j_h, per_h = s.prob.score(s.held, joint.values[1:], fx_h)
        joint_scored.append((j_h, h, joint, fx_h, per_h))
        if rnd == 0:
            s.hypotheses_out.append({"name": h.name, "parameters": {h.field: {
                "value": float(joint.values[0] * h.unit), "stderr": float(joint.stderr[0] * h.unit)}},
                "heldout_j": j_h, "heldout_nrmse": s.prob.last_nrmse})
    joint_scored.sort(key=lambda x: x[0])
    j_new, best, joint, fx_new, per_new = joint_scored[0]
    value, se = joint.values[0] * best.unit, joint.stderr[0] * best.unit
    if 1.0 - j_new / s.j_now < KEEP or s.j_now - j_new < MIN_DJ or abs(value) < MIN_T * se:
        return False
    res_new = sample_residuals(s.prob, s.held, joint.values[1:], fx_new)
    s.findings.append(_finding(s, best, joint, joint_scored, fx_new, per_new, res_new))
    s.kept.append(best)
    s.fx, s.dev, s.j_now, s.res_now = fx_new, joint.values[1:], j_new, res_new
    return True


def _finding(s: Search, best, joint, joint_scored, fx_new, per_new, res_new) -> dict:
    """The report entry of the kept hypothesis ``best``: its channel, alternatives, where the
    held-out improvement lies and how sure (block bootstrap of the keep rule)."""
    prob, held = s.prob, s.held
    j_new = joint_scored[0][0]
    value, se = joint.values[0] * best.unit, joint.stderr[0] * best.unit
    # res_now holds the residuals of (dev, fx): the model before this finding
    per_old = {c: float(np.mean(scored_samples(held, [r[c] for r in s.res_now]) ** 2) / prob.sigma[c] ** 2)
               for c in prob.channels}
    ch = max(prob.channels, key=lambda c: per_old[c] - per_new[c])
    before, after = channel_nrmse(held, s.res_now, ch), channel_nrmse(held, res_new, ch)
    gain = s.j_now - j_new
    alts = [(h, j) for j, h, *_ in joint_scored[1:] if gain > 0 and (s.j_now - j) >= ALIKE * gain]
    # relative cut >= KEEP and absolute cut >= MIN_DJ, the latter as a share of J before
    w_before, w_after = weighted(prob, s.res_now), weighted(prob, res_new)
    inclusion = bootstrap_inclusion(block_sums(held, w_before, s.block_s), block_sums(held, w_after, s.block_s),
                                    max(KEEP, MIN_DJ / s.j_now))
    reduction = scored_samples(held, w_before) - scored_samples(held, w_after)
    where_reg = concentrate(reduction, s.feats)
    # the finding's channel inside that regime (all held-out samples when it is spread out)
    in_reg = np.ones(reduction.size, bool)
    if where_reg["feature"] is not None:
        x, (lo, hi) = s.feats[where_reg["feature"]], where_reg["bin"]
        in_reg = (x >= lo) & (x <= hi)
    nrmse_in = {"before": channel_nrmse(held, s.res_now, ch, in_reg), "after": channel_nrmse(held, res_new, ch, in_reg)}
    s.regime_plots.append({"title": f"{best.effect} at {' '.join(map(str, best.where.values()))}",
                           "feature": where_reg["feature"], "feats": s.feats, "before": scored_samples(held, w_before),
                           "after": scored_samples(held, w_after)})
    return {
        "effect": best.effect, "where": best.where, "regime": where_reg["regime"],
        "regime_detail": {k: where_reg[k] for k in ("feature", "bin", "lift", "share", "cover", "by_feature")},
        "expected_regime": best.regime, "inclusion_probability": inclusion,
        "windows": finding_windows(prob, held, joint.values[1:], s.fx, fx_new, ch),
        "parameters": {best.field: {"value": float(value), "stderr": float(se)}},
        "heldout_nrmse": {"before": before, "after": after}, "heldout_channel": ch,
        "heldout_nrmse_in_regime": nrmse_in,
        "heldout_j": {"before": s.j_now, "after": j_new},
        "alternatives": sorted({h.effect for h, _ in alts if h.effect != best.effect}),
        "alternative_places": [h.where for h, _ in alts if h.effect == best.effect and h.where != best.where],
        "identifiability": {"condition": joint.condition, "at_bound": joint.at_bound},
        "evidence": (f"{best.name}: held-out noise-weighted mean square {s.j_now:.3g} -> {j_new:.3g} "
                     f"({100 * (1 - j_new / s.j_now):.0f} % less), parameter {abs(value) / max(se, 1e-300):.0f} "
                     f"standard errors from zero")}


def _unexplained(s: Search, per_final: dict) -> list:
    """Channels whose held-out mean square stays above UNEXPLAINED noise floors, in at least
    MIN_WINDOWS 1 s windows: one burst in one window (the exact model leaves such bursts at
    large command steps in simulated recordings) is no evidence of missing physics."""
    excess = {c: max(v - 1.0, 0.0) for c, v in per_final.items()}
    total = sum(excess.values()) or 1.0
    out = []
    for c, v in per_final.items():
        wins = worst_windows(s.prob, s.held, s.dev, s.fx, c) if v > UNEXPLAINED else []
        if len(wins) < MIN_WINDOWS:
            continue
        w = scored_samples(s.held, weighted(s.prob, s.res_now, [c]))
        reg = concentrate(w - 1.0, s.feats)  # residual energy above the noise floor
        s.regime_plots.append({"title": f"unexplained {c}", "feature": reg["feature"], "feats": s.feats,
                               "before": scored_samples(s.held, weighted(s.prob, s.res_base, [c])), "after": w})
        out.append({"where": where_of(c), "channel": c, "regime": reg["regime"],
                    "regime_detail": {k: reg[k] for k in ("feature", "bin", "lift", "share", "cover", "by_feature")},
                    "level": f"{c} residual at {np.sqrt(v):.1f} x its noise floor",
                    "windows": wins, "share_of_residual": excess[c] / total})
    return out


def _verdict(findings: list, unexplained: list) -> tuple[str, str, bool]:
    """(verdict, its detail, isolable)."""
    verdict = "missing_physics" if findings or unexplained else "no_significant_mismatch"
    isolable = all(not f["alternatives"] and not f["alternative_places"] for f in findings)
    if findings:
        detail = "; ".join(f"{f['effect']} at {' '.join(str(v) for v in f['where'].values())}"
                           + (f" (or {', '.join(f['alternatives'] + [str(p) for p in f['alternative_places']])})"
                              if f["alternatives"] or f["alternative_places"] else "") for f in findings)
    elif unexplained:
        detail = "residual above the noise floor that no hypothesis explains"
    else:
        detail = "the calibrated model predicts the held-out data to within the noise floor"
    return verdict, detail, isolable


def _report(model, s: Search, cal: Calibration, unexplained, per_final, train, sources, hyps) -> dict:
    """The report dict (DESIGN.md report.json, with the jet-pipe's diagnostics)."""
    prob, held = s.prob, s.held
    verdict, detail, isolable = _verdict(s.findings, unexplained)
    cal_out = {}
    for (name, sec, fields), d in zip(CALIBRATION, s.dev):
        nominal = getattr(getattr(prob.cfg0, sec), fields[0])
        cal_out[name] = float(nominal * (1.0 + d))
    base_nrmse = {c: channel_nrmse(held, s.res_base, c) for c in prob.channels}  # before any finding
    res_nominal = sample_residuals(prob, held, np.zeros(len(CALIBRATION)), JetpipeEffects())
    lb_before, xc_before = residual_tests(prob, held, s.res_base)
    lb_after, xc_after = residual_tests(prob, held, s.res_now)
    return {
        "model": model, "verdict": verdict, "verdict_detail": detail, "isolable": isolable,
        "baseline": {"heldout_nrmse": base_nrmse, "heldout_r2": {c: 1.0 - v ** 2 for c, v in base_nrmse.items()},
                     "heldout_nrmse_nominal": {c: channel_nrmse(held, res_nominal, c) for c in prob.channels}},
        "calibrated": cal_out,
        "calibration_change": {c[0]: {"relative": float(d), "stderr": float(e)}
                               for c, d, e in zip(CALIBRATION, s.dev, cal.fit.stderr)},
        "calibration_without_effects": {c[0]: {"relative": float(d), "stderr": float(e), "kept": cal.kept}
                                        for c, d, e in zip(CALIBRATION, cal.fit.values, cal.fit.stderr)},
        "findings": s.findings, "unexplained": unexplained, "hypotheses": s.hypotheses_out,
        "diagnostics": {"kind": "jetpipe", "sources": sources, "channels": prob.channels,
                        "noise_floor": prob.sigma, "train_seconds": sum(float(t.time[-1] - t.time[0]) for t in train),
                        "heldout_seconds": sum(float(t.time[-1] - t.time[0]) for t in held),
                        "heldout_j": {"nominal": cal.j_nominal, "calibrated": cal.j_base, "final": s.j_now},
                        "heldout_ms_over_noise": per_final, "calibration_condition": cal.fit.condition,
                        "calibration_at_bound": cal.fit.at_bound, "replays": prob.calls,
                        "hypotheses_tested": [h.name for h in hyps],
                        "ljung_box_heldout": {"lags": LB_LAGS, "before": lb_before, "after": lb_after},
                        "input_xcorr_heldout": {"input": "current command", "before": xc_before, "after": xc_after},
                        "bootstrap_block_seconds": s.block_s},
        "_plot": {"problem": prob, "held": held, "regimes": s.regime_plots},
    }


def fitted_effects(report: dict) -> JetpipeEffects:
    """The findings of a report as a :class:`JetpipeEffects` (to simulate what was found)."""
    values = {}
    for f in report["findings"]:
        values.update({k: v["value"] for k, v in f["parameters"].items()})
    return JetpipeEffects(**values)
