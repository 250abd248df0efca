"""Locate: where and when each finding acts on the held-out data (regime, time windows,
block-bootstrap inclusion), and what nothing explains (chambers above the common floor,
joints whose torque the library does not hold)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.base.statistics import bootstrap_inclusion, locate_energy, locate_regime, robust_ceiling, windows

from .flex_check import flexible_unexplained
from .pneumatic import replay
from .pneumatic_mods import PneumaticMods
from .hypotheses import ANGLE_PROFILE_BIN_RAD
from .output_error import locate_output_error
from .regimes import chamber_regimes, joint_regimes
from .rules import HORIZON, MECH_KEEP, PNEU_KEEP, TRAIN_RATIO, UNEXPLAINED_RATIO, DoctorRun, Finding
from .torque_judge import joint_residual, mech_block, stacked_regressors
from .sensor_offsets import apply_offset


@dataclass
class Located:
    """The held-out pressure residuals the location used, and what it left unexplained."""

    res_h: np.ndarray
    """(W, H, C) held-out pressure replay residual with the findings [Pa]"""
    res_base_h: np.ndarray
    """... without them"""
    rms_c: np.ndarray
    """(C,) held-out RMS per chamber [Pa]"""
    rms_t: np.ndarray
    """(C,) training RMS per chamber [Pa]"""
    unexplained: list
    flexible: dict
    """every place's flexible mass-flow correction (flexible.summary)"""


def locate(run: DoctorRun, flags: list) -> Located:
    """Each finding's regime, windows and inclusion; then the unexplained entries (``flags``:
    the calibration scales that moved, named in a chamber's evidence)."""
    held, win_h, mods = run.held, run.win_h, run.mods
    pred_h, meas_h = replay(held, win_h, mods)
    res_h = pred_h - meas_h                               # (W, H, C)
    idx_h = (win_h.starts[:, None] + 1 + np.arange(HORIZON)[None]).ravel()
    t_h = held.t[idx_h]
    pred_t, meas_t = replay(run.exp, run.win, mods)
    for f in run.findings:
        if f.scored.hyp.kind == "pneumatic":
            _locate_pneumatic(run, f, meas_h, res_h, idx_h, t_h, pred_t - meas_t)
        elif f.output_error:
            locate_output_error(run, f)
        else:
            _locate_mechanical(run, f)
        if f.alternative_places:
            # the effect is at one of these places, which the sensors cannot tell apart: the
            # probability of any one of them (the exact place the report's reader acts on)
            f.inclusion /= len(f.alternative_places)
    unexplained = [outside_torque(run.robot, held, run.td_h, run.rfit, j, f, gain, by, run.outside_angles.get(j))
                   for j, f, gain, by in run.outside]
    rms_c = np.sqrt(np.mean(res_h ** 2, axis=(0, 1)))
    rms_t = np.sqrt(np.mean((pred_t - meas_t) ** 2, axis=(0, 1)))
    pred_b, _ = replay(held, win_h, mods_without_all(mods, run.findings))
    res_base_h = pred_b - meas_h                          # (W, H, C) before the findings
    flex, flex_summary = flexible_unexplained(run)
    unexplained += run.outside_chambers
    unexplained += [u for u in flex if u["where"] not in [x["where"] for x in run.outside_chambers]]
    # the replay-RMS rule, for a chamber the flexible correction did not already report
    unexplained += [u for u in _unexplained_chambers(run, res_h, res_base_h, rms_c, rms_t, idx_h, t_h, flags)
                    if u["where"] not in [x["where"] for x in flex + run.outside_chambers]]
    return Located(res_h, res_base_h, rms_c, rms_t, unexplained, flex_summary)


#: A finding's regime is where it removes the most of its place's residual per unit time, on
#: the training data (its held-out NRMSE in that regime is then a test, not a choice): the
#: residual before it alone puts every finding where the model is worst anyway (Coulomb
#: friction and stiction at "high velocity", where the torque balance's error grows with the
#: motion, on fresh run 11's seeds).


def _locate_pneumatic(run: DoctorRun, f: Finding, meas_h, res_h, idx_h, t_h, res_t) -> None:
    cs = f.scored.hyp.chambers
    p_before, _ = replay(run.held, run.win_h, without_finding(run.mods, f))
    r = ((p_before - meas_h)[:, :, cs] ** 2).sum(axis=2).ravel() ** 0.5
    e_before = ((p_before - meas_h)[:, :, cs] ** 2).sum(axis=(1, 2))
    e_after = (res_h[:, :, cs] ** 2).sum(axis=(1, 2))
    f.inclusion = bootstrap_inclusion(e_before, e_after, PNEU_KEEP)
    pred_t0, meas_t = replay(run.exp, run.win, without_finding(run.mods, f))
    removed = ((pred_t0 - meas_t)[:, :, cs] ** 2 - res_t[:, :, cs] ** 2).sum(axis=2).ravel()
    idx_t = (run.win.starts[:, None] + 1 + np.arange(HORIZON)[None]).ravel()
    f.regime, lift, share = locate_energy(removed, {k: v[idx_t] for k, v in chamber_regimes(run.exp, cs[0]).items()})
    f.regimes = chamber_regimes(run.held, cs[0])
    f.windows = windows(t_h, r)


def _locate_mechanical(run: DoctorRun, f: Finding) -> None:
    held, td_h = run.held, run.td_h
    j = f.scored.hyp.joint
    r = joint_residual(td_h, run.rfit, j)
    removed = joint_residual(run.td, run.rfit, j) ** 2 - _residual_after(run, run.exp, run.td, j) ** 2
    f.regime, lift, share = locate_energy(removed, joint_regimes(run.exp, j))
    f.regimes = joint_regimes(held, j)
    f.windows = windows(held.t, r)
    after = _residual_after(run, held, td_h, j)
    nb_ = r.size // 100
    f.inclusion = bootstrap_inclusion((r[: nb_ * 100] ** 2).reshape(nb_, 100).sum(1),
                                      (after[: nb_ * 100] ** 2).reshape(nb_, 100).sum(1), MECH_KEEP)


