"""The mismatch finder for the hydraulic elbow (``pneumasim doctor --model sarcos_elbow``).

Same report contract as the other doctors (DESIGN.md "The mismatch finder"), for paper 001's
SARCOS elbow with its sensors (valve current, chamber pressures, vane angle, optional torque):

1. **Read and check** (:mod:`.data`); hold out the given files or the last 30 % of each.
2. **Calibrate**: the valve's flow gain, the oil's effective bulk modulus, the load's inertia
   and weight moment (:data:`.hypotheses.CALIBRATION`, +-50 %) by least squares on the first
   ``FIT_SECONDS`` of the fitted part; the residual channels are the restarted oil replay's
   two chamber pressures (:mod:`.replay`) and the vane and load equation errors
   (:mod:`.mechanics`), each weighted by its own white-noise level.  When the calibrated model
   predicts the held-out data worse than the nominal one, the baseline stays nominal.
3. **Name**: every hypothesis (:data:`.hypotheses.HYPOTHESES`) is fitted together with the
   calibration of its side and scored by the held-out J; the best is kept only when it cuts J
   by >= 5 % and by >= 0.25 noise variance and its parameter is >= 4 standard errors from zero
   (the keep rule, :data:`.hypotheses.KEEP`: five times what any hypothesis bought on null
   recordings); greedy rounds until nothing pays, the later rounds refitting only the
   hypotheses that cut J by >= 0.25 on their own in the first.  Hypotheses buying >= 90 % of the best
   one's improvement are listed as not separable.
4. **Unexplained**: a flexible linear model of each channel's training residual
   (:func:`.regimes.flexible_regressors`, 13-15 regressors) that cuts the held-out J by >= 20 %
   and >= 1 noise variance (a stricter bar than one parameter's: it has many) means
   something pays that no family names: reported, never silent.
"""
from __future__ import annotations

import time

import numpy as np

from identification.base import lsq
from pneumatics.hydraulics.effects import HydraulicEffects, build_sim
from pneumatics.recording import Recording

from .data import HOLDOUT, load_traces
from .hypotheses import (ALIKE, BRACED_FIT_SECONDS, CALIBRATION, FIT_SECONDS, KEEP, MIN_DJ, MIN_T, ROUNDS,
                         UNEXPLAINED_DJ, UNEXPLAINED_SHARE, select_hypotheses)
from .mechanics import from_model
from .problem import Problem, fit, sides_of
from .regimes import flexible_regressors, locate, masks

__all__ = ["diagnose_hydraulic", "fitted_effects"]


def diagnose_hydraulic(model: str, recordings: list[Recording], holdouts: list[Recording] = (),
                       holdout_fraction: float = HOLDOUT, progress=None, hypotheses=None,
                       fit_seconds: float = FIT_SECONDS) -> dict:
    """Diagnose recordings of hydraulic model ``model``; returns the report dict (report.write)."""
    say = progress or (lambda msg: None)
    t_start = time.perf_counter()
    cfg0, train, held, sources = load_traces(model, recordings, holdouts, holdout_fraction)
    hyps = select_hypotheses(hypotheses, torque=train[0].torque is not None)
    train = _fit_parts(train, fit_seconds)
    sim = build_sim(cfg=cfg0, name=model)
    prob = Problem(cfg0, from_model(sim, cfg0.vane.displacement_m3_per_rad), train, held)
    none, zero = HydraulicEffects(), np.zeros(len(CALIBRATION))
    prob.set_noise_floor(zero, none)
    say("calibrating the nominal parameters")
    cal, dev, _ = fit(prob, [], np.zeros(0), zero, none, max_nfev=20)
    prob.set_noise_floor(dev, none)
    j_nominal, _ = prob.score(held, zero, none)
    j_base, _ = prob.score(held, dev, none)
    if j_base > j_nominal:
        dev, j_base = zero.copy(), j_nominal
    state = {"dev": dev, "fx": none, "j": j_base, "j0": j_base, "kept": [], "findings": [], "hypotheses": []}
    base_nrmse = {c: prob.nrmse(held, dev, none, c) for c in prob.channels}
    for rnd in range(ROUNDS):
        if not _round(prob, state, hyps, rnd, say):
            break
    say("checking for residual no family explains")
    unexplained = _unexplained(prob, state)
    _, per_final = prob.score(held, state["dev"], state["fx"])
    findings = state["findings"]
    verdict = "missing_physics" if findings or unexplained else "no_significant_mismatch"
    if findings:
        detail = "; ".join(f"{f['effect']} at {' '.join(map(str, f['where'].values()))}"
                           + (f" (or {', '.join(f['alternatives'])})" if f["alternatives"] else "") for f in findings)
    elif unexplained:
        detail = "residual that no hypothesis explains, though a flexible model predicts it"
    else:
        detail = "the calibrated model predicts the held-out data to within the noise floor"
    return {
        "model": model, "verdict": verdict, "verdict_detail": detail,
        "isolable": all(not f["alternatives"] and not f["alternative_places"] for f in findings),
        "baseline": {"heldout_nrmse": base_nrmse},
        "calibrated": _calibrated(prob, state["dev"]),
        "calibration_change": {name: {"relative": float(d), "stderr": float(e)}
                               for (name, _), d, e in zip(CALIBRATION, state["dev"], cal.stderr)},
        "findings": findings, "unexplained": unexplained, "hypotheses": state["hypotheses"],
        "diagnostics": {"kind": "hydraulic", "sources": sources, "channels": prob.channels,
                        "noise_floor": prob.sigma, "train_seconds": sum(float(t.time[-1] - t.time[0]) for t in train),
                        "heldout_seconds": sum(float(t.time[-1] - t.time[0]) for t in held),
                        "heldout_j": {"nominal": j_nominal, "calibrated": j_base, "final": state["j"]},
                        "heldout_ms_over_noise": per_final, "replays": prob.replays,
                        "hypotheses_tested": [h.name for h in hyps], "seconds": time.perf_counter() - t_start,
                        "weakly_observable": _weakly_observable(prob, hyps)},
        "_plot": {"problem": prob, "dev": state["dev"], "fx": state["fx"]},
    }


