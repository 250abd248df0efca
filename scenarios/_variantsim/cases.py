"""Blind cases made by the variant simulator: hidden effects (a form per family, a place,
magnitudes; :mod:`.forms`) drawn from a seed, concealed the
way the published truthsim cases are (restarted 1 s open-loop replays of the recorded
commands from the true state, with vs without the effect; the scale is halved until every
channel still fits with R^2 >= 0.9, aiming at 0.91-0.97, while inside the effect's regime it
stands >= 3 noise sd out), 3 % parameter errors (10 % in null cases), a fit recording and a
different held-out one, and ``<case>.truth.json`` beside them."""
from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import numpy as np

from .arm import ANGLE_NOISE_RAD, COLUMNS, JOINTS, PRESSURE_NOISE_PA, Arm2Config, write_csv
from .control import record, reference, replay, table
from .effects import hidden_for
from .forms import FORMS, PLACES, form_of, where

#: the generator's version, in every truth file: forms or their ranges changed since the last
#: version give other cases from the same seeds
GENERATOR = "variantsim-6"
CHANNELS = COLUMNS[1:7]
NOISE = np.array([ANGLE_NOISE_RAD] * 2 + [PRESSURE_NOISE_PA] * 4)
BAND = {"r2_lo": 0.91, "r2_hi": 0.97, "r2_min": 0.9, "snr_min": 3.0}
class GeneratorError(ValueError):
    """The generator could not make a case: its integrator left a recording non-finite (a form
    it does not keep stable at those parameters).  Not the doctor's failure: a benchmark
    records the case as invalid."""


#: pairs whose effects interact: a supply effect beside a chamber effect, a mechanical one
#: beside a pneumatic one, an effect outside the vocabulary beside one inside it
INTERACTING_PAIRS = (
    ("supply_droop", "valve_leak"), ("supply_droop", "external_leak"), ("outside_vocabulary", "line_dynamics"),
    ("coulomb_friction", "piston_leak"), ("stiction", "valve_hysteresis"), ("end_stop", "valve_lag"),
    ("backlash", "heat_transfer"), ("viscous_friction", "outside_vocabulary"),
)


def draw_effects(rng: np.random.Generator, families: list[str], forms: list | None = None,
                 ctx: dict | None = None) -> list[dict]:
    """One effect per entry of ``families``: its form (``forms[i]``, or drawn from the
    family's forms), a place drawn among the form's place kind where no earlier effect holds
    the same simulator element, and magnitudes drawn by the form (``ctx`` as Form.draw)."""
    if forms is not None and len(forms) != len(families):
        raise ValueError(f"variant simulator: forms has {len(forms)} entries, families {len(families)}; "
                         "give one form name (or None) per family")
    out, taken = [], set()
    for i, fam in enumerate(families):
        name = forms[i] if forms is not None else None
        if fam not in FORMS:
            raise ValueError(f"variant simulator: unknown effect family {fam!r}; known: {', '.join(FORMS)}")
        form = form_of(fam, name) if name is not None else FORMS[fam][int(rng.integers(0, len(FORMS[fam])))]
        free = [p for p in PLACES[form.kind] if not any((s, p) in taken for s in form.slots)]
        if not free:
            raise ValueError(f"variant simulator: no free place for {fam}/{form.name}: every "
                             f"{form.kind} already holds its element ({', '.join(form.slots)})")
        place = free[int(rng.integers(0, len(free)))]
        taken |= {(s, place) for s in form.slots}
        params = form.draw(rng, {**(ctx or {}), "place": place})
        out.append({"family": fam, "form": form.name, "kind": form.name, "place_kind": form.kind,
                    "place": place, "where": where(form.kind, place), "source": form.source,
                    "parameters": params})
    return out


def reference_reach(seconds: float, ref_seed: int) -> dict:
    """joint -> (lowest, highest) angle [rad] of the reference the main recording follows."""
    ref = reference(seconds, ref_seed)
    return {j: (float(ref[:, i].min()), float(ref[:, i].max())) for i, j in enumerate(JOINTS)}


