"""Name the joints' effects by the angles they replay (output error), where the torque balance
cannot be trusted to.

Where the rigid body's calibration was held nominal (angle_replay.body_calibration_check: the
torque balance fitted on the recording replayed its held-out angles worse than the nominal
body), the torque balance's equation error is dominated by what the samples do not resolve --
humanoid38 limit-cycles at 9-14 Hz under its PIDF, and inverse dynamics at the splines'
accelerations is off by up to the actuators' own torque (docs/humanoid_doctor.md).  Its fitted
values and held-out gains are then no evidence: a concealed Coulomb friction of 0.0168 N m at
humanoid38's right_wrist_yaw (development seed 951092721) took 0.055 of that joint's held-out
torque residual, below MECH_KEEP and behind the jaw's and a toe's; its torque-balance value was
twice the true one, and with it the joint's replayed held-out angle did not improve (0.996);
a true viscous friction at left_wrist_pitch (951092725) made that joint's held-out torque
residual worse.

The output-error method (Ljung, *System Identification*, 2nd ed., 1999, §4.2 and §7.3;
Gautier, Janot & Vandanjon, IEEE TCST 21(2), 2013, for robots) fits each candidate to the
angles the rigid body replays from the measured state, driven by the measured pressures
(angle_replay.pressure_driven_angles, 0.2 s windows): one Gauss-Newton step from zero on the
joint's own angle, the sensitivities taken by replaying a probe step.  Its standard errors are
cluster-robust with the replay windows as clusters (Liang & Zeger, Biometrika 73(1), 1986): a
window's errors are one draw, not H.

1. **Screen** (:func:`screened`): one replay per parameter and group of joints no one of which
   is an ancestor of another (:func:`joint_levels`; 5 x 11 replays of a third of the training
   windows on humanoid38, one of them the subtree masses'), every joint probed at once; each
   joint's family fitted on its own angle from them (a pressure-sensor offset beside its
   joint's subtree mass, mass_nuisance).
2. **Fit** (:func:`fit_by_output_error`): the candidates that pass the screen, alone (an
   offset beside its subtree mass), from their screened values (k replays for k parameters, one
   more for the mass; a Coulomb friction also as a stiction).
3. **Name** (:func:`search_output_error`): a fit whose values are physical and OUTPUT_ERROR_MIN_T
   cluster-robust errors from zero, that removes MIN_TRAIN_GAIN of its joint's training angle
   error and replays its joint's held-out angle at most KEEP_RATIO times the NRMSE without it;
   the best held-out ratio first, greedy, one effect per joint.

The right wrist's friction this way: 0.0174 N m (23 standard errors), the training angle's
mean square down 60 %, the held-out angle's NRMSE 0.080 -> 0.063; the left wrist's viscous
friction 0.0233 N m s/rad (true 0.0259), held-out NRMSE ratio 0.35.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.base.statistics import bootstrap_inclusion, locate_energy, robust_ceiling, windows

from .angle_replay import (
    CHAMBER_TERM,
    HORIZON_S,
    angle_nrmse,
    final_mech_mods,
    pressure_driven_angles,
    with_chamber_terms,
    with_replay_terms,
    without_chamber_terms,
)
from .calibrate import fit_chambers
from .hypotheses import mechanical_hypotheses
from .mass_nuisance import mass_sensitivity, partialled
from .replay import MechMods, window_starts
from .mechanics import fit_rigid_body
from .regimes import joint_regimes
from .rules import MAX_ROUNDS, MIN_T, DoctorRun, Finding, passes_keep_rule
from .screening import Scored
from .search import MECH_ATTRS, corrected_torque_data
from .sensor_offsets import offset_chamber_choice

#: the families fitted by output error (their first forms): the torque laws, the angle
#: sensor's offset and the pressure sensor's (constant) offset, whose replays need no placement
#: (end stops are placed by the torque balance's grid).  The screen fits the one-parameter
#: ones; a joint whose Coulomb friction passes it is fitted as a stiction too (a Coulomb level
#: and a breakaway excess).  A pressure-sensor offset is screened on each cylinder's chamber a
#: (the replay sees its force, which an offset on either chamber explains); one that passes is
#: fitted on both chambers and placed by the pressure replays (sensor_offsets.offset_chamber_choice).
#: Humanoid38's fresh run of 2026-12-03 (`f65ca87`, looked at after it was reported): offsets of
#: 3.9 and -7.7 kPa missed where the body was held nominal, the torque balance's offsets not
#: searched there and the pressure replays' calibration taking them up.  Family -> its parameter
SCREEN_FAMILIES = {"coulomb_friction": "coulomb_nm", "viscous_friction": "viscous_nm_s_per_rad",
                   "angle_sensor_offset": "offset_rad", "pressure_sensor_offset": "offset_pa"}
#: the screen's probe: a torque of this share of the joint's rms actuator torque (a Coulomb
#: level; over the joint's rms speed, a viscous coefficient), an angle offset of
#: PROBE_OFFSET_RAD, a pressure offset of PROBE_OFFSET_PA: small enough for the replay to answer
#: linearly, large against the replay's round-off
PROBE_TORQUE_SHARE = 0.02
PROBE_OFFSET_RAD = 0.005
#: (a pressure offset's replays answer a smaller step with round-off: the true 3.9 kPa offset of
#: development seed 151639044 fitted from a 1 kPa step at 2.97 kPa, 4.1 errors, on chamber a and
#: -2.1 kPa, 1.5 errors, on chamber b; from a 4 kPa step at 3.55 kPa, 6.0 errors, and -3.4 kPa,
#: 3.8 errors).  An offset's own fit steps by at least as much.
PROBE_OFFSET_PA = 4000.0
#: the screen replays every SCREEN_EVERY-th window of the training data (100 windows of 0.2 s
#: on a 60 s recording), the fits every TRAIN_EVERY-th (150)
SCREEN_EVERY = 3
TRAIN_EVERY = 2
#: share of its joint's training angle mean square a candidate must remove in the screen ...
SCREEN_GAIN = 0.1
#: ... and in its own fit
MIN_TRAIN_GAIN = 0.2
#: a named effect's parameters stand this many cluster-robust standard errors from zero: twice
#: the keep rule's MIN_T, because those errors count the noise but not the rigid body's own
#: mismatch, which the replays also carry.  On four development nulls of humanoid38 (60 s + 30 s,
#: +-3 % parameter errors; seeds 951092749-752) that mismatch gave viscous frictions of 4.0-6.8
#: standard errors at three joints (left_shoulder_pitch, neck_pitch, right_hip_yaw), each also
#: improving its held-out angle (NRMSE ratios 0.68-0.94): a replay that falls away from the
#: recording (an inverted pendulum at the hips, neck and shoulders) is held closer by any damping
OUTPUT_ERROR_MIN_T = 8.0
#: ... but a pressure-sensor offset's stands the keep rule's MIN_T from zero: a constant force is
#: no damping that holds a falling replay closer.  On humanoid38's development recordings of
#: 2026-12-03 (seeds 151639044 and 151639058-061, looked at after their fresh run) the true
#: 3.9 kPa offset at left_elbow.a was fitted from a 1 kPa step at 2.97 kPa, 4.1 errors (held-out
#: ratio 0.80, training gain 0.25), from a 4 kPa step at 3.55 kPa, 6.0 errors -- yet with
#: PROBE_OFFSET_PA the screen's own fit of it still fell short of MIN_T and it was missed; the
#: nulls' offsets of 4 errors or more removed under MIN_TRAIN_GAIN of
#: their joint's training angle error (the jaw's, 0.11-0.18) or replayed its held-out angle
#: worse (right_hip_roll, 98 errors, ratio 1.03)
OFFSET_MIN_T = MIN_T
#: the families fitted beside the mass of their joint's subtree (mass_nuisance): a constant
#: force, which a held-nominal body's mass error fakes where the joint's gravity torque varies little
MASS_NUISANCE = ("pressure_sensor_offset",)
#: a candidate is named when it replays its joint's held-out angle at most this many times the
#: NRMSE without it (a tenth of the mean square removed)
KEEP_RATIO = 0.95
#: at most this many screened candidates (best screen gain first) get their own fit
MAX_CANDIDATES = 8


@dataclass
class OutputErrorFit:
    """One candidate fitted by output error on its joint's angle."""

    scored: Scored          # the hypothesis fitted (its place and family)
    values: np.ndarray      # (k,) fitted parameters
    stderr: np.ndarray      # (k,) cluster-robust standard errors
    train_gain: float       # share of the joint's training angle mean square removed
    before: float = np.nan  # the joint's held-out angle NRMSE without it ...
    after: float = np.nan   # ... and with it

    @property
    def ratio(self) -> float:
        return self.after / max(self.before, 1e-300)


