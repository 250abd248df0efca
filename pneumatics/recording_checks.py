"""Checks of a recording against the model it meets: are the numbers in the units and the
ranges that robot can produce?  (recording.validate checks names and shapes; these check
physics.)  Each raises :class:`RecordingError` naming the file, the column, what it read and
the fix.

* Pressures are absolute [Pa].  A chamber is connected by its valve to the supply or to the
  room (the exhaust), so its pressure lies between about the room pressure and the supply
  (paper 002 eqs. 6-9: the orifice flows drive it towards one of the two).  A recording whose
  lowest readings sit near or below 0 Pa, or that never reaches the room pressure, holds
  gauge pressures (relative to the room); one far above the supply is in another unit.
* Joint positions are in rad (hinge) or m (slide) and stay inside the joint's range (plus a
  margin for encoder offsets and noise).  A hinge column whose values fit the range only once
  divided by 180/pi is in degrees; a slide column that fits once divided by 1000 is in mm.
"""
from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from .errors import RecordingError
from .recording import Recording, RecordingWarning

PRESSURE_PREFIXES = ("p_a", "p_b")
#: below this share of the room pressure no chamber reads (absolute): gauge values, an error
GAUGE_LOW_SHARE = 0.5
#: below this share a chamber reads only when expanded with its valve shut, which a robot's
#: chambers rarely are for long: a warning (a gauge recording whose chambers never came near
#: the room pressure cannot be told from an absolute one by its values alone)
SUBATMOSPHERIC_SHARE = 0.8
#: a gauge reading stays under the supply's gauge pressure (supply - room): a recording whose
#: highest column reads within this share of the room pressure of the supply (99th percentile)
#: is absolute, and its subatmospheric dips are a chamber expanded with its valve shut (a null
#: recording of humanoid38 under its PIDF, seed 534539595: neck_pitch a down to 0.79 x room, 70
#: of its 152 columns' 99th percentiles above supply - 0.75 x room)
ABSOLUTE_TOP_SHARE = 0.75
#: the highest pressure a chamber can reach is the supply; this factor leaves room for sensor
#: noise, supply ripple and a regulator set a little above the model's nominal supply
SUPPLY_MARGIN = 1.5
#: share of a joint's span a recording may stray outside its range: encoder offsets, noise, and a
#: joint driven into MuJoCo's soft limit (humanoid38's PIDF pushes head_pitch 0.09 rad, 10 % of
#: its span, past the limit); a wrong joint, unit or zero strays much further
RANGE_MARGIN = 0.25
GAUGE_FIX = ("add the room pressure: `pneumasim doctor --gauge ...` does it, or give the import map's "
             "column a gauge unit (Pa_gauge, kPa_gauge, bar_gauge, psi_gauge)")


def check_pressures(rec: Recording, room_pa: float, supply_pa: float, columns=None):
    """Raise if the pressure columns look gauge (relative to ``room_pa``) or lie far above
    ``supply_pa`` [Pa abs].  ``columns``: the names to check (default: every p_a./p_b. column)."""
    cols = [c for c in rec.columns if c.split(".", 1)[0] in PRESSURE_PREFIXES] if columns is None else list(columns)
    if not cols:
        return
    low = {c: float(np.min(rec[c])) for c in cols}
    lowest = min(low, key=low.get)
    said = (f"{rec.source}: column {lowest} reads down to {low[lowest]:.4g} Pa, yet a chamber at rest or "
            f"vented reads about the room pressure {room_pa:.6g} Pa absolute")
    if low[lowest] < GAUGE_LOW_SHARE * room_pa:
        raise RecordingError(f"{said}: these look like gauge pressures (relative to the room), or a wrong unit "
                             f"(kPa, bar, psi; Pa absolute expected); for gauge values, {GAUGE_FIX}")
    top = max(cols, key=lambda c: float(np.max(rec[c])))
    if np.max(rec[top]) < room_pa * (1 - 0.05):
        raise RecordingError(
            f"{rec.source}: no pressure column reaches the room pressure {room_pa:.6g} Pa (highest: {top}, "
            f"max {np.max(rec[top]):.4g} Pa): gauge pressures or another unit; pressures must be Pa absolute; "
            f"{GAUGE_FIX}")
    p99 = {c: float(np.percentile(rec[c], 99)) for c in cols}
    high = p99[top]
    could_be_gauge = max(p99.values()) < supply_pa - ABSOLUTE_TOP_SHARE * room_pa
    if low[lowest] < SUBATMOSPHERIC_SHARE * room_pa and could_be_gauge:
        warnings.warn(f"{said}, and only a chamber expanded with its valve shut reads below "
                      f"{SUBATMOSPHERIC_SHARE:g} x that (no column comes near the supply {supply_pa:.6g} Pa, "
                      f"as none of a gauge recording would): gauge pressures? if so, {GAUGE_FIX}", RecordingWarning,
                      stacklevel=2)
    if high > SUPPLY_MARGIN * supply_pa:
        raise RecordingError(
            f"{rec.source}: column {top} reads up to {np.max(rec[top]):.4g} Pa (99th percentile {high:.4g}), "
            f"more than {SUPPLY_MARGIN:g} x the supply {supply_pa:.6g} Pa: another unit (mbar, hPa x 100)? "
            f"pressures must be Pa absolute")