def concealment_stats(cfg: Arm2Config, rec: dict, hidden=None) -> dict:
    """R^2 per channel of the restarted replays without the effects against the noise-free
    recorded sensors with them, and the in-regime RMS of their difference over the noise (the
    regime: rows where some channel differs by more than one noise sd)."""
    q, p = replay(cfg, rec, hidden)
    pred = np.column_stack([q, p])
    true = np.column_stack([rec["q_clean"], rec["p_clean"]])
    ok = ~np.isnan(pred[:, 0])
    pred, true = pred[ok], true[ok]
    diff = (true - pred) / NOISE
    r2 = 1 - ((true - pred) ** 2).sum(0) / ((true - true.mean(0)) ** 2).sum(0)
    regime = np.abs(diff).max(1) > 1.0
    snr = np.sqrt((diff[regime] ** 2).mean(0)) if regime.any() else np.zeros(6)
    return {"r2_per_channel": {c: round(float(v), 5) for c, v in zip(CHANNELS, r2)}, "min_r2": float(r2.min()),
            "regime_rms_over_noise_per_channel": {c: round(float(v), 3) for c, v in zip(CHANNELS, snr)},
            "max_regime_rms_over_noise": float(snr.max()), "regime_fraction": float(regime.mean())}


def conceal(cfg, effects, seconds, ref_seed, noise_seed, max_tries: int = 7, weights=None):
    """Search the scale: halve (quarter when far off) while min R^2 < 0.91, bisect
    geometrically back up when a smaller scale overshoots 0.97; stop in the band.  ``weights``:
    each effect's scale relative to the searched one (default all 1).  Returns the chosen
    scale, its main recording, stats and the history."""
    k, lo, hi, tried = 1.0, None, None, {}
    weights = weights or [1.0] * len(effects)
    history = []
    for _ in range(max_tries):
        t0 = time.perf_counter()
        rec = record(cfg, hidden_for(effects, [k * w for w in weights]), seconds, ref_seed, noise_seed)
        st = concealment_stats(cfg, rec)
        tried[k] = (rec, st)
        history.append({"scale": k, "min_r2": st["min_r2"], "max_regime_snr": st["max_regime_rms_over_noise"],
                        "seconds": round(time.perf_counter() - t0, 2)})
        r2 = st["min_r2"]
        if BAND["r2_lo"] <= r2 <= BAND["r2_hi"]:
            break
        if r2 < BAND["r2_lo"]:
            hi = k
            k = math.sqrt(lo * hi) if lo else k / (4.0 if r2 < 0.6 else 2.0)
        else:
            lo = k
            if hi is None:
                break
            k = math.sqrt(lo * hi)
    ok = {s: v for s, v in tried.items() if v[1]["min_r2"] >= BAND["r2_min"]}
    band = {s: v for s, v in ok.items() if v[1]["min_r2"] <= BAND["r2_hi"] and v[1]["min_r2"] >= BAND["r2_lo"]}
    k = max(band) if band else max(ok) if ok else min(tried)
    rec, st = tried[k]
    return k, rec, st, history


def _tracking(rec) -> list[float]:
    return [round(float(v), 3) for v in np.degrees(np.sqrt(((rec["ref"] - rec["q_clean"]) ** 2).mean(0)))]