def terms_of(hyp, values) -> list:
    """[(MechMods attribute, joint, value)] of hypothesis ``hyp``'s parameters ``values``; a
    pressure-sensor offset's: [(CHAMBER_TERM, its chamber, value)]."""
    if hyp.family == "pressure_sensor_offset":
        return [(CHAMBER_TERM, hyp.chambers[0], float(values[0]))]
    return [(MECH_ATTRS[name], hyp.joint, float(v)) for (name, *_), v in zip(hyp.params, values)]


def replayed(exp, run: DoctorRun, mm: MechMods, terms, every: int = 1) -> np.ndarray:
    """pressure_driven_angles of ``exp`` with the run's chamber model and ``mm``, ``terms``
    (:func:`terms_of`) added to the one or the other."""
    J = len(run.robot.joint_names)
    return pressure_driven_angles(exp, with_chamber_terms(run.mods, terms), with_replay_terms(mm, terms, J),
                                  every=every)


def window_rows(exp, every: int) -> np.ndarray:
    """(W, H) the rows each replayed window of pressure_driven_angles(..., every) fills."""
    starts, H = window_starts(exp, HORIZON_S)
    rows = starts[::every, None] + 1 + np.arange(H)[None]
    return rows[np.all(rows < len(exp.t), axis=1)]