#: families the free arm's recordings barely show (docs/hydraulic_doctor.md, Limits), which
#: braced recordings reveal: a chamber's volume (the encoder's noise through the oil spring is
#: as large as its signal) and the shaft's stiffness (its mode 2-3 times the torque's noise)
SEEN_BRACED = ("line_dynamics", "shaft_compliance")


def _weakly_observable(prob: Problem, hyps) -> list[str]:
    """The tested families these recordings barely show: SEEN_BRACED without a braced recording."""
    if any(t.braced for t in [*prob.train, *prob.held]):
        return []
    return [f for f in SEEN_BRACED if f in {h.effect for h in hyps}]


def _fit_parts(train, fit_seconds: float) -> list:
    """The start of each fitted trace: ``fit_seconds`` shared among the free recordings in
    proportion to their lengths, and BRACED_FIT_SECONDS among the braced ones (the doctor's time
    is replays; a braced recording's pressures answer the chambers' volumes within seconds)."""
    out = []
    for braced, budget in ((False, fit_seconds), (True, BRACED_FIT_SECONDS)):
        part = [t for t in train if t.braced == braced]
        total = sum(t.time[-1] - t.time[0] for t in part)
        out += [t.head(budget * (t.time[-1] - t.time[0]) / total) for t in part]
    return out


def _calibrated(prob, dev) -> dict:
    """The calibrated parameters in SI (the names carry the unit)."""
    sv, m = prob.cfg0.servovalve, prob.mech0
    return {"port_width_m": sv.port_width_m * (1 + dev[0]),
            "effective_bulk_modulus_pa": prob.cfg0.oil.bulk_modulus_pa * (1 + dev[1]),
            "load_inertia_kg_m2": m.j_l * (1 + dev[2]), "load_weight_moment_nm": m.w * (1 + dev[3])}


def _round(prob: Problem, s: dict, hyps, rnd: int, say) -> bool:
    """One greedy round: every hypothesis not kept yet fitted with its side's calibration on the
    training part and scored on the held-out part; the best kept if it passes the keep rule."""
    cands = [h for h in hyps if h.field not in {k.field for k in s["kept"]}]
    if rnd > 0:  # screened by the first round: only what paid on its own can pay beside a finding
        first = {h["name"]: h["heldout_j"] for h in s["hypotheses"]}
        cands = [h for h in cands if first[h.name] < s["j0"] - MIN_DJ]
    scored = []
    for h in cands:
        say(f"round {rnd + 1}: {h.name}")
        x0 = np.array([0.0 if h.lower < 0 else min(1.0, h.upper / h.unit)])
        res, dev_h, fx_h = fit(prob, [h], x0, s["dev"], s["fx"], sides_of([h], any(t.braced for t in prob.train)))
        j_h, per_h = prob.score(prob.held, dev_h, fx_h)
        scored.append((j_h, h, res, dev_h, fx_h, per_h))
        if rnd == 0:
            s["hypotheses"].append({"name": h.name, "parameters": {h.field: {
                "value": float(res.values[0] * h.unit), "stderr": float(res.stderr[0] * h.unit)}}, "heldout_j": j_h})
    if not scored:
        return False
    scored.sort(key=lambda x: x[0])
    j_new, best, res, dev_new, fx_new, per_new = scored[0]
    value, se = res.values[0] * best.unit, res.stderr[0] * best.unit
    if 1.0 - j_new / s["j"] < KEEP or s["j"] - j_new < MIN_DJ or abs(value) < MIN_T * se:
        return False
    gain = s["j"] - j_new
    alts = [h for j, h, *_ in scored[1:] if (s["j"] - j) >= ALIKE * gain]
    s["findings"].append(_finding(prob, s, best, value, se, dev_new, fx_new, j_new, alts, res))
    s["kept"].append(best)
    s["dev"], s["fx"], s["j"] = dev_new, fx_new, j_new
    return True