def check_joint_positions(rec: Recording, joint_names, joint_range, slide=None):
    """Raise if a ``q.<joint>`` column leaves its joint's range (``joint_range`` (J, 2) [rad or
    m]; ``slide`` (J,) bool marks slide joints, in m), naming degrees or mm when that explains it."""
    slide = np.zeros(len(joint_names), bool) if slide is None else np.asarray(slide, bool)
    for j, name in enumerate(joint_names):
        col = f"q.{name}"
        if col not in rec:
            continue
        lo, hi = map(float, joint_range[j])
        if not hi > lo:
            continue  # an unlimited joint
        v = rec[col]
        margin = RANGE_MARGIN * (hi - lo)
        if v.min() >= lo - margin and v.max() <= hi + margin:
            continue
        unit, factor = ("m", 1e-3) if slide[j] else ("rad", math.pi / 180)
        rng = f"±{hi:.3g} {unit}" if math.isclose(-lo, hi, rel_tol=1e-3) else f"[{lo:.3g}, {hi:.3g}] {unit}"
        big = v.max() if abs(v.max()) >= abs(v.min()) else v.min()
        # the other unit: the values fit the range once converted, and they are too large or
        # move too far to be the right unit shifted by an offset
        too_big = np.max(np.abs(v)) > (1.0 if slide[j] else 2 * math.pi) or np.ptp(v) > 2 * ((hi - lo) + 2 * margin)
        if too_big and v.min() * factor >= lo - margin and v.max() * factor <= hi + margin:
            other = "mm" if slide[j] else "degrees"
            raise RecordingError(f"{rec.source}: column {col} looks like {other} ({'max' if big == v.max() else 'min'} "
                                 f"{big:.4g}, joint range {rng}); convert it to {unit} (the import map's unit "
                                 f"{'mm' if slide[j] else 'deg'} does it)")
        raise RecordingError(f"{rec.source}: column {col} spans {v.min():.4g}..{v.max():.4g}, outside the joint "
                             f"range {rng} by more than {100 * RANGE_MARGIN:g} % of its span: another joint, unit "
                             f"or zero?")


def check_for_robot(rec: Recording, robot):
    """Pressures against the robot's room and supply, angles against its joint ranges."""
    tab = robot.tables
    check_pressures(rec, tab.room_pa, tab.supply_pa)
    m = robot.model
    slide = [int(m.jnt_type[m.joint(n).id]) == 2 for n in robot.joint_names]  # mjJNT_SLIDE
    limited = np.array([bool(m.jnt_limited[m.joint(n).id]) for n in robot.joint_names])
    rng = np.where(limited[:, None], robot.joint_range(), 0.0)
    check_joint_positions(rec, robot.joint_names, rng, slide)


def add_room_pressure(rec: Recording, room_pa: float, columns=None) -> Recording:
    """The recording with ``room_pa`` added to its pressure columns (gauge -> absolute), noted
    in its metadata ("gauge_room_pa")."""
    cols = [c for c in rec.columns if c.split(".", 1)[0] in PRESSURE_PREFIXES] if columns is None else list(columns)
    new = {c: (v + room_pa if c in cols else v) for c, v in rec.columns.items()}
    return dataclasses.replace(rec, columns=new, meta={**rec.meta, "gauge_room_pa": room_pa},
                               source=f"{rec.source} (gauge + {room_pa:.6g} Pa)")