def joint_levels(robot) -> list[list[int]]:
    """The joints grouped by their place in the kinematic tree (how many joints lie between
    the root and them): no joint of a group is an ancestor of another, so a torque at each moves
    the others only through the bodies they share a parent in (humanoid38: 11 groups of 2-5)."""
    m, levels = robot.model, {}
    for j, name in enumerate(robot.joint_names):
        jnt = m.joint(name)
        body = int(jnt.bodyid[0])
        depth = int(jnt.id - m.body_jntadr[body])
        parent = int(m.body_parentid[body])
        while parent > 0:
            depth += int(m.body_jntnum[parent])
            parent = int(m.body_parentid[parent])
        levels.setdefault(depth, []).append(j)
    return [levels[d] for d in sorted(levels)]


def probe_steps(run: DoctorRun) -> dict:
    """parameter -> (J,) the screen's probe step at each joint (PROBE_TORQUE_SHARE, PROBE_OFFSET_RAD)."""
    tau = np.sqrt(np.mean(np.where(run.td.valid[:, None], run.td.tau_act, 0.0) ** 2, axis=0)
                  / max(float(np.mean(run.td.valid)), 1e-12))
    torque = np.maximum(PROBE_TORQUE_SHARE * tau, 1e-6)
    speed = np.maximum(np.sqrt(np.mean(run.exp.qd ** 2, axis=0)), 1e-3)
    return {"coulomb_nm": torque, "viscous_nm_s_per_rad": torque / speed,
            "offset_rad": np.full(tau.size, PROBE_OFFSET_RAD), "offset_pa": np.full(tau.size, PROBE_OFFSET_PA)}


