"""``pneumasim doctor``: locate, name, model and fit the physics a simulation left out.

Workflow (issue "The mismatch finder"):
1. read and check the recordings; hold out data (given files, or the last 30 %);
2. calibrate the nominal model first (chamber valve areas and dead volumes by pressure
   replays; link masses, damping, armature by inverse dynamics);
3. residuals: pressure replays and torque equation error; noise floors from the data;
4. locate: channels above their floor, time windows, the regime holding the residual;
5. name: score every hypothesis (score test), fit the promising ones jointly with the
   calibration, keep one only when it pays on held-out data; greedy, a few rounds;
   isolability when two explain equally; what nothing explains is "unexplained";
6. fit and prove: parameters with standard errors, bootstrap inclusion probability,
   coupled short replays (MuJoCo + chambers) on held-out data before and after;
7. report: report.json, report.md with plots, an .rrd, and a ten-second summary.
"""
from __future__ import annotations

import copy
import time

import numpy as np
from threadpoolctl import threadpool_limits

from identification.base.memory import return_freed_arrays
from identification.base.reporting import with_error
from identification.base.statistics import input_xcorr, ljung_box, ljung_box_p
from pneumatics.effects.from_finding import form_of
from pneumatics.errors import RecordingError
from pneumatics.recording import validate
from pneumatics.recording_checks import check_for_robot
from pneumatics.robot import Robot

from .angle_replay import body_calibration_check, final_mech_mods
from .calibrate import fit_chambers, pressure_sigma
from .data import MIN_ROWS, pool, prepare, split
from .flex_check import block_samples
from .final_fit import (final_calibration, final_joint_fit, follow_angle_sensors, scale_stderr,
                        withdraw_angle_worsening, withdraw_worsening, worsening)
from .fitted_model import fitted_model
from .locate import Located, locate, mods_without_all
from .mechanics import fit_rigid_body, hold_nominal
from .torque_balance import torque_data
from .output_error import search_output_error
from .pneumatic import Windows
from .pneumatic_mods import PneumaticMods
from .replay import MechMods, coupled_replay, typical_window_ratio
from .rules import HOLDOUT_SHARE, HORIZON, DoctorRun, Finding
from .search import search_mechanical, search_pneumatic, start_torque_balance
from .twin import twin_gains
from .weak_supply import weak_supply_finding


def diagnose(robot: Robot, recordings, holdouts=(), progress=None) -> dict:
    """Run the doctor; returns the report dict (DESIGN.md report.json) with extras.

    BLAS runs on one thread: the doctor's least squares are small (a few thousand rows, tens to
    a hundred columns), where OpenBLAS's threads only add their start-up, and on a busy machine
    they spin against each other: the humanoid38 rigid-body calibration took 196 s with them
    and 2.7 s without at a load of 7 on 2 cores.  It also gives the same bits as a sweep
    worker (workflow.sweep.cases.one_thread), so a benchmark case and the CLI agree.

    Arrays of 1 MiB or more are handed back to the operating system when freed
    (identification.base.memory.return_freed_arrays, for the whole process): under glibc's
    default a humanoid38 case's resident memory ratcheted up to 4822 MiB, 2548 MiB without."""
    return_freed_arrays()
    with threadpool_limits(limits=1, user_api="blas"):
        return _diagnose(robot, recordings, holdouts, progress)


