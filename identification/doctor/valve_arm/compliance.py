"""Name: a line's volume is constant; a compliant wall's grows with pressure.

A tube between valve and chamber adds a fixed volume to the chamber (line_dynamics), and one
whose wave time is 1-3 ms shows as that volume alone.  A chamber whose wall, bellows or hose
yields under pressure also holds more air than the model, but by an amount that grows with
the pressure: V = V_0 + C_w (p - p_room), so dp/dt = n (R T mdot - p dV_piston/dt) /
(V + n p C_w) (paper 002 eq. 9 with V a function of p).  The vocabulary has no family for it.

Before a line is named, the same chamber is fitted with a compliant wall instead (its
compliance and the calibration, no tube): when the wall replays the recording clearly better
than the tube (WALL_MARGIN) and the held-out pressures no worse, or the held-out pressures
clearly better (WALL_HELDOUT_MARGIN) and the training ones no worse, the extra air follows the
pressure, not a tube, and the place is reported ``unexplained`` with the compliance it implies.

A chamber that stays within a narrow band of pressure (arm2's b chambers held near 6 bar)
cannot show the difference: a wall's extra capacity C ((1 + n) p - p_room) is then a constant
volume, as a tube's without a measurable delay is.  When the line found there has no delay
(LINE_DELAY_UNRESOLVED_S) and the wall replays as well, the line is named and the wall stays
its alternative (:func:`wall_alternative`), the evidence saying why they cannot be told apart.
"""
from __future__ import annotations

import numpy as np

from identification.base.statistics import locate_regime, windows

from .hypotheses import Hypothesis
from .pneumatic import replay
from .regimes import chamber_regimes
from .rules import HORIZON, DoctorRun, Finding
from .screening import Scored, chamber_rms, fit_pneumatic

#: the compliance's probe step and bound [m^3/Pa]: 1e-12 is 0.6 cm^3 more volume at 6 bar
#: gauge (arm2's dead volumes are 3-4 cm^3); 2e-11 more than doubles a chamber's capacity
WALL_PROBE_M3_PA, WALL_MAX_M3_PA = 1e-12, 2e-11
#: the share of the chamber's mean-square replay error over all training windows the wall
#: must remove beyond the tube's (and on held-out data it must not do worse): a tie goes to
#: the vocabulary's family.  On development recordings of the random-form generator
#: (2026-11-27) compliant walls gave 2.3-12 %, lumped RLC lines -1 to 0.4 %
WALL_MARGIN = 0.02
#: or the share of the held-out mean-square replay error the wall removes beyond the tube's,
#: the training error no worse: the wall's physics carries over to a recording it was not
#: fitted to, a tube's volume standing in for it less well.  Development recordings of fresh
#: runs 26-29 (looked at after reporting): three compliant walls 10-18 %, one at 0.8 % in
#: training (seed 646247227, named a delay-free line before); five lines with a fitted delay
#: under 1.1 ms (lumped RLC, Richer-Hurmuzlu) at most 0.7 %, the rest worse than the tube
WALL_HELDOUT_MARGIN = 0.05
#: a line whose fitted delay [s] is below this shows only its volume: one 1 ms step of the
#: replays (pneumatic.FINE_DT) at 100 Hz recordings
LINE_DELAY_UNRESOLVED_S = 1e-3


def _wall_hypothesis(where: dict, c: int) -> Hypothesis:
    def apply(mods, x):
        wall = np.zeros(mods.supply_scale.size) if mods.wall_compliance_m3_pa is None else mods.wall_compliance_m3_pa.copy()
        wall[c] = x[0]
        return mods.copy(wall_compliance_m3_pa=wall)
    return Hypothesis("outside_vocabulary", where, "pneumatic",
                      [("wall_compliance_m3_pa", 0.0, 0.0, WALL_MAX_M3_PA, WALL_PROBE_M3_PA)], [c], apply=apply)