def fit_by_output_error(run: DoctorRun, s, step: np.ndarray, base_mm: MechMods,
                        base_q: np.ndarray) -> OutputErrorFit | None:
    """Candidate ``s`` (a Scored hypothesis) fitted on its joint's training angle: the
    replay's change for each parameter's probe ``step`` (k,), one Gauss-Newton step from zero
    (``base_q``: the training replay of ``base_mm``, every TRAIN_EVERY-th window), beside its
    joint's subtree mass for a family of MASS_NUISANCE.  None when the replays do not move the
    angle in k directions."""
    h, exp = s.hyp, run.exp
    rows = window_rows(exp, TRAIN_EVERY)
    cols = []
    for i in range(len(h.params)):
        probe = np.zeros(len(h.params))
        probe[i] = step[i]
        q = replayed(exp, run, base_mm, terms_of(h, probe), every=TRAIN_EVERY)
        cols.append((q[rows, h.joint] - base_q[rows, h.joint]) / step[i])   # (W, H) d q_j / d theta_i
    A = np.stack(cols, axis=-1)                                            # (W, H, k)
    r = exp.q[rows, h.joint] - base_q[rows, h.joint]                       # (W, H)
    ok = np.all(np.isfinite(A), axis=(1, 2)) & np.all(np.isfinite(r), axis=1)
    if h.family in MASS_NUISANCE:
        nuisance = mass_sensitivity(exp, run, base_mm, base_q[rows], [h.joint], TRAIN_EVERY, rows)[:, :, h.joint]
        ok &= np.all(np.isfinite(nuisance), axis=1)
        cols = [partialled(A[ok, :, i], nuisance[ok], r[ok]) for i in range(A.shape[-1])]
        A, r, ok = np.stack([a for a, _ in cols], axis=-1), cols[0][1], np.ones(int(ok.sum()), bool)
    step_fit = gauss_newton_step(A[ok], r[ok])
    return None if step_fit is None else OutputErrorFit(s, *step_fit)


def gauss_newton_step(A: np.ndarray, r: np.ndarray) -> tuple | None:
    """(theta (k,), cluster-robust standard errors (k,), share of ``r``'s mean square removed)
    of the least-squares step r ~ A theta, with ``A`` (W, H, k) the sensitivities and ``r``
    (W, H) the residual of W windows of H rows each; the windows are the clusters (Liang &
    Zeger 1986: the sandwich (A'A)^-1 (sum_w g_w g_w') (A'A)^-1, g_w a window's score).  None
    when A's columns do not span k directions."""
    k = A.shape[-1]
    AtA = np.einsum("whk,whl->kl", A, A)
    if A.shape[0] <= k or not np.all(np.isfinite(AtA)) or np.linalg.matrix_rank(AtA) < k:
        return None
    theta = np.linalg.solve(AtA, np.einsum("whk,wh->k", A, r))
    e = r - A @ theta
    g = np.einsum("whk,wh->wk", A, e)                                    # each window's score
    inv = np.linalg.inv(AtA)
    cov = inv @ (g.T @ g) @ inv
    gain = 1.0 - float(np.sum(e ** 2)) / max(float(np.sum(r ** 2)), 1e-300)
    return theta, np.sqrt(np.maximum(np.diag(cov), 0.0)), gain


def physical(fit: OutputErrorFit, tested: bool = True) -> bool:
    """Frictions dissipate (every parameter within its hypothesis's bounds) and, if
    ``tested``, the fitted values pass the keep rule (MIN_T cluster-robust standard errors
    from zero)."""
    lo = np.array([p[2] for p in fit.scored.hyp.params], float)
    hi = np.array([p[3] for p in fit.scored.hyp.params], float)
    inside = bool(np.all(fit.values >= lo) and np.all(fit.values <= hi))
    return inside and (not tested or passes_keep_rule(fit.values, fit.stderr))


def significant(fit: OutputErrorFit) -> bool:
    """Every fitted value OUTPUT_ERROR_MIN_T (a pressure-sensor offset: OFFSET_MIN_T)
    cluster-robust standard errors from zero."""
    se = np.asarray(fit.stderr, float)
    t = OFFSET_MIN_T if fit.scored.hyp.family == "pressure_sensor_offset" else OUTPUT_ERROR_MIN_T
    return bool(np.all(np.isfinite(se)) and np.all(se > 0) and np.all(np.abs(fit.values) >= t * se))