def _diagnose(robot: Robot, recordings, holdouts, progress) -> dict:
    t_start = time.perf_counter()

    def say(msg):
        if progress:
            progress(msg)

    run, held_recs = _calibrated_run(robot, recordings, holdouts, say)
    calibrated = {n: float(np.exp(v)) for n, v in zip(run.cfit.names, run.cfit.values)}
    calibrated.update({n: float(1 + v) for n, v in zip(run.rfit.names, run.rfit.values)})
    search_pneumatic(run, say)
    start_torque_balance(run)
    if run.td.held_nominal:  # the torque balance does not predict this robot's angles
        search_output_error(run, say)
    search_mechanical(run, say)
    final_joint_fit(run)
    follow_angle_sensors(run)
    withdraw_angle_worsening(run, say)
    final_cal, cal_se, flags = final_calibration(run)
    say("locating regimes and windows")
    located = locate(run, flags)
    if not located.unexplained and (weak := weak_supply_finding(run)) is not None:
        # nothing found or unexplained, but the supply's droop shows in every chamber
        say(f"a weak supply droop: {100 * weak.heldout_gain:.0f} % of the chambers' held-out residual")
        run.findings.append(weak)
        run.mods = weak.scored.mods
        final_cal, cal_se, flags = final_calibration(run)
        located = locate(run, flags)
    say("coupled replays on held-out data (before/after)")
    replays = _prove(run)
    while worse := worsening(run):  # the keep rule on what the user runs: withdrawn, fitted again
        say(f"withdrawing {worse[0].family} at {worse[0].where}: it makes the held-out replay worse")
        withdraw_worsening(run, worse[0])
        final_joint_fit(run)
        follow_angle_sensors(run)
        withdraw_angle_worsening(run, say)
        final_cal, cal_se, flags = final_calibration(run)
        located = locate(run, flags)
        replays = _prove(run)
    report = _report(run, located, replays, calibrated, final_cal, flags)
    report["diagnostics"].update({
        "train_sources": [r.source for r in recordings],
        "heldout_sources": [r.source for r in held_recs] if holdouts else "last 30 % of each recording",
        "seconds": time.perf_counter() - t_start})
    report["_replays"] = replays
    # the fitted model as a file (model.toml, .fitted_model): the findings carry the final joint
    # fit's values and errors (final_fit), the ones the final replay runs
    final_params = [dict(f.params) for f in run.findings]
    report["_fitted"] = fitted_model(robot, report, final_params, scale_stderr(final_cal, cal_se))
    return report


def _calibrated_run(robot: Robot, recordings, holdouts, say) -> tuple[DoctorRun, list]:
    """Read and check the recordings, hold out data (the given files, or the last
    HOLDOUT_SHARE of each), calibrate the chambers (pressure replays) and the rigid body
    (inverse dynamics).  Returns the run and the held-out recordings."""
    if not recordings:
        raise RecordingError("doctor: no recordings given")
    _check_lengths(recordings, holdouts)
    for r in [*recordings, *holdouts]:  # whole recordings, so the error names the user's file
        validate(r, robot.joint_names, robot.actuator_names, model_name=robot.name)
        check_for_robot(r, robot)
    if holdouts:
        train_recs, held_recs = list(recordings), list(holdouts)
    else:  # the last 30 % of each recording is held out
        pairs = [split(r, HOLDOUT_SHARE) for r in recordings]
        train_recs, held_recs = [a for a, _ in pairs], [b for _, b in pairs]
    say("reading and checking recordings")
    exp = pool([prepare(robot, r, checked=True) for r in train_recs])
    held = pool([prepare(robot, r, checked=True) for r in held_recs])
    win = Windows.tile(len(exp.t), HORIZON, breaks=exp.breaks)
    sigma = pressure_sigma(exp)
    say("calibrating chambers (valve areas, dead volumes)")
    nominal = PneumaticMods.nominal(robot.tables.n_chambers)
    mods, cfit = fit_chambers(exp, win, nominal, sigma)
    say("calibrating the rigid body (masses, damping, armature)")
    td, td_h = torque_data(exp), torque_data(held)
    fresh_torque = ((copy.copy(td), exp), (copy.copy(td_h), held))   # before calibration mutates them
    rfit = fit_rigid_body(td)
    body_check = body_calibration_check(held, mods, rfit)
    if not body_check["kept"]:
        why = (f"the calibrated rigid body replayed the held-out angles worse than the nominal one (summed squared "
               f"NRMSE {body_check['calibrated_sum_nrmse2']:.3g} against {body_check['nominal_sum_nrmse2']:.3g})")
        say("the rigid body's calibration replays the held-out angles worse: the nominal body is kept")
        hold_nominal(td, why)
        hold_nominal(td_h, why)
        rfit = fit_rigid_body(td)
    run = DoctorRun(robot, exp, held, win,
                    fit_win=Windows.tile(len(exp.t), HORIZON, stride=2 * HORIZON, breaks=exp.breaks),
                    win_h=Windows.tile(len(held.t), HORIZON, breaks=held.breaks),
                    sigma=sigma, nominal=nominal, mods=mods, cfit=cfit, td=td, td_h=td_h, rfit=rfit,
                    fresh_torque=fresh_torque,
                    body_check=body_check)
    say("a twin of the recordings from the calibrated chambers (each chamber's flexible-correction floor)")
    run.twin_gains, run.twin_supply_in_time = twin_gains(exp, held, mods, sigma, block_samples(held))
    return run, held_recs


