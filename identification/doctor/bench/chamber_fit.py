"""bench_chamber hypotheses: leak to the room vs the gas cooling to the wall after charging.

Pressure p(t) [Pa abs] of a chamber that was charged and shut at t_c (before t_c it is held
by the supply, so the pressure is constant):

* ``none`` — closed and isothermal: p = p_s.
* ``external_leak`` — isothermal laminar leak (pneumatics.effects.external_leak, "laminar"):
  V/(R T_w) dp/dt = -G (p^2 - p_r^2)/(2 p_r); with kappa = R T_w G / V = 1/tau_leak the
  solution is (p - p_r)/(p + p_r) = (p_s - p_r)/(p_s + p_r) exp(-(t - t_c)/tau_leak).
  tau_leak is the small-pressure-difference time constant; G = V/(R T_w tau_leak) needs the
  chamber volume (fluid.toml; not given by the thesis, so G is per that nominal volume).
* ``heat_transfer`` — no leak; the gas, dT0 above the wall at t_c, cools with
  tau_th = m c_v/(h A_w) (pneumatics.effects.heat_transfer.closed_chamber):
  p = p_s (T_w + dT0 exp(-(t - t_c)/tau_th)) / (T_w + dT0).
* ``external_leak+pressure_sensor_offset`` — the leak, read by a gauge sensor whose zero is
  off by ``offset_pa`` (the pressure then levels off at room + offset instead of room).
* ``external_leak+heat_transfer`` — both, with the gas cooling as it expands through the leak
  (energy balance, heat_transfer.chamber_rates, RK4): parameters p_s, tau_leak, dT0, tau_th.

All parameters are volume-free (time constants and a temperature), fitted by
``lsq.nonlinear`` on log time constants (standard errors by the delta method).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from pneumatics.effects.external_leak import conductance_from_time_constant

from identification.base import lsq
from .common import (
    ALIKE,
    KEEP,
    MAX_DT_K,
    MIN_DT_K,
    PARSIMONY,
    noise_sd,
    autocorrelation_inflation,
    nrmse,
    split_parts,
)
from pneumatics.bench.model import BenchChamberCfg, for_recording

HYPS = ("none", "external_leak", "heat_transfer", "external_leak+heat_transfer",
        "external_leak+pressure_sensor_offset")


def closing_time(t, p, noise_pa: float, resolution_pa: float) -> float:
    """When the chamber was shut [s]: the end of the initial plateau, extrapolated back along
    the first decay so that a slow drift that starts at once gives t[0]."""
    n0 = max(3, min(10, t.size // 20))
    p0 = float(np.median(p[:n0]))
    band = max(5 * noise_pa, 3 * resolution_pa)
    above = np.nonzero(p >= p0 - band)[0]
    i = int(above[-1]) + 1 if above.size else 0
    if i >= t.size - 3:
        return float(t[0])
    j = min(t.size, i + max(5, round(max(2.0, 0.1 * (t[-1] - t[0])) / max(float(np.median(np.diff(t))), 1e-6))))
    slope = np.polyfit(t[i:j], p[i:j], 1)[0] if j - i >= 3 else 0.0
    tc = t[i] - band / abs(slope) if slope < 0 else t[i]
    return float(np.clip(tc, t[0], t[i]))


def model_pressure(hyp: str, theta, t, tc: float, cfg: BenchChamberCfg) -> np.ndarray:
    """Predicted p(t) (N,) of hypothesis ``hyp`` with parameters ``theta``."""
    pr, Tw = cfg.room_pa, cfg.wall_temperature_k
    ps = theta[0]
    s = np.maximum(np.asarray(t, float) - tc, 0.0)
    if hyp == "none":
        return np.full(s.size, ps)
    if hyp == "external_leak":
        tau = math.exp(theta[1])
        r = (ps - pr) / (ps + pr) * np.exp(-s / tau)
        return pr * (1 + r) / (1 - r)
    if hyp == "heat_transfer":
        dT, tau = theta[1], math.exp(theta[2])
        return ps * (Tw + dT * np.exp(-s / tau)) / (Tw + dT)
    if hyp == "external_leak+heat_transfer":
        return leak_and_heat(theta, s, cfg)
    if hyp == "external_leak+pressure_sensor_offset":
        tau, off = math.exp(theta[1]), theta[2]
        pt = ps - off
        r = (pt - pr) / (pt + pr) * np.exp(-s / tau)
        return pr * (1 + r) / (1 - r) + off
    raise ValueError(hyp)


def leak_and_heat(theta, s, cfg: BenchChamberCfg):
    """Pressure [Pa] at times ``s`` after the shut of a chamber that both leaks (laminar, time
    constant tau_l) and exchanges heat with its wall (tau_th, gas dT above the wall at the shut):
    the energy balance of Richer & Hurmuzlu 2000 with the leak's mass flow, by RK4;
    ``theta`` = (p_shut, log tau_l, dT, log tau_th)."""
    ps, tau_l, dT, tau_th = theta[0], math.exp(theta[1]), theta[2], math.exp(theta[3])
    R, k, Tw, pr = cfg.gas_constant_j_per_kg_k, cfg.heat_capacity_ratio, cfg.wall_temperature_k, cfg.room_pa
    T0 = Tw + dT
    cv = R / (k - 1.0)
    ha_per_v = ps * cv / (R * T0 * tau_th)        # h A_w / V [W/(m^3 K)] from tau_th at t_c
    g_per_v = 1.0 / (R * Tw * tau_l)              # G / V [kg/(s Pa m^3)] from tau_leak
    span = float(np.max(s)) if s.size else 0.0
    dt = min(0.05, tau_th / 4.0)
    n = max(1, math.ceil(span / dt))
    P = leak_heat_rk4(ps, T0, Tw, pr, R, k, ha_per_v, g_per_v, span / n, n)
    return np.interp(s, np.linspace(0.0, span, n + 1), P)


@njit(cache=True)
def leak_heat_rk4(ps, T0, Tw, pr, R, k, ha, g, h, n):  # pragma: no cover - compiled
    """RK4 of (p, T) of a rigid chamber (V = 1 m^3: ``ha`` = h A_w / V, ``g`` = G / V) leaking
    by the laminar law: the numba twin of heat_transfer.chamber_rates (tests compare them)."""
    out = np.empty(n + 1)
    p, T = ps, T0
    out[0] = p
    for i in range(n):
        dp1, dT1 = _rates(p, T, Tw, pr, R, k, ha, g)
        dp2, dT2 = _rates(p + 0.5 * h * dp1, T + 0.5 * h * dT1, Tw, pr, R, k, ha, g)
        dp3, dT3 = _rates(p + 0.5 * h * dp2, T + 0.5 * h * dT2, Tw, pr, R, k, ha, g)
        dp4, dT4 = _rates(p + h * dp3, T + h * dT3, Tw, pr, R, k, ha, g)
        p += h / 6.0 * (dp1 + 2.0 * dp2 + 2.0 * dp3 + dp4)
        T += h / 6.0 * (dT1 + 2.0 * dT2 + 2.0 * dT3 + dT4)
        if not (p > 0.0 and T > 0.0):
            out[i + 1:] = np.nan
            return out
        out[i + 1] = p
    return out


@njit(cache=True)
def _rates(p, T, Tw, pr, R, k, ha, g):  # pragma: no cover - compiled
    mout = g * (p - pr) * (p + pr) / (2.0 * pr)
    dp = -k * R * T * mout + (k - 1.0) * ha * (Tw - T)      # Richer & Hurmuzlu 2000 eq. 11, V = 1
    dT = T * (dp / p + mout * R * T / p)                    # ideal gas: T'/T = p'/p - m'/m
    return dp, dT


def _starts(hyp, ps, span_s, fitted: dict):
    """Initial guesses; the pair starts from what the single hypotheses found."""
    if hyp == "none":
        return [[ps]]
    if hyp == "external_leak":
        return [[ps, math.log(t)] for t in (span_s / 3, span_s * 10, span_s * 300)]
    if hyp == "heat_transfer":
        return [[ps, dT, math.log(t)] for t, dT in ((span_s / 10, 3.0), (span_s / 2, 10.0), (span_s * 2, 30.0))]
    if hyp == "external_leak+pressure_sensor_offset":
        log_tl = fitted["external_leak"].values[1] if "external_leak" in fitted else math.log(span_s * 10)
        return [[ps, log_tl, 0.0], [ps, log_tl - 0.5, 2e3]]
    log_tl = fitted["external_leak"].values[1] if "external_leak" in fitted else math.log(span_s * 10)
    heat = fitted["heat_transfer"].values[1:] if "heat_transfer" in fitted else [3.0, math.log(span_s / 5)]
    return [[ps, log_tl, heat[0], heat[1]], [ps, log_tl, 2.0, math.log(span_s / 20)],
            [ps, log_tl + 0.5, -5.0, math.log(span_s / 20)]]


def _bounds(hyp, pmax):
    lo_tau, hi_tau = math.log(0.3), math.log(1e7)
    if hyp == "none":
        return [5e4], [pmax * 3]
    if hyp == "external_leak":
        return [5e4, lo_tau], [pmax * 3, hi_tau]
    if hyp == "heat_transfer":
        return [5e4, 0.0, lo_tau], [pmax * 3, MAX_DT_K, hi_tau]
    if hyp == "external_leak+pressure_sensor_offset":
        return [5e4, lo_tau, -2e4], [pmax * 3, hi_tau, 2e4]
    return [5e4, lo_tau, -MAX_DT_K, math.log(0.5)], [pmax * 3, hi_tau, MAX_DT_K, math.log(1e5)]


PARAM_NAMES = {
    "none": ["initial_pressure_pa"],
    "external_leak": ["initial_pressure_pa", "log_tau_leak"],
    "heat_transfer": ["initial_pressure_pa", "gas_excess_temperature_k", "log_tau_thermal"],
    "external_leak+heat_transfer": ["initial_pressure_pa", "log_tau_leak", "gas_excess_temperature_k",
                                    "log_tau_thermal"],
    "external_leak+pressure_sensor_offset": ["initial_pressure_pa", "log_tau_leak", "offset_pa"],
}


def fit_hypothesis(hyp, t, p, tc, cfg, fitted: dict | None = None) -> lsq.Fit:
    ps = float(np.median(p[: max(3, min(10, p.size // 20))]))
    lo, hi = _bounds(hyp, float(p.max()))
    best = None
    for x0 in _starts(hyp, ps, float(t[-1] - t[0]), fitted or {}):
        x0 = np.clip(x0, np.array(lo) + 1e-9, np.array(hi) - 1e-9)
        try:
            f = lsq.nonlinear(lambda th: model_pressure(hyp, th, t, tc, cfg) - p, x0, PARAM_NAMES[hyp], lo, hi,
                              max_nfev=200 if len(x0) > 3 else 400)
        except (ValueError, FloatingPointError):
            continue
        if np.isfinite(f.rss) and (best is None or f.rss < best.rss):
            best = f
    return best


def report_parameters(hyp, fit: lsq.Fit, cfg: BenchChamberCfg, temperature_k: float) -> dict:
    """Physical parameters with standard errors (time constants from their logs, delta method)."""
    out = {}
    for name, v, e in zip(fit.names, fit.values, fit.stderr):
        if name.startswith("log_tau"):
            tau = math.exp(v)
            key = "leak_time_constant_s" if "leak" in name else "thermal_time_constant_s"
            out[key] = {"value": tau, "stderr": tau * float(e)}
            if "leak" in name:
                g = conductance_from_time_constant(cfg.volume_m3, tau, temperature_k, cfg.gas_constant_j_per_kg_k)
                out["leak_conductance_kg_s_pa_per_nominal_volume"] = {"value": g, "stderr": g * float(e)}
        elif name != "initial_pressure_pa":
            out[name] = {"value": float(v), "stderr": float(e)}
    return out


def diagnose_chamber(model, cfg: BenchChamberCfg, recordings, holdouts, fraction) -> dict:
    ch = f"p_a.{cfg.name}"
    for r in [*recordings, *holdouts]:
        if ch not in r:
            raise_missing(r, ch)
    if len(recordings) > 1 or len(holdouts) > 1:
        from pneumatics.errors import RecordingError

        raise RecordingError(f"bench_chamber: one charge per diagnosis (got {len(recordings)} recording(s), "
                             f"{len(holdouts)} held-out); give a second charge of the same chamber with --holdout")
    rec = recordings[0]
    c = for_recording(cfg, rec)
    train, held = split_parts(recordings[:1], holdouts[:1], fraction)
    tr, ho = train[0], held[0]
    noise = max(noise_sd(rec[ch]), c.pressure_resolution_pa / math.sqrt(12))
    tc = closing_time(tr.time, tr[ch], noise, c.pressure_resolution_pa)
    ho_tc = tc if not holdouts else closing_time(ho.time, ho[ch], noise, c.pressure_resolution_pa)
    scored, fitted = {}, {}
    for hyp in HYPS:
        fit = fitted[hyp] = autocorrelation_inflation(fit_hypothesis(hyp, tr.time, tr[ch], tc, c, fitted))
        theta = fit.values.copy()
        if holdouts:  # another charge: its own initial pressure, the fitted rates
            theta[0] = float(np.median(ho[ch][:10]))
        pred = model_pressure(hyp, theta, ho.time, ho_tc, c)
        scored[hyp] = {"fit": fit, "pred": pred, "heldout_mse": float(np.mean((pred - ho[ch]) ** 2)),
                       "heldout_nrmse": nrmse(pred, ho[ch]), "train_rmse": math.sqrt(fit.rss / fit.n)}
    return _chamber_report(model, c, rec, tr, ho, ch, tc, noise, scored, recordings, holdouts)


def raise_missing(r, ch):
    from pneumatics.errors import RecordingError

    raise RecordingError(f"{r.source}: no column {ch!r} (the bench chamber's pressure, Pa abs); "
                         f"columns: {', '.join(r.columns)}")


def _plausible(hyp, fit) -> str | None:
    """Why a fit is physically implausible, or None."""
    names = fit.names
    if "gas_excess_temperature_k" in names:
        dT = fit.values[names.index("gas_excess_temperature_k")]
        if dT >= 0.98 * MAX_DT_K:
            return (f"it needs the gas {dT:.0f} K above the wall temperature, more than charging "
                    "can heat it ((k-1) T_w)")
        if dT < MIN_DT_K:
            return (f"it needs the gas {-dT:.0f} K colder than the wall when the chamber is shut, "
                    "which charging from a supply at room temperature cannot do")
    return None


def _chamber_report(model, cfg, rec, tr, ho, ch, tc, noise, scored, recordings, holdouts) -> dict:
    base = scored["none"]["heldout_mse"]
    floor = max(noise ** 2, 1e-12)
    ok = {h: s for h, s in scored.items() if h == "none" or _plausible(h, s["fit"]) is None}
    best = min(ok, key=lambda h: ok[h]["heldout_mse"])
    gain = 1.0 - ok[best]["heldout_mse"] / max(base, 1e-300)
    if gain < KEEP or base < 4 * floor:
        best = "none"
    elif "+" in best:  # a pair must pay clearly over the better of its single effects
        singles = [h for h in best.split("+") if h in ok]
        sb = min(singles, key=lambda h: ok[h]["heldout_mse"]) if singles else None
        if sb and ok[sb]["heldout_mse"] - ok[best]["heldout_mse"] < PARSIMONY * base:
            best = sb
    alternatives = []
    if best in ("external_leak", "heat_transfer"):
        other = "heat_transfer" if best == "external_leak" else "external_leak"
        if other in ok:
            o = ok[other]
            excess = (o["heldout_mse"] - ok[best]["heldout_mse"]) / max(ok[best]["heldout_mse"], floor)
            if excess < ALIKE and 1.0 - o["heldout_mse"] / base >= KEEP:
                alternatives = [other]
    findings = []
    temp = cfg.wall_temperature_k
    if best != "none":
        fit = scored[best]["fit"]
        params = report_parameters(best, fit, cfg, temp)
        n_before, n_after = scored["none"]["heldout_nrmse"], scored[best]["heldout_nrmse"]
        effects = best.split("+")
        for eff in effects:
            keys = effect_keys(eff, params)
            findings.append({
                "effect": eff, "where": {"actuator": cfg.name, "chamber": "a"},
                "regime": "after the chamber is shut" + (f" (t > {tc:.1f} s)" if tc > rec.time[0] + 0.5 else ""),
                "windows": [[float(tc), float(ho.time[-1])]],
                "parameters": {k: params[k] for k in keys},
                "heldout_nrmse": {"before": n_before, "after": n_after},
                "heldout_channel": ch,
                "heldout_equation_error_reduction": float(gain),
                "alternatives": alternatives if len(effects) == 1 else [],
                "inclusion_probability": 1.0,
                "evidence": _evidence(eff, best, params, gain, alternatives, scored, tc),
            })
    unexplained = []
    if best != "none":
        rest = scored[best]["heldout_mse"] - floor
        if rest > 9 * floor and (rest / base > 0.05 or scored[best]["heldout_nrmse"] > 2.0):
            unexplained.append({"where": {"actuator": cfg.name, "chamber": "a"}, "regime": "held-out part",
                                "share_of_residual": float(rest / base),
                                "evidence": f"the held-out pressure stays {math.sqrt(rest):.0f} Pa (RMS) off the best "
                                            f"model, {math.sqrt(rest / floor):.0f}x the sensor noise: a leak law "
                                            "between laminar and orifice flow, a gauge zero offset or room drift"})
    isolable = not alternatives
    detail = _detail(best, alternatives, scored)
    hyps = []
    for h, s in scored.items():
        why = _plausible(h, s["fit"])
        hyps.append({"name": h, "parameters": report_parameters(h, s["fit"], cfg, temp),
                     "initial_pressure_pa": float(s["fit"].values[0]),
                     "train_rmse_pa": s["train_rmse"], "heldout_rmse_pa": math.sqrt(s["heldout_mse"]),
                     "heldout_nrmse": s["heldout_nrmse"], "implausible": why})
    n_before = scored["none"]["heldout_nrmse"]
    return {
        "model": model,
        "verdict": "missing_physics" if findings or unexplained else "no_significant_mismatch",
        "verdict_detail": detail,
        "isolable": isolable,
        "baseline": {"heldout_nrmse": {ch: n_before}, "nominal_heldout_nrmse": {ch: n_before}},
        "calibrated": {"initial_pressure_pa": float(scored["none"]["fit"].values[0]), "closing_time_s": tc},
        "findings": findings,
        "unexplained": unexplained,
        "after": {"heldout_nrmse": {ch: scored[best]["heldout_nrmse"]}},
        "hypotheses": hyps,
        "diagnostics": {"kind": "bench_chamber", "pressure_noise_pa": noise, "closing_time_s": tc,
                        "train_seconds": float(tr.time[-1] - tr.time[0]),
                        "heldout_seconds": float(ho.time[-1] - ho.time[0]), "best_hypothesis": best,
                        "volume_m3_assumed": cfg.volume_m3,
                        "sources": [r.source for r in recordings] + [r.source for r in holdouts]},
        "_plot": {"train": tr, "held": ho, "scored": scored, "best": best, "channel": ch, "tc": tc, "cfg": cfg},
    }


def _evidence(eff, best, params, gain, alternatives, scored, tc) -> str:
    p = ", ".join(f"{k} = {params[k]['value']:.3g} ± {params[k]['stderr']:.2g}" for k in effect_keys(eff, params))
    what = {"external_leak": "air leaking to the room (laminar law, pressure falling towards room pressure)",
            "heat_transfer": "the gas cooling to the wall after the charge (pressure levelling off above room pressure)",
            "pressure_sensor_offset": "a zero offset of the gauge sensor (the emptied chamber reads above room "
                                      "pressure)"}[eff]
    s = f"{what} ({p}) extrapolates the held-out pressure {100 * gain:.0f} % better (in mean square) than a sealed chamber"
    if alternatives:
        o = alternatives[0]
        s += (f"; {o.replace('_', ' ')} extrapolates nearly as well (held-out RMSE "
              f"{math.sqrt(scored[o]['heldout_mse']):.0f} vs {math.sqrt(scored[best]['heldout_mse']):.0f} Pa): "
              "this record cannot tell a leak from a slow thermal relaxation")
    return s


def effect_keys(eff: str, params: dict) -> list:
    """The parameters (report names) that belong to effect ``eff``."""
    tag = {"external_leak": "leak", "heat_transfer": ("thermal", "gas_excess"), "pressure_sensor_offset": "offset"}[eff]
    tags = (tag,) if isinstance(tag, str) else tag
    return [k for k in params if any(t in k for t in tags)]


def _detail(best, alternatives, scored) -> str:
    if best == "none":
        return "the pressure holds within the sensor noise: no leak or thermal relaxation is visible"
    if alternatives:
        return (f"{best} or {alternatives[0]}: both extrapolate the held-out pressure alike; a longer record "
                "(leaks keep falling, thermal relaxation levels off) or a temperature sensor would tell")
    return f"named: {best.replace('+', ' and ')}"