def screened(run: DoctorRun, base_mm: MechMods) -> list[tuple]:
    """[(Scored hypothesis, probe step (k,))] worth their own fit: every joint's
    SCREEN_FAMILIES fitted on its training angle from the sensitivities of one replay per
    parameter and group of :func:`joint_levels` (every joint of the group probed at once:
    4 x 11 replays on humanoid38 instead of 4 x 38, and 11 of the subtree masses, the nuisance
    of MASS_NUISANCE's families: :func:`joint_data`), those that remove SCREEN_GAIN of it with
    a physical, significant value, best first, each Coulomb friction followed by the stiction
    at its joint; at most MAX_CANDIDATES places."""
    robot, exp, J = run.robot, run.exp, len(run.robot.joint_names)
    hyps, chamber_b = screen_hypotheses(run)
    steps, rows = probe_steps(run), window_rows(exp, SCREEN_EVERY)
    base = pressure_driven_angles(exp, run.mods, base_mm, every=SCREEN_EVERY)[rows]      # (W, H, J)
    r = exp.q[rows] - base
    passed = []
    for family in SCREEN_FAMILIES:
        param = SCREEN_FAMILIES[family]
        sens = np.full(base.shape, np.nan)
        for level in joint_levels(robot):
            probed = [j for j in level if (family, j) in hyps]
            if probed:
                terms = [t for j in probed for t in terms_of(hyps[(family, j)], [steps[param][j]])]
                q = replayed(exp, run, base_mm, terms, every=SCREEN_EVERY)[rows]
                for j in probed:
                    sens[:, :, j] = (q[:, :, j] - base[:, :, j]) / steps[param][j]
        nuisance = None
        if family in MASS_NUISANCE:  # each joint's subtree mass, probed a level at a time
            nuisance = np.full(base.shape, np.nan)
            for level in joint_levels(robot):
                got = mass_sensitivity(exp, run, base_mm, base, level, SCREEN_EVERY, rows)
                nuisance[:, :, level] = got[:, :, level]
        data = [joint_data(sens[:, :, j], r[:, :, j], None if nuisance is None else nuisance[:, :, j]) for j in range(J)]
        fits = []
        for j, (s_j, r_j) in enumerate(data):
            got = None if (family, j) not in hyps else gauss_newton_step(s_j[:, :, None], r_j)
            fits.append(None if got is None else OutputErrorFit(Scored(hyps[(family, j)], got[2]), *got))
        # what a joint's mismatch gives this family anyway: the gains of its physical fits at
        # every joint (an unphysical one counts as none), whose spread a true effect stands out of
        gains = [f.train_gain if f is not None and physical(f, tested=False) else 0.0 for f in fits]
        floor = max(SCREEN_GAIN, robust_ceiling(gains))
        limits = {robot.joint_names[j]: detection_limit(*data[j], f, family, floor)
                  for j, f in enumerate(fits) if f is not None}
        limits = {j: v for j, v in limits.items() if np.isfinite(v)}   # a joint the probe did not move: none
        run.output_error_screen[family] = {"floor": floor, "gains": dict(zip(robot.joint_names, gains)),
                                           "parameter": param, "detection_limit": limits}
        passed += [f for f in fits if f is not None and f.train_gain >= floor and physical(f)]
    passed.sort(key=lambda f: -f.train_gain)
    out = []
    for f in passed[:MAX_CANDIDATES]:
        step = f.values.copy()
        if f.scored.hyp.family == "pressure_sensor_offset":
            step = np.where(step < 0, -1.0, 1.0) * np.maximum(np.abs(step), PROBE_OFFSET_PA)
        out.append((f.scored, step))
        if f.scored.hyp.family == "coulomb_friction" and ("stiction", f.scored.hyp.joint) in hyps:
            out.append((Scored(hyps[("stiction", f.scored.hyp.joint)], f.train_gain), np.repeat(f.values, 2)))
        if f.scored.hyp.joint in chamber_b and f.scored.hyp.family == "pressure_sensor_offset":
            out.append((Scored(chamber_b[f.scored.hyp.joint], f.train_gain), -step))
    return out