def compliant_wall(run: DoctorRun, finding: Finding) -> tuple[dict | None, bool]:
    """(the unexplained entry of ``finding``'s chamber when a compliant wall replays it clearly
    better than the line does (WALL_MARGIN in training or WALL_HELDOUT_MARGIN held out), else
    None; whether the wall is the line's alternative instead: it replays within those margins
    of the line both ways and the line's delay is unresolved)."""
    line = finding.scored
    c = line.hyp.chambers[0]
    wall = Scored(_wall_hypothesis(finding.where, c), 0.0)
    fit_pneumatic(wall, run.exp, run.fit_win, run.mods, run.sigma)
    after = chamber_rms(run.held, run.win_h, wall.mods)[c]
    train_wall, train_line = (chamber_rms(run.exp, run.win, m)[c] for m in (wall.mods, line.mods))
    held_line = line.heldout_after[c]
    clear_in_training = train_wall ** 2 <= (1.0 - WALL_MARGIN) * train_line ** 2 and after <= held_line
    clear_held_out = after ** 2 <= (1.0 - WALL_HELDOUT_MARGIN) * held_line ** 2 and train_wall <= train_line
    if not (clear_in_training or clear_held_out):
        as_good = (train_wall ** 2 <= (1.0 + WALL_MARGIN) * train_line ** 2
                   and after ** 2 <= (1.0 + WALL_HELDOUT_MARGIN) * held_line ** 2)
        return None, as_good and delay_unresolved(finding)
    value, se = float(wall.fit.values[-1]), float(wall.fit.stderr[-1])
    before = line.heldout_before[c]
    pred, meas = replay(run.held, run.win_h, run.mods)
    r = (pred - meas)[:, :, c].ravel()
    idx = (run.win_h.starts[:, None] + 1 + np.arange(HORIZON)[None]).ravel()
    regime, _, _ = locate_regime(r, {k: v[idx] for k, v in chamber_regimes(run.held, c).items()})
    gauge = run.robot.tables.supply_pa - run.robot.tables.room_pa
    return ({
        "where": dict(finding.where), "regime": regime, "residual": "pressure",
        "share_of_residual": float(1.0 - (after / before) ** 2) if before > 0 else 0.0,
        "depends_on": ["pressure level", "volume"], "suggests": [], "windows": windows(run.held.t[idx], r),
        "wall_compliance_m3_pa": {"value": value, "stderr": se},
        "evidence": (f"the chamber holds more air than the model, growing with its pressure: a compliant wall "
                     f"(dV/dp {value:.2g} m^3/Pa, {1e6 * value * gauge:.2f} cm^3 at the supply's gauge pressure) "
                     f"predicts its held-out pressures to {after:.0f} Pa RMS, a tube's fixed volume "
                     f"(line_dynamics) to {line.heldout_after[c]:.0f} Pa (from {before:.0f} Pa); the library "
                     "has no family for a wall that yields")}, False)


def delay_unresolved(finding: Finding) -> bool:
    """Whether ``finding`` (a line) shows no delay, only a volume: its delay_volume form's delay,
    or its lumped_rc form's time constant, under LINE_DELAY_UNRESOLVED_S."""
    p = finding.params
    delay = p.get("delay_s", p.get("time_constant_s", {})).get("value", np.inf)
    return delay < LINE_DELAY_UNRESOLVED_S


def wall_alternative(finding: Finding) -> Finding:
    """``finding`` (a line with no delay, a compliant wall replaying its chamber as well) with
    the wall as its alternative and the evidence saying why."""
    finding.alternatives = ["outside_vocabulary"] + [a for a in finding.alternatives if a != "outside_vocabulary"]
    finding.evidence = ("no delay is seen, only more volume than the model: a tube's, or a compliant wall's "
                        "(outside the vocabulary), which replays this chamber as well (a wall's extra volume "
                        "grows with the pressure, nearly constant where the pressure stays in a narrow band); "
                        "a recording that takes this chamber through a wider range of pressures tells them apart")
    return finding