def _finding(prob, s, best, value, se, dev_new, fx_new, j_new, alts, res) -> dict:
    held = prob.held
    _, per_old = prob.score(held, s["dev"], s["fx"])
    _, per_new = prob.score(held, dev_new, fx_new)
    ch = max(prob.channels, key=lambda c: per_old[c] - per_new[c])
    weight, regime_masks, wins = [], {}, []
    for tr in held:
        r0, r1 = prob.sample_residuals(tr, s["dev"], s["fx"]), prob.sample_residuals(tr, dev_new, fx_new)
        w = sum((r0[c] ** 2 - r1[c] ** 2) / prob.sigma[c] ** 2 * prob.masks[id(tr)][c] for c in prob.channels)
        weight.append(w[tr.scored])
        for k, v in masks(tr).items():
            regime_masks.setdefault(k, []).append(v[tr.scored])
        wins += _windows(tr, w)
    where = locate(np.concatenate(weight), {k: np.concatenate(v) for k, v in regime_masks.items()})
    return {
        "effect": best.effect, "where": best.where, "regime": where["regime"], "expected_regime": best.regime,
        "regime_detail": where, "windows": wins[:10],
        "parameters": {best.field: {"value": float(value), "stderr": float(se)}},
        "heldout_nrmse": {"before": prob.nrmse(held, s["dev"], s["fx"], ch), "after": prob.nrmse(held, dev_new, fx_new, ch)},
        "heldout_channel": ch, "heldout_j": {"before": s["j"], "after": j_new},
        "alternatives": sorted({h.effect for h in alts if h.effect != best.effect}),
        "alternative_places": [h.where for h in alts if h.effect == best.effect and h.where != best.where],
        "identifiability": {"condition": res.condition, "at_bound": res.at_bound},
        "evidence": (f"{best.name}: held-out noise-weighted mean square {s['j']:.3g} -> {j_new:.3g} "
                     f"({100 * (1 - j_new / s['j']):.0f} % less), parameter {abs(value) / max(se, 1e-300):.0f} "
                     "standard errors from zero"),
    }


def _windows(tr, weight, width_s: float = 1.0) -> list:
    """1 s windows of ``tr`` holding at least half the best window's improvement."""
    edges = np.arange(tr.time[0], tr.time[-1], width_s)
    gains = [(float(np.sum(weight[(tr.time >= a) & (tr.time < a + width_s) & tr.scored])), float(a)) for a in edges]
    top = max((g for g, _ in gains), default=0.0)
    return [[a, min(a + width_s, float(tr.time[-1]))] for g, a in gains if top > 0 and g >= 0.5 * top]


def _unexplained(prob: Problem, s: dict) -> list:
    """Channels whose training residual a flexible linear model predicts on held-out data well
    enough (UNEXPLAINED_SHARE of J, UNEXPLAINED_DJ): something pays that no family names."""
    out = []
    _, per = prob.score(prob.held, s["dev"], s["fx"])
    j_all = sum(per.values())
    for c in prob.channels:
        def design(traces):
            a, r = [], []
            for tr in traces:
                m = prob.masks[id(tr)][c]
                a.append(flexible_regressors(tr)[m])
                r.append(prob.sample_residuals(tr, s["dev"], s["fx"])[c][m])
            return np.concatenate(a), np.concatenate(r)
        a_tr, r_tr = design(prob.train)
        coef = lsq.linear(a_tr, r_tr, [f"x{k}" for k in range(a_tr.shape[1])]).values
        a_h, r_h = design(prob.held)
        after = float(np.mean((r_h - a_h @ coef) ** 2) / prob.sigma[c] ** 2)
        gain = per[c] - after
        if gain >= UNEXPLAINED_SHARE * j_all and gain >= UNEXPLAINED_DJ:
            regime_masks = {}
            for tr in prob.held:
                for k, v in masks(tr).items():
                    regime_masks.setdefault(k, []).append(v[prob.masks[id(tr)][c]])
            where = locate((r_h ** 2 - (r_h - a_h @ coef) ** 2) / prob.sigma[c] ** 2,
                           {k: np.concatenate(v) for k, v in regime_masks.items()})
            place = ({"actuator": "elbow", "chamber": c[-1]} if c.startswith("p_") else
                     {"joint": "shaft"} if c == "brace" else {"joint": "elbow"})
            out.append({"where": place, "channel": c, "regime": where["regime"],
                        "level": f"{c} held-out mean square {per[c]:.2f} noise variances; a flexible model cuts it to {after:.2f}",
                        "share_of_residual": float(gain / max(j_all, 1e-300))})
    return out


def fitted_effects(report: dict) -> HydraulicEffects:
    """The findings of a report as :class:`HydraulicEffects` (to simulate what was found)."""
    values = {}
    for f in report["findings"]:
        values.update({k: v["value"] for k, v in f["parameters"].items()})
    return HydraulicEffects(**values)