def joint_data(sens: np.ndarray, r: np.ndarray, nuisance: np.ndarray | None = None) -> tuple:
    """(sensitivity, residual), each (W', H), of the windows where both (and the ``nuisance``'s
    sensitivity, if given) are finite; with a nuisance, each taken off its projection on it
    (mass_nuisance.partialled)."""
    ok = np.all(np.isfinite(sens), axis=1) & np.all(np.isfinite(r), axis=1)
    if nuisance is None:
        return sens[ok], r[ok]
    ok &= np.all(np.isfinite(nuisance), axis=1)
    return partialled(sens[ok], nuisance[ok], r[ok])


def detection_limit(sens: np.ndarray, r: np.ndarray, fit: OutputErrorFit, family: str, floor: float) -> float:
    """The smallest size of ``family``'s parameter at a joint that the rules could name there
    on this recording: the larger of (a) the value standing the naming rule's t (significant)
    from zero at the screen's cluster-robust standard error, and (b) the value whose replayed
    change removes the larger of the screen's ``floor`` and MIN_TRAIN_GAIN of the joint's
    training angle mean square, were the rest of that error (the replay's mismatch, ``r``
    (W, H) at the screen's windows, :func:`joint_data`'s) independent of it: a change of size theta with signature
    ``sens`` (W, H) removes g = |S theta|^2 / (|S theta|^2 + |r|^2), so theta = sqrt(g / (1 - g))
    |r| / |S|.  Below it a silent joint is no evidence that the effect is absent: the recording
    cannot show it through this replay.  An approximation (the screen's errors, the mismatch
    taken as independent), stated as such in the report."""
    t = OFFSET_MIN_T if family == "pressure_sensor_offset" else OUTPUT_ERROR_MIN_T
    g = max(floor, MIN_TRAIN_GAIN)
    s_norm = float(np.sqrt(np.sum(sens ** 2)))
    by_gain = np.sqrt(g / (1.0 - g)) * float(np.sqrt(np.sum(r ** 2))) / s_norm if s_norm > 0 else np.inf
    return float(max(t * float(fit.stderr[0]), by_gain))


def screen_hypotheses(run: DoctorRun) -> tuple[dict, dict]:
    """({(family, joint): the hypothesis the screen fits there}, {joint: the pressure-sensor
    offset on its cylinder's chamber b}): the first forms of SCREEN_FAMILIES and stiction not
    tried yet, a pressure-sensor offset on chamber a (none on a cylinder whose offset the
    pressure replays found)."""
    found = {f.where["actuator"] for f in run.findings if f.family == "pressure_sensor_offset"}
    hyps, chamber_b = {}, {}
    for h in mechanical_hypotheses(run.robot):
        if h.family not in (*SCREEN_FAMILIES, "stiction") or h.form or h.label in run.tried:
            continue
        if h.family != "pressure_sensor_offset":
            hyps[(h.family, h.joint)] = h
        elif h.where["actuator"] in found or run.robot.joint_names[h.joint] != h.where["actuator"]:
            continue
        elif h.where["chamber"] == "a":
            hyps[(h.family, h.joint)] = h
        else:
            chamber_b[h.joint] = h
    return hyps, chamber_b


