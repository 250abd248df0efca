"""Where a pressure-sensor offset sits and how it enters the chamber model.

The torque balance sees a transducer's zero offset as a cylinder force error that either of the
cylinder's chambers explains (offset_a A_a = -offset_b A_b); :func:`offset_place` chooses the
chamber from the pressure replays and the chamber calibration.  :func:`apply_offset`,
:func:`offset_of_term` and :func:`corrected` put a fitted offset into the chamber model or take
it out of the measured pressures (effects.pressure_sensor_offset: measured = true + offset).
"""
from __future__ import annotations

import numpy as np

from .calibrate import fit_chambers
from .data import Experiment
from .hypotheses import pneumatic_hypotheses
from .pneumatic_mods import PneumaticMods
from .rules import ISOLABLE, PNEU_KEEP, DoctorRun, Finding
from .screening import chamber_rms, finding_params, fit_pneumatic, score_pneumatic


def apply_offset(mods: PneumaticMods, c: int, offset_pa: float, n_ch: int, drift_pa: float = 0.0,
                 time_constant_s: float = 0.0) -> PneumaticMods:
    """``mods`` with chamber c's pressure-sensor offset set to ``offset_pa`` [Pa] and its
    warm-up drift to ``drift_pa`` [Pa] over ``time_constant_s`` (none by default)."""
    arrays = {}
    for attr, value in (("sensor_offset_pa", offset_pa), ("sensor_drift_pa", drift_pa),
                        ("sensor_drift_tau_s", time_constant_s)):
        arr = np.zeros(n_ch) if getattr(mods, attr) is None else getattr(mods, attr).copy()
        arr[c] = value
        arrays[attr] = arr
    return mods.copy(**arrays)


def offset_of_term(mods: PneumaticMods, h, values, n_ch: int) -> PneumaticMods:
    """``mods`` with the pressure-sensor offset of the torque-balance term ``h`` at ``values``
    (offset, and the drift of the warm-up form with its chosen time constant)."""
    if len(values) > 1:
        return apply_offset(mods, h.chambers[0], float(values[0]), n_ch, float(values[1]),
                            h.fixed["time_constant_s"]["value"])
    return apply_offset(mods, h.chambers[0], float(values[0]), n_ch)


#: a chamber whose held-out replay gains this much more than the other's, with the torque
#: balance's offset put in its sensor and the calibration refitted, is named alone; closer, the
#: other chamber stays an alternative place.  On the development seeds (runs 5-9, 15 offsets the
#: free fits left at the cylinder) the better chamber was the right one in 11; the four wrong
#: ones led by 0.08-0.23, the right ones by 0.02-0.9.
OFFSET_MARGIN = 0.15

#: the calibration's departure from the datasheet (:func:`calibration_departure`) decides the
#: chamber when the other chamber's is this many times larger; closer, the held-out gain does.
#: On 25 development offsets of the random-form generator the free replay fits left at the
#: cylinder, the held-out gain alone named the right chamber in 19, the departure of the
#: cylinder's chambers alone in 21, this rule in 23; where the two disagreed, the departure was
#: right at ratios 1.5-2.7 (5 of 5), wrong at 1.08, 1.09 and 1.45.
DEPARTURE_RATIO = 1.3


def offset_place(run: DoctorRun, finding: Finding, scored: list) -> Finding:
    """Chambers a and b of one actuator explain a constant actuator-force error equally well in
    the torque balance (offset_a * A_a = -offset_b * A_b).  The pressure replays tell them apart
    only where the offset changes a chamber's flow (near the supply and room asymptotes, where a
    restarted replay runs into the wrong end pressure).  First :func:`offset_chamber` fits the
    offset freely in each chamber's replays and names a chamber when only its held-out replay
    pays (ISOLABLE).  Otherwise :func:`fixed_offset_evidence` puts the torque balance's offset
    (its size and sign for that chamber) into each chamber's sensor and refits the calibration.
    The first calibration took the offset up by moving its own chamber's valve-area and volume
    scales; taken out of the right sensor, they return towards the datasheet.  The chamber whose
    refitted calibration departs least from it is named when the other's departs DEPARTURE_RATIO
    times more; else the chamber whose held-out replay gains more.  The other chamber stays an
    alternative place unless both views agree and its gain trails by OFFSET_MARGIN."""
    act = finding.where["actuator"]
    form = [p[0] for p in finding.scored.hyp.params]  # the constant or the drifting offset
    cands = {s.hyp.where["chamber"]: s for s in scored if s.hyp.family == "pressure_sensor_offset"
             and s.hyp.where["actuator"] == act and [p[0] for p in s.hyp.params] == form}
    offsets = {ch: (s.hyp, s.fit.values[-len(form):]) for ch, s in cands.items()}
    chamber, alternatives = offset_chamber_choice(run, act, offsets, drifting=len(form) > 1)
    primary = cands.get(chamber or "a", finding.scored)
    where = {"actuator": act} if chamber is None else {"actuator": act, "chamber": chamber}
    f = Finding(primary, primary.hyp.family, where, finding_params(primary), primary.heldout_gain,
                finding.alternatives)
    if chamber is None or alternatives:
        for ch, s in cands.items():
            if s is not primary:
                f.params[f"offset_pa_if_chamber_{ch}"] = finding_params(s)["offset_pa"]
        f.alternative_places = [{"actuator": act, "chamber": ch} for ch in sorted(cands)]
    return f