def _prove(run: DoctorRun) -> dict:
    """Coupled replays (MuJoCo and the chambers together) of the held-out data: the nominal
    model, the calibrated one without the findings, the final one; each finding's NRMSE on the
    channel it improves most, overall and in each regime of its place."""
    robot, held = run.robot, run.held
    mm_base = MechMods.from_fit(run.rfit, robot.joint_names)
    mm_final = final_mech_mods(run)
    # before the findings: the chambers as calibrated on the angles as read
    base_held, base_mods = (held, run.mods) if run.read is None else (run.read[1], run.read[2])
    base_replay = coupled_replay(base_held, mods_without_all(base_mods, run.findings), mm_base)
    nominal_replay = coupled_replay(held, run.nominal, MechMods())
    final_replay = coupled_replay(held, run.mods, mm_final)
    nb, nf = base_replay.nrmse(), final_replay.nrmse()
    for f in run.findings:
        ch = max(_channels(f, robot), key=lambda c: nb[c] - nf[c])
        f.nrmse = {"before": nb[ch], "after": nf[ch], "channel": ch,
                   "typical_window_ratio": typical_window_ratio(base_replay, final_replay, ch)}
        # the channel's NRMSE inside each regime of the finding's place (those the replays visit)
        f.nrmse["by_regime"] = {name: {"before": base_replay.nrmse(m)[ch], "after": final_replay.nrmse(m)[ch],
                                       "share_of_time": float(np.mean(m[base_replay.index]))}
                                for name, m in f.regimes.items() if np.any(m[base_replay.index])}
        # "throughout" (or a regime the replays miss): the whole held-out data
        f.nrmse["in_regime"] = {k: f.nrmse["by_regime"].get(f.regime, {"before": nb[ch], "after": nf[ch]})[k]
                                for k in ("before", "after")}
        f.evidence = _evidence(f)
    return {"nominal": nominal_replay, "baseline": base_replay, "final": final_replay}


def _report(run: DoctorRun, located: Located, replays: dict, calibrated: dict, final_cal: dict, flags: list) -> dict:
    """The report dict of DESIGN.md's report.json (with diagnostics)."""
    robot, td, cfit, rfit = run.robot, run.td, run.cfit, run.rfit
    base_replay, final_replay = replays["baseline"], replays["final"]
    tests = _residual_tests(robot, run.held, run.win_h, located.res_h, located.res_base_h)
    chambers = [f"{a}.{c}" for a, c in robot.chamber_names]
    return {
        "model": robot.name,
        "verdict": "missing_physics" if run.findings or located.unexplained else "no_significant_mismatch",
        "baseline": {"heldout_nrmse": base_replay.nrmse(), "heldout_r2": base_replay.r2(),
                     "nominal_heldout_nrmse": replays["nominal"].nrmse()},
        "calibrated": calibrated,
        "calibrated_with_findings": final_cal,
        "findings": [_finding_json(f) for f in run.findings],
        "unexplained": located.unexplained,
        "after": {"heldout_nrmse": final_replay.nrmse()},
        "diagnostics": {
            "pressure_noise_pa": run.sigma,
            "calibration_flags": flags,
            "flexible_corrections": located.flexible,
            "withdrawn_after_final_fit": run.withdrawn,
            "unexplained_withdrawn": run.outside_withdrawn,
            "chamber_rms_heldout_pa": dict(zip(chambers, map(float, located.rms_c))),
            "chamber_rms_train_pa": dict(zip(chambers, map(float, located.rms_t))),
            "calibration_condition": cfit.condition,
            "rigid_body_condition": rfit.condition,
            "parameters_at_bounds": cfit.at_bound + rfit.at_bound,
            "rigid_body_kept_nominal": dict(td.fixed or {}),
            "rigid_body_calibration_replay": run.body_check,
            "output_error_screen": run.output_error_screen,
            "chamber_detection_limit": run.chamber_detection,
            "pneumatic_candidates": run.pneumatic_candidates,
            "output_error_candidates": run.output_error_candidates,
            **tests,
            "ljung_box_q_heldout_pressure": {k: v["after"]["q"] for k, v in tests["ljung_box_heldout_pressure"].items()},
            "train_seconds": float(run.exp.t[-1] - run.exp.t[0]),
            "heldout_seconds": float(run.held.t[-1] - run.held.t[0]),
        },
    }