def search_output_error(run: DoctorRun, say) -> None:
    """Up to MAX_ROUNDS rounds: fit every screened candidate by output error against the model
    as it stands, judge the promising ones on the held-out angles, name the best
    (:func:`named`); one effect per joint."""
    say("fitting joint effects to the angles they replay (the torque balance does not predict them)")
    body = fit_rigid_body(run.td, *run.base_extra) if run.base_extra else run.rfit
    cands = screened(run, final_mech_mods(run, fit=body))
    for rnd in range(MAX_ROUNDS):
        mm = final_mech_mods(run, fit=body)
        base_t = pressure_driven_angles(run.exp, run.mods, mm, every=TRAIN_EVERY)
        base_h = pressure_driven_angles(run.held, run.mods, mm)
        named_joints = {f.scored.hyp.joint for f in run.findings if f.output_error}
        every = [fit_by_output_error(run, s, step, mm, base_t) for s, step in cands if s.hyp.joint not in named_joints]
        every = [f for f in every if f is not None]
        fits = [f for f in every if f.train_gain >= MIN_TRAIN_GAIN and physical(f) and significant(f)]
        for f in fits:
            judge_heldout(run, f, mm, base_h)
        best = min((f for f in fits if f.ratio <= KEEP_RATIO), key=lambda f: f.ratio, default=None)
        run.output_error_candidates += [candidate_record(run, f, rnd, best) for f in every]
        if best is None:
            return
        where, places = best.scored.hyp.where, []
        if best.scored.hyp.family == "pressure_sensor_offset":
            best, where, places = placed_offset(run, best, every)
            if not np.isfinite(best.after):
                judge_heldout(run, best, mm, base_h)
        finding = named(run, best, where, places)
        say(f"{finding.family} at {finding.where}: its joint's held-out angle NRMSE "
            f"{best.before:.4g} -> {best.after:.4g} (output error)")
        run.findings.append(finding)
        run.tried.update(s.hyp.label for s, _ in cands if s.hyp.joint == best.scored.hyp.joint)
        if finding.family == "pressure_sensor_offset":
            take_offset(run, finding)


def refusal(f: OutputErrorFit) -> str:
    """Why candidate ``f`` was not named, in the rules' own terms ('' when every rule passed)."""
    t = OFFSET_MIN_T if f.scored.hyp.family == "pressure_sensor_offset" else OUTPUT_ERROR_MIN_T
    if f.train_gain < MIN_TRAIN_GAIN:
        return f"removes {f.train_gain:.2f} of its joint's training angle error, under {MIN_TRAIN_GAIN}"
    if not physical(f, tested=False):
        return "a value outside its physical bounds"
    if not significant(f):
        return f"a value under {t:g} cluster-robust standard errors from zero"
    if not f.ratio <= KEEP_RATIO:
        return f"its joint's held-out angle NRMSE ratio {f.ratio:.3f} over {KEEP_RATIO}"
    return ""


def candidate_record(run: DoctorRun, f: OutputErrorFit, round_: int, best: OutputErrorFit | None) -> dict:
    """What the report keeps of one output-error candidate of round ``round_``: its fit, its
    held-out judgement where it got one, and its verdict (named, beaten by the round's best at
    a lower held-out ratio, or the rule it failed) -- the answer to 'why was nothing named at
    this joint?'."""
    why = refusal(f)
    verdict = ("named" if f is best else f"refused: {why}" if why
               else f"passed, the round's best was {best.scored.hyp.label}")
    se = np.asarray(f.stderr, float)
    return {"hypothesis": f.scored.hyp.label, "round": round_ + 1, "joint": run.robot.joint_names[f.scored.hyp.joint],
            "values": [float(v) for v in f.values], "stderr": [float(e) for e in se],
            "t": [float(v / e) if e > 0 else None for v, e in zip(f.values, se)],
            "train_gain": float(f.train_gain),
            "heldout_nrmse": {"before": _or_none(f.before), "after": _or_none(f.after)},
            "verdict": verdict}