def make_case(out: Path, seed: int, families: list[str], *, forms: list | None = None, seconds: float = 60.0,
              heldout_seconds: float = 30.0, fraction: float | None = None, conceal_effects: bool = True,
              name: str | None = None) -> dict:
    """Write ``<name>.csv``, ``<name>_heldout.csv`` and ``<name>.truth.json`` into ``out``.

    ``families``: vocabulary family names and/or "outside_vocabulary" ([] = a null case);
    ``forms``: a form name per entry (None = drawn with the seed).  The parameter errors come
    from their own stream of the seed, so a case and its null twin (same seed and fraction)
    share the perturbed arm."""
    t_start = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    name = name or f"variant_{seed}"
    rng = np.random.default_rng(seed)
    seeds = {"reference": seed * 1000 + 1, "heldout_reference": seed * 1000 + 2,
             "noise": seed * 1000 + 3, "heldout_noise": seed * 1000 + 4}
    effects = draw_effects(rng, families, forms, {"reach_rad": reference_reach(seconds, seeds["reference"])})
    fraction = fraction if fraction is not None else (0.03 if families else 0.10)
    cfg, factors = Arm2Config().perturbed(np.random.default_rng([seed, 2]), fraction)
    weights = [1.0] * len(effects)
    if effects and conceal_effects:
        if len(effects) > 1:
            # each effect of a pair first concealed alone, then the two together at a common
            # multiple of those scales: one common scale let a strong effect (an end stop) push
            # the other below what any sensor resolves (a 0.56 ms line delay, seed 488402088)
            weights = [conceal(cfg, [e], seconds, seeds["reference"], seeds["noise"])[0] for e in effects]
        k, main, st, history = conceal(cfg, effects, seconds, seeds["reference"], seeds["noise"], weights=weights)
        concealment = {"method": "restarted 1 s open-loop replays of the recorded commands from the true state, "
                                 "without vs with the effects", "scale": k, "effect_scales": [k * w for w in weights],
                       **st, "band": BAND, "history": history,
                       "concealed": bool(st["min_r2"] >= BAND["r2_min"] and st["max_regime_rms_over_noise"] >= BAND["snr_min"])}
    else:
        k = 1.0
        main = record(cfg, hidden_for(effects, k), seconds, seeds["reference"], seeds["noise"])
        concealment = {"method": "null case: restarted replays through the UNPERTURBED model",
                       **concealment_stats(Arm2Config(), main)} if not effects else {"scale": 1.0}
    scales = [k * w for w in weights]
    held = record(cfg, hidden_for(effects, scales), heldout_seconds, seeds["heldout_reference"], seeds["heldout_noise"])
    truth_effects = [{**e, "scale": ke, "effective": form_of(e["family"], e["form"]).effective(e["parameters"], ke)}
                     for e, ke in zip(effects, scales)]
    paths = {"main": str(out / f"{name}.csv"), "heldout": str(out / f"{name}_heldout.csv")}
    for which, rec in (("main", main), ("heldout", held)):
        bad = [c for c, ok in zip(COLUMNS, np.all(np.isfinite(table(rec)), axis=0)) if not ok]
        if bad:  # a form the integrator does not keep stable: fail here, not as the doctor's refusal
            raise GeneratorError(f"variant case {name} (seed {seed}, {[e['form'] for e in effects]}): the {which} "
                                 f"recording has non-finite values in {', '.join(bad)}")
    write_csv(Path(paths["main"]), table(main))
    write_csv(Path(paths["heldout"]), table(held))
    truth = {"case_id": name, "generator": GENERATOR, "seed": seed,
             "kind": "effect" if effects else "null", "families": families,
             "effects": truth_effects, "locations": [{"family": e["family"], "where": e["where"]} for e in effects],
             "parameter_perturbation": {"fraction": fraction, "factors": factors},
             "concealment": concealment,
             # the same measure on the held-out recording, which follows another reference: an
             # effect the held-out motions hardly reach (a bumper touched in the main recording
             # alone) cannot be confirmed there (DESIGN.md's keep rule on held-out data)
             "heldout_visibility": concealment_stats(cfg, held) if effects else None,
             "recordings": {**paths, "main_seconds": seconds, "heldout_seconds": heldout_seconds, "rate_hz": 100.0,
                            "noise_sd": {"angle_rad": ANGLE_NOISE_RAD, "pressure_pa": PRESSURE_NOISE_PA}},
             "tracking_rms_deg": {"main": _tracking(main), "heldout": _tracking(held)},
             "seeds": seeds, "wall_seconds": round(time.perf_counter() - t_start, 2)}
    tmp = out / f"{name}.truth.json.tmp"
    tmp.write_text(json.dumps(truth, indent=1, default=float))
    os.replace(tmp, out / f"{name}.truth.json")
    return truth