def _check_lengths(recordings, holdouts):
    """Each fitted and held-out part needs data.MIN_ROWS rows; without held-out files the last
    HOLDOUT_SHARE of each recording is held out, so each recording needs MIN_ROWS / HOLDOUT_SHARE:
    say so up front, in the recording's own terms (not about a slice the user never made)."""
    need = MIN_ROWS if holdouts else int(np.ceil(MIN_ROWS / HOLDOUT_SHARE))
    for r in list(recordings) + list(holdouts):
        if len(r) < need:
            rate = r.rate_hz if len(r) > 1 else float("nan")
            why = ("" if holdouts else f"; without --holdout files the last {100 * HOLDOUT_SHARE:.0f} % is held "
                   f"out and each part needs {MIN_ROWS} rows")
            raise RecordingError(f"{r.source}: {len(r)} rows ({r.time[-1] - r.time[0]:.3g} s) is too short for the doctor: "
                                 f"it needs at least {need} rows ({need / rate:.3g} s at {rate:.4g} Hz){why}")


def _residual_tests(robot, held, win_h, res_after, res_before) -> dict:
    """Ljung's tests of the held-out pressure residuals (W, H, C) before and after the findings:
    whiteness (Ljung-Box Q over lags 1-20 with its chi-square tail probability) and the
    cross-correlation with the chamber's own valve command at lags 0-50 ms (Ljung 1999 §16.6).
    Each replay window (a restart from the measured pressures) is one trace; reported, not used
    to decide (the integrated error of a restarted replay is coloured even for an exact model)."""
    idx = win_h.starts[:, None] + 1 + np.arange(win_h.horizon)[None]         # (W, H)
    dt = float(np.median(np.diff(held.t)))
    lb, xc = {}, {}
    for c, (a, ch) in enumerate(robot.chamber_names):
        key = f"p_{ch}.{a}"
        u = [held.u[i, c] for i in idx]
        lb[key], xc[key] = {}, {}
        for when, res in (("before", res_before), ("after", res_after)):
            q = ljung_box(res[:, :, c].ravel())
            lb[key][when] = {"q": q, "p": ljung_box_p(q)}
            xc[key][when] = input_xcorr(list(res[:, :, c]), u, dt)
    return {"ljung_box_heldout_pressure": lb,
            "input_xcorr_heldout_pressure": {"input": "the chamber's valve command", **xc}}


def _channels(f: Finding, robot) -> list[str]:
    """The recorded channels a finding acts on (the report shows the one it improves most)."""
    w = f.where
    if "joint" in w:
        return [f"q.{w['joint']}"]
    if "chamber" in w:
        return [f"p_{w['chamber']}.{w['actuator']}"]
    if "actuator" in w:
        return [f"p_a.{w['actuator']}", f"p_b.{w['actuator']}"]
    return [f"p_{c}.{a}" for a, c in robot.chamber_names]


def _evidence(f: Finding) -> str:
    p = ", ".join(with_error(k, v, 3, 2) for k, v in f.params.items())
    where = " ".join(f"{k} {v}" for k, v in f.where.items())
    alt = f"; {' or '.join([f.family] + f.alternatives)}: these sensors cannot tell them apart" if f.alternatives else ""
    if f.alternative_places:
        other = [k for k in f.params if k.startswith("offset_pa_if_chamber_")]
        alt += ("; a constant force error of this cylinder: an offset on chamber a or on chamber b "
                f"({', '.join(other)}), these sensors cannot tell which for sure")
    judged = "" if f.scored.judged_by == "held-out data" else f" (judged by {f.scored.judged_by})"
    seen = f"; {f.evidence}" if f.evidence else ""  # what a naming test saw (breakaway.py)
    return (f"{f.family} at {where} ({p}) removes {100 * f.heldout_gain:.0f} % of the held-out "
            f"{'pressure' if f.scored.hyp.kind == 'pneumatic' else 'angle' if f.output_error else 'torque'} residual{judged}, concentrated in {f.regime}{alt}{seen}")


def _finding_json(f: Finding) -> dict:
    return {
        "effect": f.family,
        "form": form_of(f.family, f.params),
        "where": f.where,
        "regime": f.regime,
        "windows": f.windows,
        "parameters": f.params,
        "heldout_nrmse": {"before": f.nrmse.get("before"), "after": f.nrmse.get("after")},
        "heldout_channel": f.nrmse.get("channel"),
        "heldout_typical_window_ratio": f.nrmse.get("typical_window_ratio"),
        "heldout_nrmse_in_regime": f.nrmse.get("in_regime"),
        "heldout_nrmse_by_regime": f.nrmse.get("by_regime", {}),
        "heldout_nrmse_angle_replay": f.angle_replay or None,
        "heldout_equation_error_reduction": f.heldout_gain,
        "alternatives": f.alternatives,
        "alternative_places": f.alternative_places,
        "inclusion_probability": f.inclusion,
        "evidence": f.evidence,
    }