def _or_none(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def placed_offset(run: DoctorRun, best: OutputErrorFit, fits: list) -> tuple:
    """(the fit of the chamber named, the finding's place, its alternative places) of a
    cylinder's force error ``best`` that a pressure-sensor offset explains: its chambers'
    output-error fits (``fits``) handed to sensor_offsets.offset_chamber_choice, which the
    pressure replays and the chamber calibration decide (offset_place's rules).  No chamber:
    the place is the actuator, the offset carried on chamber a."""
    act = best.scored.hyp.where["actuator"]
    pair = {f.scored.hyp.where["chamber"]: f for f in fits if f.scored.hyp.family == "pressure_sensor_offset"
            and f.scored.hyp.where["actuator"] == act}
    offsets = {ch: (f.scored.hyp, f.values) for ch, f in pair.items()}
    chamber, alternatives = offset_chamber_choice(run, act, offsets)
    chosen = pair.get(chamber or "a", best)
    where = {"actuator": act} if chamber is None else {"actuator": act, "chamber": chamber}
    places = [{"actuator": act, "chamber": ch} for ch in sorted(pair)] if chamber is None or alternatives else []
    return chosen, where, places


def take_offset(run: DoctorRun, finding: Finding) -> None:
    """A pressure-sensor offset named by output error goes into the chamber model (the replays
    take it out of the measured pressures), the chambers are calibrated again beside it (the
    first calibration took part of it up in its chamber's areas and dead volume, as
    sensor_offsets.fixed_offset_evidence does), and the torque data are corrected by it."""
    run.mods, run.cfit = fit_chambers(run.exp, run.win, with_chamber_terms(run.mods, finding.replay_terms), run.sigma)
    run.td, run.td_h = corrected_torque_data(run, run.mods)
    run.rfit = fit_rigid_body(run.td)


def judge_heldout(run: DoctorRun, f: OutputErrorFit, mm: MechMods, base_h: np.ndarray) -> None:
    """``f``'s joint's held-out angle NRMSE without it (``base_h``: the held-out replay of
    ``mm``) and with it."""
    j, held = f.scored.hyp.joint, run.held
    q = replayed(held, run, mm, terms_of(f.scored.hyp, f.values))
    f.before, f.after = angle_nrmse(held, base_h, j), angle_nrmse(held, q, j)


def named(run: DoctorRun, fit: OutputErrorFit, where: dict | None = None, places=()) -> Finding:
    """The finding of an output-error fit at ``where`` (its hypothesis's place by default; a
    pressure-sensor offset's, :func:`placed_offset`, with its alternative ``places``): its
    parameters with their errors, judged by the joint's angle (``Scored.judged_by``), its
    torque-balance alternatives none (that balance is not evidence here)."""
    s, h = fit.scored, fit.scored.hyp
    s.judged_by = "its joint's angle replayed on held-out data"
    params = {name: {"value": float(v), "stderr": float(e)} for (name, *_), v, e in zip(h.params, fit.values, fit.stderr)}
    f = Finding(s, h.family, dict(where or h.where), params, 1.0 - fit.ratio ** 2, [],
                replay_terms=terms_of(h, fit.values), alternative_places=list(places))
    f.angle_replay = {"channel": f"q.{run.robot.joint_names[h.joint]}", "before": fit.before, "after": fit.after,
                      "replay_horizon_s": HORIZON_S}
    return f


#: the share of its joint's held-out angle mean square a finding must remove in a bootstrap
#: resample of the windows to count there (its inclusion probability): KEEP_RATIO's
OUTPUT_ERROR_KEEP = 1.0 - KEEP_RATIO ** 2


def locate_output_error(run: DoctorRun, f: Finding) -> None:
    """An output-error finding's regime (where it removes most of its joint's training angle
    error), windows (where its joint's held-out angle error is largest without it) and
    inclusion probability (a block bootstrap of the held-out windows: the share of resamples in
    which it still removes OUTPUT_ERROR_KEEP of the angle's mean square)."""
    j = f.scored.hyp.joint
    err, models = {}, ((without_chamber_terms(run.mods, f.replay_terms), final_mech_mods(run, without=f)), (run.mods, final_mech_mods(run)))
    for name, exp, every in (("train", run.exp, TRAIN_EVERY), ("held", run.held, 1)):
        err[name] = [pressure_driven_angles(exp, pm, mm, every=every)[:, j] - exp.q[:, j] for pm, mm in models]
    before, after = (np.nan_to_num(e) for e in err["train"])
    f.regime, _, _ = locate_energy(before ** 2 - after ** 2, joint_regimes(run.exp, j))
    f.regimes = joint_regimes(run.held, j)
    before, after = (np.nan_to_num(e) for e in err["held"])
    f.windows = windows(run.held.t, np.abs(before))
    rows = window_rows(run.held, 1)
    rows = rows[np.all(rows < len(run.held.t), axis=1)]
    f.inclusion = bootstrap_inclusion((before[rows] ** 2).sum(axis=1), (after[rows] ** 2).sum(axis=1), OUTPUT_ERROR_KEEP)