def _residual_after(run: DoctorRun, exp, td, j: int) -> np.ndarray:
    """(N,) joint j's torque equation error with the final fit's rigid body and kept terms (0
    where the torque data are not valid)."""
    full = stacked_regressors(run.kept_mech, exp, td)
    after = td.residual[:, j] - np.einsum("np,p->n", np.concatenate([td.regressors, full], axis=2)[:, j],
                                          run.final_rfit.values)
    return np.where(td.valid, after, 0.0)


def _unexplained_chambers(run: DoctorRun, res_h, res_base_h, rms_c, rms_t, idx_h, t_h, flags) -> list:
    """Chambers whose held-out replay error stands above the chambers' common floor, in training
    too (a held-out excess alone is often a regime the training data did not visit, not
    missing physics), and that no finding explains."""
    base_rms = np.sqrt(np.mean(res_base_h ** 2, axis=(0, 1)))
    floor_h, floor_t = np.median(base_rms), np.median(rms_t)
    # on a robot with enough chambers, also above their spread (the floor set per robot from
    # the data): chambers of different sizes and valves replay with errors of different sizes
    ceiling_h, ceiling_t = robust_ceiling(base_rms, log=True), robust_ceiling(rms_t, log=True)
    explained = {c for f in run.findings for c in f.scored.hyp.chambers}
    out = []
    for c, (a, ch) in enumerate(run.robot.chamber_names):
        others = floor_h
        consistent = rms_t[c] >= max(TRAIN_RATIO * floor_t, ceiling_t)
        if (c in explained or rms_c[c] < max(UNEXPLAINED_RATIO * floor_h, ceiling_h) or rms_c[c] < 2 * run.sigma
                or not consistent):
            continue
        r = res_h[:, :, c].ravel()
        reg = chamber_regimes(run.held, c)
        name, lift, share = locate_regime(r, {k: v[idx_h] for k, v in reg.items()})
        moved = [x for x in flags if f"{a}.{ch}" in x]
        out.append({"where": {"actuator": a, "chamber": ch}, "regime": name, "residual": "pressure",
                    "share_of_residual": float(np.sum(res_h[:, :, c] ** 2) / np.sum(res_h ** 2)),
                    "windows": windows(t_h, r),
                    "rms_pa": float(rms_c[c]), "chambers_median_rms_pa": float(others),
                    "evidence": f"held-out pressure replay error {rms_c[c]:.0f} Pa against a median of "
                                f"{others:.0f} Pa over the chambers (training: {rms_t[c]:.0f} vs {floor_t:.0f} Pa); "
                                f"no effect of the library explains it"
                                + (f"; calibration moved {', '.join(moved)}" if moved else "")})
    return out


def outside_torque(robot, held, td_h, rfit, j: int, best: Finding | None, yard_gain: float,
                   by: str = "state", angles: tuple | None = None) -> dict:
    """The unexplained entry of joint j, whose torque residual a smooth function of its state
    (``by`` "state") or a torque of its angle alone ("angle": torque_judge.outside_without_finding)
    takes up far better than the library's best effect (``best``; None: no library effect paid
    at all there); ``angles``: the joint's held-out angle NRMSE in the pressure-driven replay
    without and with that torque, where the search judged it so."""
    r = joint_residual(td_h, rfit, j)
    # in 0.1 s means: the raw equation error is mostly noise from differentiating the angles twice
    block = mech_block(held)
    r = np.convolve(r, np.ones(block) / block, mode="same")
    name, _, _ = locate_regime(r, joint_regimes(held, j))
    return {"where": {"joint": robot.joint_names[j]}, "regime": name, "residual": "torque",
            "share_of_residual": float(yard_gain), "windows": windows(held.t, r),
            "depends_on": ["joint angle and velocity"] if by == "state" else ["joint angle"],
            "suggests": [],  # a yardstick, not a family: nothing of the library took it up
            "evidence": (f"a smooth torque of the joint's angle and velocity removes {100 * yard_gain:.0f} % of its "
                         if by == "state" else
                         f"a torque of the joint's angle alone, in {ANGLE_PROFILE_BIN_RAD:g} rad bins, removes "
                         f"{100 * yard_gain:.0f} % of its ")
                        + (f"held-out torque residual, the library's best ({best.family}) only "
                           f"{100 * best.heldout_gain:.0f} %" if best is not None else
                           "held-out torque residual, and no library effect pays there")
                        + (": a torque the library does not hold (a spring, a hose or cable pulling on the link, ...)"
                           if by == "state" else
                           ": a torque the library does not hold that varies along the angle (a detent, cogging, a cam)")
                        + ("" if angles is None else
                           f"; with it the rigid body driven by the measured pressures replays the held-out angle at "
                           f"NRMSE {angles[1]:.3g} ({angles[0]:.3g} without)")}


def without_finding(mods: PneumaticMods, f: Finding) -> PneumaticMods:
    """The final chamber model without finding f's effect (its parameter set to the null value)."""
    return f.scored.hyp.switched_off(mods)


def mods_without_all(mods, findings):
    """The final chamber model without any finding's effect (what the baseline replays run)."""
    for f in findings:
        h = f.scored.hyp
        if h.kind == "pneumatic":
            mods = without_finding(mods, f)
        elif h.family == "pressure_sensor_offset":  # found by the torque balance
            mods = apply_offset(mods, h.chambers[0], 0.0, mods.supply_scale.size)
    return mods