def offset_chamber_choice(run: DoctorRun, act: str, offsets: dict, drifting: bool = False) -> tuple:
    """(the chamber of actuator ``act`` named, or None; the chambers left as alternative places)
    for a force error of its cylinder that a sensor offset on either chamber explains
    (``offsets``: chamber -> (its offset hypothesis, the offset's values there)):
    :func:`offset_chamber` first, then :func:`fixed_offset_evidence` (offset_place's rules)."""
    chamber, alternatives = offset_chamber(run, act, drifting=drifting), []
    if chamber is None and len(offsets) > 1:
        gains, departure = fixed_offset_evidence(run, offsets)
        by_gain, nearest = max(gains, key=gains.get), min(departure, key=departure.get)
        clear = all(d >= DEPARTURE_RATIO * departure[nearest] for ch, d in departure.items() if ch != nearest)
        chamber = nearest if clear else by_gain
        if by_gain != nearest or any(g > gains[chamber] - OFFSET_MARGIN for ch, g in gains.items() if ch != chamber):
            alternatives = sorted(offsets)
    return chamber, alternatives


def calibration_departure(mods: PneumaticMods, chambers=None) -> float:
    """How far a chamber calibration sits from the datasheet: the sum over the ``chambers``
    (indices; None: every chamber) of the squared logarithms of their supply-area, exhaust-area
    and dead-volume scales."""
    idx = slice(None) if chambers is None else list(chambers)
    scales = np.concatenate([mods.supply_scale[idx], mods.exhaust_scale[idx], mods.dead_volume_scale[idx]])
    return float(np.sum(np.log(scales) ** 2))


def fixed_offset_evidence(run: DoctorRun, offsets: dict) -> tuple[dict, dict]:
    """(chamber -> held-out gain of its replay (1 - mean square ratio), chamber ->
    :func:`calibration_departure`) with the offset fitted for that chamber (``offsets``:
    chamber -> (its offset hypothesis, the offset's values)) taken out of its sensor and the
    chamber calibration refitted on the training windows.  No offset is fitted here: a chamber
    whose sensor is right is made worse by the other's offset.  The departure counts the
    cylinder's own chambers: the others' residuals do not see the offset, and on a robot with
    many chambers their refits' small differences would add up to more than the cylinder's."""
    base = chamber_rms(run.held, run.win_h, run.mods)
    cylinder = [h.chambers[0] for h, _ in offsets.values()]
    gains, departure = {}, {}
    for ch, (h, values) in offsets.items():
        c = h.chambers[0]
        mods, _ = fit_chambers(run.exp, run.fit_win, offset_of_term(run.mods, h, values, base.size), run.sigma)
        gains[ch] = 1.0 - (chamber_rms(run.held, run.win_h, mods)[c] / max(base[c], 1e-300)) ** 2
        departure[ch] = calibration_departure(mods, cylinder)
    return gains, departure


def offset_chamber(run: DoctorRun, act: str, drifting: bool = False) -> str | None:
    """The chamber of actuator ``act`` whose pressure replays a sensor offset explains: each
    chamber's offset (``drifting``: the warm-up form) fitted with the chamber calibration (the
    replays' own pneumatic hypothesis), judged by the reduction of that chamber's held-out mean
    square.  The best if it pays (>= PNEU_KEEP) and no other chamber comes within ISOLABLE of
    it; else None."""
    hyps = [h for h in pneumatic_hypotheses(run.robot)
            if h.family == "pressure_sensor_offset" and h.where["actuator"] == act
            and (len(h.params) > 1) == drifting]
    trials, _ = score_pneumatic(run.exp, run.win, run.mods, hyps, run.sigma)
    base = chamber_rms(run.held, run.win_h, run.mods)
    gains = {}
    for s in trials:
        fit_pneumatic(s, run.exp, run.fit_win, run.mods, run.sigma)
        c = s.hyp.chambers[0]
        gains[s.hyp.where["chamber"]] = 1.0 - (chamber_rms(run.held, run.win_h, s.mods)[c] / max(base[c], 1e-300)) ** 2
    if not gains:
        return None
    best = max(gains, key=gains.get)
    if gains[best] >= PNEU_KEEP and all(g < ISOLABLE * gains[best] for ch, g in gains.items() if ch != best):
        return best
    return None


def corrected(exp: Experiment, mods: PneumaticMods) -> Experiment:
    """The experiment with the pressure-sensor offsets of ``mods`` (and their drifts) taken out
    of the measured pressures."""
    import dataclasses
    offset = mods.sensor_offsets(exp.clock_at())
    if offset is None:
        return exp
    return dataclasses.replace(exp, p=exp.p - offset, p_at_t=exp.p_at_t - offset)
