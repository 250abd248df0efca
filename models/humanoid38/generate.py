"""Generate the humanoid38 model: ``humanoid38.xml`` (MJCF) and ``fluid.toml`` (fluid power).

humanoid38 is a fixed-base, child-sized (1.34 m, 28 kg) humanoid with 38 pneumatic joints in
the spirit of Kokoro's Diego-San (paper 002 §VI: 38 DOFs without the hands, one double-acting
cylinder or vane per joint, two valves and two pressure sensors per actuator, 76 controls).
The paper gives no dimensions, so everything here is a plausible design derived from a few
stated rules.  This script writes both files, and the joint table of ``README.md``, from the
tables below, so every number is derived and reproducible
(``python -m models.humanoid38.generate``; random draws come from ``SEED``).

What is derived, in order:

1. **Link masses** -- a 28 kg total split over body segments by fractions close to human ones
   (Winter's adult table, with more mass in the limbs, where a pneumatic robot carries its
   cylinders, and less in the trunk), then over the links of each segment.
2. **Link inertias** -- each link's mass spread over a solid box, cylinder or sphere of the
   link's size, about a centre of mass given per link.
3. **Cylinder geometry** -- a *tendon* joint is driven by a cylinder pinned to the parent link
   at distance ``a`` from the joint axis and to a lever of length ``b`` on the child link.  The
   pin-to-pin length grows monotonically over the whole range (chamber ``a`` extends the
   cylinder and turns the joint positive) and the moment arm ``a b sin(phi) / L`` never
   vanishes, because the lever angle phi stays inside (0.2, pi - 0.2); the lever's phase is
   chosen to minimise the force the joint needs (step 4).  A *gear* joint has a constant moment
   arm; a *rotary* joint a vane.
4. **Loads** -- MuJoCo computes, over random poses inside the joint ranges, each joint's
   gravity torque and its diagonal inertia; a joint needs ``max(1.5 x gravity, 10 rad/s^2 x
   inertia, 0.1 N m)``, divided by the moment arm at that pose (MuJoCo's actuator length,
   differentiated) for a cylinder.  In the home pose it also needs an air spring (both
   chambers sealed at 4 bar) that holds the gravity load within 4 deg and is 1.5 times stiffer
   than gravity's destabilising slope (inverted pendulums: waist, neck).
5. **Actuator sizes** -- the smallest ISO bore (with its ISO rod) whose rod-side annulus makes
   that force at 6 bar (7 bar supply, 1 bar room) and whose air spring is stiff enough; a
   vane's displacement likewise.  Strokes (vane travels) cover the joint's travel plus 4 mm
   (0.1 rad) and are rounded up to 5 mm (0.05 rad); the piston clears both end stops by the same
   margin over the whole range.  Dead volumes (port and tube) are 0.5 cm^3 + 10 % of the swept
   volume, kept in 0.5-5 cm^3.
6. **Joint damping and armature** -- seal friction grows with the actuator (0.5 % of its
   6-bar torque per rad/s, kept in 0.05-0.5 N m s/rad); armature is the steel rod and
   aluminium piston reflected through the mean moment arm (a vane: 1e-4 kg m^2), kept in
   1e-4-1e-3 kg m^2.
7. **Valves** -- the valve's effective area scales with its chamber's volume at mid-stroke,
   anchored at arm2's shoulder (15 cm^3 -> 8e-7 m^2 supply, 9e-7 m^2 exhaust), so every
   chamber fills with about arm2's time constant, kept in 1.5e-7-2e-6 m^2; then every one of
   the 76 valves gets its own draw: both areas x U(0.85, 1.15) (one factor per valve), null
   5 V + U(-0.15, 0.15) V, null-leak fraction U(0.015, 0.03), dead band U(0.1, 0.25) V,
   opening exponent U(1.1, 1.5).
8. **Sensors** -- arm2's noise after averaging, times sqrt(500/200): the humanoid's DAQ
   averages 200 samples per period instead of 500 (paper 002 §II).

Conventions: x forward, y left, z up; at q = 0 the robot stands straight with the arms
hanging and the palms facing the thighs, and every body frame is aligned with the world.  The
pelvis is welded to the world at 0.75 m (the robot stands on a stand).  Every body but the
pelvis has exactly one hinge, at its origin.  Sagittal joints turn positive in flexion (waist
and neck bend forward, head nods down, arm and thigh swing forward, elbow and knee bend,
ankle dorsiflexes, toes curl down, jaw opens); limb roll joints are positive in abduction
(ankle: eversion, clavicle: elevation), limb yaw joints in external rotation (forearm:
supination, wrist yaw: radial deviation); trunk and neck roll and yaw follow the right-hand
rule about x and z.  The right side mirrors the left (positions y -> -y, axes (x, y, z) ->
(-x, y, -z)), so a joint and its twin have the same range, the same sign convention and the
same actuator.
"""
from __future__ import annotations

import argparse
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np

HERE = Path(__file__).resolve().parent
MODEL = "humanoid38"
SEED = 38

# -- air and sizing rules -----------------------------------------------------------------
SUPPLY_PA = 7.0e5
ROOM_PA = 1.0e5
DP_PA = SUPPLY_PA - ROOM_PA                 # 6 bar differential
GRAVITY_MARGIN = 1.5                        # hold 1.5 x the worst static load in range
ACCEL_REF = 10.0                            # rad/s^2 at the worst inertia, for joints gravity spares
TORQUE_FLOOR = 0.1                          # N m; smallest useful actuator
HOLD_PA = 4.0e5                             # with both chambers sealed at 4 bar (valves at null)...
HOLD_SAG_RAD = math.radians(4.0)            # ...the home pose's gravity load may bend a joint 4 deg
POLYTROPIC = 1.4                            # (fast deflection: adiabatic air spring)
N_POSES = 4000                              # random poses for the load statistics
STROKE_MARGIN_M = 0.004                     # piston clearance kept at each end stop...
TRAVEL_MARGIN_RAD = 0.1                     # ...and vane clearance
STROKE_ROUND_M = 0.005                      # strokes rounded up to 5 mm...
TRAVEL_ROUND_RAD = 0.05                     # ...vane travels to 0.05 rad
PHI_CLEAR = 0.2                             # rad: lever kept this far from dead centre (0, pi)
MIN_CYLINDER_BODY_M = 0.035                 # retracted pin distance minus stroke: heads, piston
DEAD_TUBE_M3 = 0.5e-6                       # dead volume: the port and the tube's share...
DEAD_FRACTION = 0.10                        # ...plus this fraction of the swept volume
DEAD_MIN_M3, DEAD_MAX_M3 = 0.5e-6, 5.0e-6
# ISO 6432 / ISO 15552 bores and their rods [mm]; 10 mm is the smallest we use (a 4 mm rod
# over a 30-60 mm stroke; smaller cylinders are fragile and their ports dominate the volume)
ISO_BORES = ((10, 4), (12, 6), (16, 6), (20, 8), (25, 10), (32, 12),
             (40, 16), (50, 20), (63, 20))
STEEL, ALUMINIUM = 7850.0, 2700.0           # kg/m^3
PISTON_THICKNESS_M = 0.01
ROD_EXTRA_M = 0.03                          # rod length beyond the stroke
DAMPING_PER_TORQUE = 0.005                  # N m s/rad per N m of 6-bar torque
DAMPING_RANGE = (0.05, 0.5)
ARMATURE_RANGE = (1e-4, 1e-3)
VANE_ARMATURE = 1e-4
# valves: area ~ chamber volume^VALVE_EXPONENT, anchored at arm2's shoulder (reference/arm2.md:
# 4 cm^3 dead + half of its 20 mm x 70 mm swept volume -> 8e-7 m^2 supply, 9e-7 m^2 exhaust);
# exponent 1 gives every chamber arm2's filling time constant
VALVE_REF_VOLUME = 4.0e-6 + math.pi / 4 * 0.020 ** 2 * 0.035
VALVE_REF_SUPPLY_M2, VALVE_EXHAUST_RATIO = 8.0e-7, 9.0 / 8.0
VALVE_EXPONENT = 1.0
VALVE_AREA_RANGE = (1.5e-7, 2.0e-6)
VALVE_SCATTER = 0.15
NULL_V, NULL_SCATTER_V = 5.0, 0.15
# sensors: arm2 averages 500 samples (paper 002 §II), the humanoid 200: noise x sqrt(500/200)
ARM2_ANGLE_NOISE, ARM2_PRESSURE_NOISE = 0.00087, 300.0
NOISE_SCALE = math.sqrt(500 / 200)

# -- masses ----------------------------------------------------------------------------------
TOTAL_MASS_KG = 28.0
#: robot segment mass fractions (per side for limbs); Winter's adult values in the comments
SEGMENT_FRACTION = {
    "trunk": 0.370,        # 0.497 (no viscera; valves are off-board)
    "head_neck": 0.085,    # 0.081 (a child's head is relatively heavier)
    "upper_arm": 0.055,    # 0.028 (shoulder girdle and its five actuators)
    "forearm": 0.027,      # 0.016
    "hand": 0.011,         # 0.006 (hand removed; wrist actuators and a palm)
    "thigh": 0.112,        # 0.100 (hip yaw and roll housings)
    "shank": 0.043,        # 0.0465
    "foot": 0.0245,        # 0.0145 (ankle and toe actuators)
}
assert abs(SEGMENT_FRACTION["trunk"] + SEGMENT_FRACTION["head_neck"]
           + 2 * sum(v for k, v in SEGMENT_FRACTION.items() if k not in ("trunk", "head_neck")) - 1) < 1e-9


# -- link table ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Rotary:
    """A vane actuator on the joint (joint transmission, gear 1)."""


@dataclass(frozen=True)
class Gear:
    """A cylinder with a constant moment arm r [m] (joint transmission, gear r)."""
    r: float


@dataclass(frozen=True)
class Tendon:
    """A cylinder between a pin on the parent (distance ``a`` from the axis, along ``toward``)
    and a lever of length ``b`` on the child; both pins shifted by ``shift`` (along the axis,
    so the cylinder works in a plane perpendicular to it, beside the link)."""
    a: float
    b: float
    toward: tuple[float, float, float]
    shift: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Geom:
    """A geom; ``collide`` adds a collision twin (group 3) of the visual geom (group 2)."""
    type: str
    size: tuple
    pos: tuple = (0.0, 0.0, 0.0)
    fromto: tuple | None = None
    material: str = "shell"
    collide: bool = False


@dataclass(frozen=True)
class Link:
    """A body with its one hinge joint and the actuator that drives it."""
    body: str
    parent: str
    pos: tuple
    joint: str
    axis: tuple
    range_deg: tuple
    drive: object
    segment: str
    share: float                          # of the segment's mass
    com: tuple
    shape: tuple                          # ("box", hx, hy, hz) | ("cyl", r, half_len) | ("sphere", r)
    home_deg: float = 0.0
    geoms: tuple = ()
    sites: tuple = ()                     # (name, pos)


def _cap(p0, p1, r, material="shell", collide=False):
    return Geom("capsule", (r,), fromto=(*p0, *p1), material=material, collide=collide)


def _box(pos, half, material="shell", collide=False):
    return Geom("box", half, pos=pos, material=material, collide=collide)


def _joint_cyl(axis, r, length, pos=(0, 0, 0)):
    """A dark cylinder drawn along the joint axis (the joint housing)."""
    a = np.asarray(axis, float)
    p0 = np.asarray(pos) - 0.5 * length * a
    p1 = np.asarray(pos) + 0.5 * length * a
    return Geom("cylinder", (r,), fromto=(*p0, *p1), material="joint")


Y, NY, X, NX, Z = (0, 1, 0), (0, -1, 0), (1, 0, 0), (-1, 0, 0), (0, 0, 1)
UP, DOWN, BACK_DOWN = (0, 0, 1), (0, 0, -1), (-0.5, 0, -1)

CENTRE = (
    Link("waist_yaw_link", "pelvis", (0, 0, 0.08), "waist_yaw", Z, (-45, 45), Rotary(),
         "trunk", 0.05, (0, 0, 0.0), ("cyl", 0.05, 0.02),
         geoms=(_joint_cyl(Z, 0.05, 0.04),)),
    Link("waist_pitch_link", "waist_yaw_link", (0, 0, 0), "waist_pitch", Y, (-20, 50),
         Tendon(a=0.20, b=0.06, toward=DOWN), "trunk", 0.04, (0, 0, 0), ("cyl", 0.04, 0.04),
         geoms=(_joint_cyl(Y, 0.035, 0.08),)),
    Link("torso", "waist_pitch_link", (0, 0, 0), "waist_roll", X, (-25, 25), Gear(0.06),
         "trunk", 0.58, (0, 0, 0.15), ("box", 0.075, 0.10, 0.13),
         geoms=(_box((0, 0, 0.16), (0.075, 0.10, 0.12), collide=True),
                _cap((0, -0.04, 0.22), (0, 0.04, 0.22), 0.03, "joint"),
                _joint_cyl(X, 0.03, 0.1))),
    Link("neck_yaw_link", "torso", (0, 0, 0.28), "neck_yaw", Z, (-70, 70), Rotary(),
         "head_neck", 0.06, (0, 0, 0.01), ("cyl", 0.03, 0.015),
         geoms=(_joint_cyl(Z, 0.03, 0.03),)),
    Link("neck_pitch_link", "neck_yaw_link", (0, 0, 0.02), "neck_pitch", Y, (-30, 40), Gear(0.025),
         "head_neck", 0.08, (0, 0, 0.01), ("cyl", 0.025, 0.02),
         geoms=(_joint_cyl(Y, 0.02, 0.06),)),
    Link("neck_roll_link", "neck_pitch_link", (0, 0, 0), "neck_roll", X, (-25, 25), Rotary(),
         "head_neck", 0.06, (0, 0, 0.035), ("cyl", 0.022, 0.035),
         geoms=(_cap((0, 0, 0), (0, 0, 0.06), 0.022),)),
    Link("head", "neck_roll_link", (0, 0, 0.07), "head_pitch", Y, (-25, 25), Gear(0.02),
         "head_neck", 0.75, (0.0, 0, 0.05), ("sphere", 0.085),
         geoms=(Geom("sphere", (0.085,), pos=(0.0, 0, 0.05), collide=True),
                Geom("sphere", (0.014,), pos=(0.075, 0.03, 0.07), material="joint"),
                Geom("sphere", (0.014,), pos=(0.075, -0.03, 0.07), material="joint"),
                _joint_cyl(Y, 0.015, 0.06)),
         sites=(("head_site", (0.0, 0, 0.05)),)),
    Link("jaw", "head", (0.0, 0, -0.01), "jaw", Y, (-3, 25), Rotary(),
         "head_neck", 0.05, (0.03, 0, -0.01), ("box", 0.035, 0.04, 0.012),
         geoms=(_box((0.04, 0, -0.012), (0.035, 0.035, 0.01), "joint"),)),
)

LEFT_ARM = (
    Link("left_clavicle", "torso", (0, 0.04, 0.22), "left_clavicle_elevation", X, (-10, 25),
         Gear(0.035), "upper_arm", 0.22, (0, 0.06, 0), ("cyl", 0.02, 0.055),
         geoms=(_cap((0, 0, 0), (0, 0.11, 0), 0.02),)),
    Link("left_shoulder_pitch_link", "left_clavicle", (0, 0.11, 0), "left_shoulder_pitch", NY,
         (-45, 100), Tendon(a=0.18, b=0.035, toward=BACK_DOWN, shift=(0, -0.04, 0)), "upper_arm", 0.14,
         (0, 0, 0), ("cyl", 0.035, 0.03), home_deg=3,
         geoms=(_joint_cyl(Y, 0.035, 0.06),)),
    Link("left_shoulder_roll_link", "left_shoulder_pitch_link", (0, 0, 0), "left_shoulder_roll", X,
         (-10, 100), Gear(0.03), "upper_arm", 0.14, (0, 0, -0.01), ("cyl", 0.03, 0.03), home_deg=6,
         geoms=(_joint_cyl(X, 0.03, 0.07),)),
    Link("left_upper_arm", "left_shoulder_roll_link", (0, 0, -0.04), "left_shoulder_yaw", Z,
         (-80, 80), Rotary(), "upper_arm", 0.50, (0, 0, -0.08), ("cyl", 0.035, 0.09),
         geoms=(_cap((0, 0, -0.02), (0, 0, -0.17), 0.035, collide=True),)),
    Link("left_forearm", "left_upper_arm", (0, 0, -0.19), "left_elbow", NY, (-3, 130),
         Tendon(a=0.15, b=0.03, toward=UP), "forearm", 0.6, (0, 0, -0.03), ("cyl", 0.03, 0.04),
         home_deg=17, geoms=(_joint_cyl(Y, 0.03, 0.07),
                             _cap((0, 0, -0.02), (0, 0, -0.06), 0.03, collide=True))),
    Link("left_forearm_distal", "left_forearm", (0, 0, -0.06), "left_forearm_roll", Z, (-80, 80),
         Rotary(), "forearm", 0.4, (0, 0, -0.055), ("cyl", 0.028, 0.06),
         geoms=(_cap((0, 0, 0), (0, 0, -0.11), 0.028, collide=True),)),
    Link("left_wrist", "left_forearm_distal", (0, 0, -0.13), "left_wrist_pitch", NX, (-50, 60),
         Gear(0.012), "hand", 0.25, (0, 0, 0), ("cyl", 0.02, 0.02),
         geoms=(_joint_cyl(X, 0.018, 0.05),)),
    Link("left_hand", "left_wrist", (0, 0, 0), "left_wrist_yaw", NY, (-30, 20), Rotary(),
         "hand", 0.75, (0, 0, -0.06), ("box", 0.04, 0.015, 0.06),
         geoms=(_box((0, 0, -0.065), (0.04, 0.015, 0.055), collide=True),),
         sites=(("left_palm", (0, -0.02, -0.07)),)),
)

LEFT_LEG = (
    Link("left_hip_yaw_link", "pelvis", (0, 0.075, -0.07), "left_hip_yaw", Z, (-30, 40), Gear(0.025),
         "thigh", 0.11, (0, 0, 0.02), ("cyl", 0.04, 0.03),
         geoms=(_joint_cyl(Z, 0.04, 0.04, (0, 0, 0.03)),)),
    Link("left_hip_roll_link", "left_hip_yaw_link", (0, 0, 0), "left_hip_roll", X, (-20, 40),
         Tendon(a=0.15, b=0.05, toward=UP), "thigh", 0.14, (0, 0, 0), ("cyl", 0.04, 0.04),
         geoms=(_joint_cyl(X, 0.04, 0.09),)),
    Link("left_thigh", "left_hip_roll_link", (0, 0, 0), "left_hip_pitch", NY, (-25, 100),
         Tendon(a=0.20, b=0.055, toward=UP, shift=(0, 0.03, 0)), "thigh", 0.75, (0, 0, -0.13),
         ("cyl", 0.055, 0.13), home_deg=5,
         geoms=(_joint_cyl(Y, 0.045, 0.1), _cap((0, 0, -0.03), (0, 0, -0.26), 0.05, collide=True))),
    Link("left_shank", "left_thigh", (0, 0, -0.30), "left_knee", Y, (-3, 130),
         Tendon(a=0.20, b=0.04, toward=UP), "shank", 1.0, (0, 0, -0.12), ("cyl", 0.04, 0.13),
         home_deg=9, geoms=(_joint_cyl(Y, 0.04, 0.09),
                            _cap((0, 0, -0.03), (0, 0, -0.25), 0.04, collide=True))),
    Link("left_ankle_link", "left_shank", (0, 0, -0.30), "left_ankle_pitch", NY, (-40, 25),
         Tendon(a=0.18, b=0.045, toward=UP), "foot", 0.18, (0, 0, 0), ("cyl", 0.025, 0.03),
         home_deg=4, geoms=(_joint_cyl(Y, 0.025, 0.07),)),
    Link("left_foot", "left_ankle_link", (0, 0, 0), "left_ankle_roll", X, (-25, 20), Gear(0.025),
         "foot", 0.70, (0.025, 0, -0.04), ("box", 0.075, 0.04, 0.02),
         geoms=(_box((0.025, 0, -0.04), (0.075, 0.04, 0.02), collide=True),)),
    Link("left_toe", "left_foot", (0.10, 0, -0.045), "left_toe", Y, (-35, 25), Rotary(),
         "foot", 0.12, (0.02, 0, 0), ("box", 0.02, 0.04, 0.015),
         geoms=(_box((0.02, 0, 0), (0.02, 0.04, 0.015), collide=True),)),
)

#: collision pairs that overlap or touch by construction (joint regions), excluded
EXCLUDE = (("pelvis", "torso"), ("pelvis", "waist_pitch_link"), ("pelvis", "left_thigh"),
           ("pelvis", "right_thigh"), ("left_upper_arm", "left_forearm_distal"),
           ("right_upper_arm", "right_forearm_distal"), ("left_shank", "left_foot"),
           ("right_shank", "right_foot"), ("left_forearm_distal", "left_hand"),
           ("right_forearm_distal", "right_hand"))
PELVIS_HEIGHT = 0.75
PELVIS = dict(mass_share=0.33, com=(-0.005, 0, 0), shape=("box", 0.075, 0.11, 0.06),
              geoms=(_box((-0.005, 0, 0), (0.075, 0.11, 0.06), collide=True),))


def _mirror_name(s: str) -> str:
    return s.replace("left", "right")


def _mirror_pos(p):
    return (p[0], -p[1], p[2])


def _mirror_axis(a):
    return (-a[0], a[1], -a[2])


def _mirror_geom(g: Geom) -> Geom:
    return replace(g, pos=_mirror_pos(g.pos),
                   fromto=None if g.fromto is None else (*_mirror_pos(g.fromto[:3]), *_mirror_pos(g.fromto[3:])))


def mirror(link: Link) -> Link:
    """The right-side twin of a left-side link (see the module docstring)."""
    drive = link.drive
    if isinstance(drive, Tendon):
        drive = replace(drive, toward=_mirror_pos(drive.toward), shift=_mirror_pos(drive.shift))
    return replace(link, body=_mirror_name(link.body), parent=_mirror_name(link.parent),
                   pos=_mirror_pos(link.pos), joint=_mirror_name(link.joint),
                   axis=_mirror_axis(link.axis), drive=drive, com=_mirror_pos(link.com),
                   geoms=tuple(_mirror_geom(g) for g in link.geoms),
                   sites=tuple((_mirror_name(n), _mirror_pos(p)) for n, p in link.sites))


LINKS = (*CENTRE, *LEFT_ARM, *map(mirror, LEFT_ARM), *LEFT_LEG, *map(mirror, LEFT_LEG))


# -- derived quantities -------------------------------------------------------------------
def rotation(axis, angle) -> np.ndarray:
    """Rotation matrix about unit ``axis`` by ``angle`` (Rodrigues)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def link_mass(link: Link) -> float:
    return TOTAL_MASS_KG * SEGMENT_FRACTION[link.segment] * link.share


def shape_inertia(mass: float, shape: tuple) -> tuple[float, float, float]:
    """Principal inertia [kg m^2] of a solid box (half sizes), z-cylinder or sphere."""
    kind, *dims = shape
    if kind == "box":
        hx, hy, hz = dims
        return (mass * (hy ** 2 + hz ** 2) / 3, mass * (hx ** 2 + hz ** 2) / 3, mass * (hx ** 2 + hy ** 2) / 3)
    if kind == "cyl":
        r, h = dims
        side = mass * (3 * r ** 2 + 4 * h ** 2) / 12
        return (side, side, mass * r ** 2 / 2)
    (r,) = dims
    return (0.4 * mass * r ** 2,) * 3


def lever_offset(link: Link, phase: float) -> float:
    """phi0: the lever's angle from the parent pin's direction at q = 0, given ``phase``, the
    angle at mid-range (pi/2 puts the peak moment arm at mid-range)."""
    lo, hi = np.radians(link.range_deg)
    return phase - 0.5 * (lo + hi)


def tendon_sites(link: Link, phase: float) -> tuple[np.ndarray, np.ndarray]:
    """(pin on the parent, in the parent frame; lever pin on the child, in the child frame).

    Both pins lie in one plane perpendicular to the axis; the lever makes the angle
    phi = phi0 + q with the parent pin's direction ``toward``.  While phi stays inside (0, pi)
    the length sqrt(a^2 + b^2 - 2ab cos phi) grows with q and the moment arm a b sin(phi) / L
    keeps its sign.
    """
    d: Tendon = link.drive
    n = np.asarray(link.axis, float)
    u = np.asarray(d.toward, float)
    u = u - n * (u @ n)
    u /= np.linalg.norm(u)
    phi0 = lever_offset(link, phase)
    lo, hi = np.radians(link.range_deg)
    assert PHI_CLEAR - 1e-9 <= phi0 + lo and phi0 + hi <= math.pi - PHI_CLEAR + 1e-9, link.joint
    shift = np.asarray(d.shift, float)
    assert np.allclose(np.cross(shift, n), 0), f"{link.joint}: shift must lie along the axis"
    base = np.asarray(link.pos) + d.a * u + shift
    rod = d.b * rotation(n, phi0) @ u + shift
    return base, rod


def tendon_length(link: Link, phase: float, q: np.ndarray) -> np.ndarray:
    """Pin-to-pin length [m] at joint angles ``q`` (the same as MuJoCo's, checked later)."""
    base, rod = tendon_sites(link, phase)
    k = np.asarray(link.axis, float)
    q = np.asarray(q, float)[:, None]
    # Rodrigues on the lever for every q at once
    rotated = (rod * np.cos(q) + np.cross(k, rod) * np.sin(q) + k * (k @ rod) * (1 - np.cos(q)))
    return np.linalg.norm(np.asarray(link.pos) + rotated - base, axis=1)


# -- MJCF --------------------------------------------------------------------------------
def _f(x) -> str:
    """A number as MJCF text: short and exact enough (5 significant digits, no -0)."""
    s = f"{float(x):.5g}"
    return "0" if s in ("-0", "0") else s


def _v(xs) -> str:
    return " ".join(_f(x) for x in xs)


@dataclass
class JointDyn:
    damping: float = 0.1
    armature: float = 1e-4


def _geom_xml(g: Geom, cls: str) -> str:
    attrs = [f'class="{cls}"', f'type="{g.type}"', f'size="{_v(g.size)}"']
    if g.fromto is not None:
        attrs.append(f'fromto="{_v(g.fromto)}"')
    elif any(g.pos):
        attrs.append(f'pos="{_v(g.pos)}"')
    if cls == "visual":
        attrs.append(f'material="{g.material}"')
    return f"<geom {' '.join(attrs)}/>"


def _geoms_xml(geoms) -> list[str]:
    out = [_geom_xml(g, "visual") for g in geoms]
    out += [_geom_xml(g, "collision") for g in geoms if g.collide]
    return out


def build_mjcf(dyn: dict[str, JointDyn], phases: dict[str, float] | None = None,
               actuators: dict | None = None) -> str:
    """The MJCF text; ``dyn`` gives joint damping/armature, ``phases`` the tendon levers'
    phase (default pi/2) and ``actuators`` the comment on each actuator."""
    children: dict[str, list[Link]] = {}
    for link in LINKS:
        children.setdefault(link.parent, []).append(link)
    tendon_links = [l for l in LINKS if isinstance(l.drive, Tendon)]
    site_of: dict[str, list[str]] = {}
    for link in tendon_links:
        base, rod = tendon_sites(link, (phases or {}).get(link.joint, math.pi / 2))
        site_of.setdefault(link.parent, []).append(
            f'<site class="cylinder" name="{link.joint}_cyl_base" pos="{_v(base)}"/>')
        site_of.setdefault(link.body, []).append(
            f'<site class="cylinder" name="{link.joint}_cyl_rod" pos="{_v(rod)}"/>')

    def inertial(mass, com, shape):
        return (f'<inertial pos="{_v(com)}" mass="{_f(mass)}" '
                f'diaginertia="{_v(shape_inertia(mass, shape))}"/>')

    def body(link: Link, depth: int) -> list[str]:
        ind = "  " * depth
        lo, hi = np.radians(link.range_deg)
        d = dyn[link.joint]
        lines = [f'{ind}<body name="{link.body}" pos="{_v(link.pos)}">',
                 f'{ind}  <joint name="{link.joint}" axis="{_v(link.axis)}" range="{_f(lo)} {_f(hi)}" '
                 f'damping="{_f(d.damping)}" armature="{_f(d.armature)}"/>',
                 f'{ind}  {inertial(link_mass(link), link.com, link.shape)}']
        lines += [f"{ind}  {g}" for g in _geoms_xml(link.geoms)]
        lines += [f'{ind}  <site class="marker" name="{n}" pos="{_v(p)}"/>' for n, p in link.sites]
        lines += [f"{ind}  {s}" for s in site_of.get(link.body, [])]
        for child in children.get(link.body, []):
            lines += body(child, depth + 1)
        lines.append(f"{ind}</body>")
        return lines

    pelvis_mass = TOTAL_MASS_KG * SEGMENT_FRACTION["trunk"] * PELVIS["mass_share"]
    tree = ['    <body name="pelvis" pos="0 0 %s" childclass="%s">' % (_f(PELVIS_HEIGHT), MODEL),
            f'      {inertial(pelvis_mass, PELVIS["com"], PELVIS["shape"])}']
    tree += [f"      {g}" for g in _geoms_xml(PELVIS["geoms"])]
    tree += [f"      {s}" for s in site_of.get("pelvis", [])]
    for child in children["pelvis"]:
        tree += body(child, 3)
    tree.append("    </body>")

    tendons = [f'    <spatial name="{l.joint}_cyl" class="{MODEL}">\n'
               f'      <site site="{l.joint}_cyl_base"/>\n      <site site="{l.joint}_cyl_rod"/>\n'
               f"    </spatial>" for l in tendon_links]
    acts = []
    for link in LINKS:
        note = f"  <!-- {actuators[link.joint]} -->" if actuators else ""
        if isinstance(link.drive, Tendon):
            acts.append(f'    <motor name="{link.joint}" tendon="{link.joint}_cyl"/>{note}')
        else:
            gear = 1.0 if isinstance(link.drive, Rotary) else link.drive.r
            acts.append(f'    <motor name="{link.joint}" joint="{link.joint}" gear="{_f(gear)}"/>{note}')
    sensors = [f'    <jointpos name="q.{l.joint}" joint="{l.joint}"/>' for l in LINKS]
    home = " ".join(_f(math.radians(l.home_deg)) for l in LINKS)
    excludes = [f'    <exclude body1="{a}" body2="{b}"/>' for a, b in EXCLUDE]
    n_vane = sum(isinstance(l.drive, Rotary) for l in LINKS)
    n_gear = sum(isinstance(l.drive, Gear) for l in LINKS)
    return f"""<!--
  humanoid38: a fixed-base, child-sized pneumatic humanoid with 38 joints, in the spirit of
  Kokoro's Diego-San (paper 002 section VI).  GENERATED by generate.py: edit that, then run
  `python -m models.humanoid38.generate`.  See README.md.

  x forward, y left, z up; the pelvis is welded to the world at {_f(PELVIS_HEIGHT)} m (the robot
  stands on a stand).  One hinge per body, at the body origin.  Every joint has one
  double-acting actuator, named after the joint, a plain force actuator whose ctrl the fluid
  layer writes every step (models/humanoid38/fluid.toml):
    {n_vane} rotary vanes        <motor joint gear="1">   ctrl = torque [N m]
    {n_gear} cylinders, fixed arm <motor joint gear="r">   ctrl = force [N], r = moment arm [m]
    {len(tendon_links)} cylinders on pins   <motor tendon>          ctrl = force [N] along the
                                                    pin-to-pin tendon <joint>_cyl; its
                                                    length grows with the joint angle
-->
<mujoco model="{MODEL}">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.001" gravity="0 0 -9.81"/>

  <default>
    <default class="{MODEL}">
      <joint type="hinge" limited="true" solreflimit="0.01 1"/>
      <motor ctrllimited="false"/>
      <site group="4"/>
      <tendon width="0.004" rgba="0.85 0.65 0.15 1"/>
      <default class="visual">
        <geom contype="0" conaffinity="0" group="2" density="0"/>
      </default>
      <default class="collision">
        <geom group="3" density="0" rgba="0.8 0.3 0.3 0.3"/>
      </default>
      <default class="cylinder">
        <site size="0.006" rgba="0.85 0.65 0.15 1"/>
      </default>
      <default class="marker">
        <site size="0.01" rgba="0.9 0.3 0.1 1"/>
      </default>
    </default>
  </default>

  <asset>
    <material name="shell" rgba="0.88 0.88 0.9 1"/>
    <material name="joint" rgba="0.22 0.22 0.25 1"/>
  </asset>

  <worldbody>
{chr(10).join(tree)}
  </worldbody>

  <contact>
{chr(10).join(excludes)}
  </contact>

  <tendon>
{chr(10).join(tendons)}
  </tendon>

  <actuator>
{chr(10).join(acts)}
  </actuator>

  <sensor>
{chr(10).join(sensors)}
  </sensor>

  <keyframe>
    <key name="home" qpos="{home}"/>
  </keyframe>
</mujoco>
"""


# -- loads and sizing ----------------------------------------------------------------------
@dataclass
class Sizing:
    """One actuator as sized: its loads, transmission, size, stroke and air volumes."""
    link: Link
    kind: str                       # "rotary" | "linear"
    transmission: str               # "joint" | "tendon"
    tau_gravity: float = 0.0        # N m, worst static load in range
    need: float = 0.0               # N (cylinder) or N m (vane) to provide
    moment_min: float = 0.0         # m (cylinder) / 1 (vane)
    moment_mean: float = 0.0
    length_span: tuple = (0.0, 0.0)  # actuator length at the range ends
    length_zero: float = 0.0        # actuator length at q = 0
    bore_mm: int = 0
    rod_mm: int = 0
    displacement: float = 0.0       # m^3/rad
    stroke: float = 0.0             # m or rad
    position_at_zero: float = 0.0
    dead_volume: float = 0.0
    capacity: float = 0.0           # N m at 6 bar: rod side x mean moment arm, or D x 6 bar
    extras: dict = field(default_factory=dict)

    @property
    def area_a(self):
        return self.displacement if self.kind == "rotary" else math.pi / 4 * (self.bore_mm / 1e3) ** 2

    @property
    def area_b(self):
        if self.kind == "rotary":
            return self.displacement
        return math.pi / 4 * ((self.bore_mm / 1e3) ** 2 - (self.rod_mm / 1e3) ** 2)


def _lengths_over_range(model, data, act_id, qadr, lo, hi, n=201):
    """(joint angles, MuJoCo actuator lengths) over [lo, hi], the other joints at zero."""
    qs = np.linspace(lo, hi, n)
    L = np.empty(n)
    for i, q in enumerate(qs):
        data.qpos[:] = 0
        data.qpos[qadr] = q
        mujoco.mj_fwdPosition(model, data)
        L[i] = data.actuator_length[act_id]
    return qs, L


@dataclass
class Loads:
    """Per joint, over random poses: the joint's angle, gravity torque and diagonal inertia,
    and the torque it needs (step 4); in the home pose, the gravity torque on the joint and
    its derivative (positive: gravity pulls further as the joint gives way, an inverted
    pendulum).  A joint and its mirror twin share their samples."""
    q: np.ndarray
    gravity: np.ndarray
    inertia: np.ndarray
    home_gravity: float = 0.0
    home_softening: float = 0.0

    @property
    def torque_need(self) -> np.ndarray:
        return np.maximum.reduce([GRAVITY_MARGIN * np.abs(self.gravity), ACCEL_REF * self.inertia,
                                  np.full(self.q.size, TORQUE_FLOOR)])

    @property
    def stiffness_need(self) -> float:
        """Air-spring stiffness [N m/rad] that holds the home pose within HOLD_SAG_RAD and
        outweighs an inverted pendulum's softening GRAVITY_MARGIN times."""
        return GRAVITY_MARGIN * max(self.home_softening, 0.0) + abs(self.home_gravity) / HOLD_SAG_RAD


def sample_loads(model: mujoco.MjModel) -> dict[str, Loads]:
    """Gravity torques (qfrc_bias at rest) and inertias (diag M) over random poses, and the
    gravity torque and its slope in the home pose."""
    data = mujoco.MjData(model)
    rng = np.random.default_rng(SEED)
    lo, hi = model.jnt_range.T
    home = model.key("home").qpos
    poses = np.vstack([home, rng.uniform(lo, hi, size=(N_POSES, model.nq))])
    tau = np.empty_like(poses)
    inertia = np.empty_like(poses)
    M = np.zeros((model.nv, model.nv))
    for i, q in enumerate(poses):
        data.qpos[:] = q
        data.qvel[:] = 0
        mujoco.mj_forward(model, data)
        tau[i] = data.qfrc_bias
        mujoco.mj_fullM(model, data, M)
        inertia[i] = np.diag(M)

    def home_gravity(qadr, dadr, dq=0.0):
        data.qpos[:] = home
        data.qpos[qadr] += dq
        data.qvel[:] = 0
        mujoco.mj_forward(model, data)
        return -data.qfrc_bias[dadr]  # the generalised gravity force

    own = {}
    for link in LINKS:
        jid = model.joint(link.joint).id
        qadr, dadr = model.jnt_qposadr[jid], model.jnt_dofadr[jid]
        h = 1e-4
        slope = (home_gravity(qadr, dadr, h) - home_gravity(qadr, dadr, -h)) / (2 * h)
        own[link.joint] = (poses[:, qadr], tau[:, dadr], inertia[:, dadr],
                           home_gravity(qadr, dadr), slope)
    loads = {}
    for name, (q, g, i, g0, k0) in own.items():
        twin = name.replace("left_", "right_") if name.startswith("left_") else name.replace("right_", "left_")
        if twin != name:
            q2, g2, i2, g02, k02 = own[twin]
            q, g, i = np.concatenate([q, q2]), np.concatenate([g, g2]), np.concatenate([i, i2])
            g0, k0 = max(g0, g02, key=abs), max(k0, k02)
        loads[name] = Loads(q, g, i, float(g0), float(k0))
    return loads


def best_phase(link: Link, loads: Loads) -> float:
    """Step 3: the lever phase that minimises the cylinder force the joint needs."""
    lo, hi = np.radians(link.range_deg)
    half = 0.5 * (hi - lo)
    qs = np.linspace(lo, hi, 201)
    best = None
    for phase in np.arange(half + PHI_CLEAR, math.pi - half - PHI_CLEAR + 1e-9, 0.01):
        moment = np.gradient(tendon_length(link, phase, qs), qs)
        force = (loads.torque_need / np.interp(loads.q, qs, moment)).max()
        if best is None or force < best[0]:
            best = (force, float(phase))
    return round(best[1], 2)


def size_actuators(model: mujoco.MjModel, loads: dict[str, Loads]) -> list[Sizing]:
    """Step 5: bores, displacements, strokes, piston positions and dead volumes, with the
    moment arms MuJoCo computes for the final geometry."""
    data = mujoco.MjData(model)
    home = model.key("home").qpos
    out = []
    for link in LINKS:
        jid = model.joint(link.joint).id
        qadr = model.jnt_qposadr[jid]
        qlo, qhi = model.jnt_range[jid]
        qs, L = _lengths_over_range(model, data, model.actuator(link.joint).id, qadr, qlo, qhi)
        moment = np.gradient(L, qs)
        assert moment.min() > 0, f"{link.joint}: moment arm must stay positive"
        load = loads[link.joint]
        kind = "rotary" if isinstance(link.drive, Rotary) else "linear"
        s = Sizing(link, kind, "tendon" if isinstance(link.drive, Tendon) else "joint",
                   tau_gravity=float(np.abs(load.gravity).max()),
                   need=float((load.torque_need / np.interp(load.q, qs, moment)).max()),
                   moment_min=float(moment.min()), moment_mean=float((L[-1] - L[0]) / (qhi - qlo)),
                   length_span=(float(L[0]), float(L[-1])),
                   length_zero=float(np.interp(0.0, qs, L)))
        s.extras["moment_max"] = float(moment.max())
        s.extras["stiffness_need"] = load.stiffness_need
        travel = L[-1] - L[0]
        step = TRAVEL_ROUND_RAD if kind == "rotary" else STROKE_ROUND_M
        margin = TRAVEL_MARGIN_RAD if kind == "rotary" else STROKE_MARGIN_M
        s.stroke = _round_up(travel + 2 * margin, step)
        # the piston clears both end stops by the same margin over the range
        s.position_at_zero = 0.5 * (s.stroke - travel) + (s.length_zero - L[0])
        x_home = s.position_at_zero + float(np.interp(home[qadr], qs, L)) - s.length_zero
        r_home = float(np.interp(home[qadr], qs, moment))

        def settle(size):
            """Set the size, then the dead volume and the air spring that follow from it;
            True when the actuator is both strong and stiff enough."""
            if kind == "rotary":
                s.displacement = size
            else:
                s.bore_mm, s.rod_mm = size
            swept = s.area_a * s.stroke
            s.dead_volume = min(max(DEAD_TUBE_M3 + DEAD_FRACTION * swept, DEAD_MIN_M3), DEAD_MAX_M3)
            s.extras["swept_m3"] = swept
            s.extras["stiffness"] = air_spring(s, x_home, r_home)
            force = s.area_a * DP_PA if kind == "rotary" else s.area_b * DP_PA
            return force >= s.need and s.extras["stiffness"] >= s.extras["stiffness_need"]

        if kind == "rotary":
            d = _round_up_sig(s.need / DP_PA, 2)
            while not settle(d):
                d = _round_up_sig(d * 1.05, 2)
            s.capacity = s.displacement * DP_PA
        else:
            for size in ISO_BORES:
                if settle(size):
                    break
            else:
                raise ValueError(f"{link.joint}: needs {s.need:.0f} N, more than the largest bore")
            s.capacity = s.area_b * DP_PA * s.moment_mean
            if s.transmission == "tendon":
                body = L[0] - s.stroke
                s.extras["body_m"] = body
                assert body >= MIN_CYLINDER_BODY_M, (
                    f"{link.joint}: pins {1e3 * L[0]:.0f} mm apart when retracted leave "
                    f"{1e3 * body:.0f} mm for a {1e3 * s.stroke:.0f} mm-stroke cylinder's body")
        s.extras["sealed_sag_rad"] = (abs(load.home_gravity)
                                      / max(s.extras["stiffness"] - load.home_softening, 1e-9))
        out.append(s)
    return out


def air_spring(s: Sizing, x: float, moment: float) -> float:
    """Joint stiffness [N m/rad] of the two sealed chambers at HOLD_PA, piston at x."""
    v_a = s.dead_volume + s.area_a * x
    v_b = s.dead_volume + s.area_b * (s.stroke - x)
    return POLYTROPIC * HOLD_PA * (s.area_a ** 2 / v_a + s.area_b ** 2 / v_b) * moment ** 2


def _round_up(x, step):
    return math.ceil(x / step - 1e-9) * step


def _round_up_sig(x, digits):
    e = math.floor(math.log10(x)) - digits + 1
    return math.ceil(x / 10 ** e - 1e-9) * 10 ** e


def joint_dynamics(sizes: list[Sizing]) -> dict[str, JointDyn]:
    """Step 6: damping from the actuator's strength, armature from its moving parts."""
    dyn = {}
    for s in sizes:
        torque = (s.area_a * DP_PA) * (1.0 if s.kind == "rotary" else s.moment_mean)
        damping = float(np.clip(DAMPING_PER_TORQUE * torque, *DAMPING_RANGE))
        if s.kind == "rotary":
            armature = VANE_ARMATURE
        else:
            rod = STEEL * math.pi / 4 * (s.rod_mm / 1e3) ** 2 * (s.stroke + ROD_EXTRA_M)
            piston = ALUMINIUM * s.area_a * PISTON_THICKNESS_M
            armature = (rod + piston) * s.moment_mean ** 2
        dyn[s.link.joint] = JointDyn(round(damping, 3), float(_round_sig(np.clip(armature, *ARMATURE_RANGE), 2)))
    return dyn


def _round_sig(x, digits):
    return float(f"{x:.{digits}g}")


# -- valves and TOML ---------------------------------------------------------------------
def valve_tables(sizes: list[Sizing]) -> list[tuple[dict, dict]]:
    """Step 7: base areas from the actuator's displacement, then one random draw per valve."""
    rng = np.random.default_rng(SEED)
    out = []
    for s in sizes:
        volume = s.dead_volume + 0.5 * s.extras["swept_m3"]  # chamber a at mid-stroke
        base = VALVE_REF_SUPPLY_M2 * (volume / VALVE_REF_VOLUME) ** VALVE_EXPONENT
        base = float(np.clip(base, *VALVE_AREA_RANGE))
        pair = []
        for _ in "ab":
            scale = rng.uniform(1 - VALVE_SCATTER, 1 + VALVE_SCATTER)
            pair.append({
                "supply_area_max_m2": base * scale,
                "exhaust_area_max_m2": base * VALVE_EXHAUST_RATIO * scale,
                "null_v": NULL_V + rng.uniform(-NULL_SCATTER_V, NULL_SCATTER_V),
                "null_leak_fraction": rng.uniform(0.015, 0.03),
                "deadband_v": rng.uniform(0.10, 0.25),
                "opening_exponent": rng.uniform(1.1, 1.5),
            })
        s.extras["valve_base_m2"] = base
        out.append(tuple(pair))
    return out


def _t(x, digits=4) -> str:
    """A TOML float with ``digits`` significant digits, written like 1.25e-6 or 0.035."""
    mantissa, _, exponent = f"{x:.{digits}g}".partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    return f"{mantissa}e{int(exponent)}" if exponent else mantissa


def build_toml(sizes: list[Sizing], valves) -> str:
    lines = [
        "# humanoid38 fluid-power parameters.  GENERATED by generate.py (see README.md): edit",
        "# that and run `python -m models.humanoid38.generate`.  Every field is documented in",
        "# pneumatics/{medium,params,valve,actuator}.py; SI units, pressures absolute.",
        "# Actuators are in the MJCF's actuator order; chamber a turns the joint positive.",
        "",
        "[gas]                              # as arm2: air, adiabatic chambers (002 eq. 9)",
        "gas_constant_j_per_kg_k = 287.0",
        "heat_capacity_ratio = 1.4",
        "temperature_k = 293.15",
        "polytropic_exponent = 1.4",
        "laminar_ratio = 0.995",
        "",
        "[supply]",
        f"supply_pa = {_t(SUPPLY_PA)}                  # 7 bar compressor",
        f"room_pa = {_t(ROOM_PA)}                    # 1 bar room",
        "",
        "[control]",
        "rate_hz = 100.0                    # 100 Hz loop, as the arm (002 §II)",
        "",
        "[sensors]                          # 200 samples at 20 kHz averaged (002 §II): arm2's",
        f"angle_noise_rad = {_t(ARM2_ANGLE_NOISE * NOISE_SCALE, 3)}          # noise (500 samples) x sqrt(500/200)",
        f"pressure_noise_pa = {_t(ARM2_PRESSURE_NOISE * NOISE_SCALE, 3)}",
        "average = true",
        "",
        "[valve]                            # shared shape; every valve overrides its own below",
        "half_range_v = 5.0",
        "null_leak_width_v = 0.6",
    ]
    for s, (va, vb) in zip(sizes, valves):
        link = s.link
        lo, hi = link.range_deg
        lines += ["", "[[actuator]]", f'name = "{link.joint}"']
        if s.kind == "rotary":
            lines += [
                'kind = "rotary"',
                f"displacement_m3_per_rad = {_t(s.displacement, 2)}  # {s.capacity:.3g} N m at 6 bar; "
                f"needs {s.need:.3g}",
                f"travel_rad = {_t(s.stroke, 3)}{' ' * 19}# range {lo:g}..{hi:g} deg",
            ]
        else:
            how = (f"pins, moment arm {1e3 * s.moment_min:.1f}-{1e3 * s.extras['moment_max']:.1f} mm"
                   if s.transmission == "tendon" else f"moment arm {1e3 * s.moment_mean:.0f} mm")
            lines += [
                'kind = "linear"',
                f"bore_m = {_t(s.bore_mm / 1e3)}{' ' * 22}# {how}; needs {s.need:.0f} N",
                f"rod_m = {_t(s.rod_mm / 1e3)}",
                f"stroke_m = {_t(s.stroke, 3)}{' ' * 20}# range {lo:g}..{hi:g} deg moves the piston "
                f"{1e3 * (s.length_span[1] - s.length_span[0]):.1f} mm",
            ]
        lines += [
            f"dead_volume_a_m3 = {_t(s.dead_volume, 3)}",
            f"dead_volume_b_m3 = {_t(s.dead_volume, 3)}",
            f"position_at_zero = {_t(s.position_at_zero, 4)}",
        ]
        for tag, v in (("a", va), ("b", vb)):
            lines.append(f"[actuator.valve_{tag}]")
            lines += [f"{k} = {_t(x, 4)}" for k, x in v.items()]
    return "\n".join(lines) + "\n"


# -- README table --------------------------------------------------------------------------
TABLE_BEGIN, TABLE_END = "<!-- joint table: generated -->", "<!-- end of joint table -->"


def readme_table(sizes: list[Sizing], dyn: dict[str, JointDyn]) -> str:
    rows = ["| # | joint | range [°] | home [°] | actuator | transmission | size | stroke / travel "
            "| torque at 6 bar [N·m] | worst gravity [N·m] | damping | armature |",
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for i, s in enumerate(sizes):
        link = s.link
        lo, hi = link.range_deg
        if s.kind == "rotary":
            act, trn = "rotary vane", "joint, gear 1"
            size, stroke = f"D = {s.displacement * 1e6:.3g} cm³/rad", f"{math.degrees(s.stroke):.0f}°"
            torque = f"{s.capacity:.3g}"
        else:
            size, stroke = f"Ø{s.bore_mm}/{s.rod_mm} mm", f"{1e3 * s.stroke:.0f} mm"
            force = s.area_b * DP_PA  # the weaker (rod) side
            if s.transmission == "joint":
                act, trn = "cylinder", f"joint, r = {1e3 * s.moment_mean:.0f} mm"
                torque = f"{force * s.moment_mean:.3g}"
            else:
                act = "cylinder"
                trn = f"pins, r = {1e3 * s.moment_min:.0f}–{1e3 * s.extras['moment_max']:.0f} mm"
                torque = f"{force * s.moment_min:.3g}–{force * s.extras['moment_max']:.3g}"
        d = dyn[link.joint]
        rows.append(f"| {i} | `{link.joint}` | {lo:g} … {hi:g} | {link.home_deg:g} | {act} | {trn} | {size} "
                    f"| {stroke} | {torque} | {s.tau_gravity:.2g} | {d.damping:g} | {d.armature:.2g} |")
    return "\n".join(rows)


def update_readme(table: str):
    path = HERE / "README.md"
    if not path.is_file():
        return
    text = path.read_text()
    pattern = re.compile(re.escape(TABLE_BEGIN) + ".*?" + re.escape(TABLE_END), re.S)
    if pattern.search(text):
        path.write_text(pattern.sub(lambda _: f"{TABLE_BEGIN}\n{table}\n{TABLE_END}", text))


# -- checks ------------------------------------------------------------------------------
def check(model: mujoco.MjModel, sizes: list[Sizing]):
    """Home pose inside the ranges, no contact at home, every piston inside its stroke over
    its joint's range, and MuJoCo's pin-to-pin lengths equal to :func:`tendon_length`'s."""
    data = mujoco.MjData(model)
    for s in sizes:
        if s.transmission != "tendon":
            continue
        link = s.link
        jid = model.joint(link.joint).id
        qs, L = _lengths_over_range(model, data, model.actuator(link.joint).id,
                                    model.jnt_qposadr[jid], *model.jnt_range[jid], n=11)
        base = model.site_pos[model.site(f"{link.joint}_cyl_base").id]
        rod = model.site_pos[model.site(f"{link.joint}_cyl_rod").id]
        n = np.asarray(link.axis, float)
        ours = [np.linalg.norm(np.asarray(link.pos) + rotation(n, q) @ rod - base) for q in qs]
        assert np.allclose(L, ours, atol=1e-9), link.joint
    key = model.key("home")
    lo, hi = model.jnt_range.T
    assert np.all((key.qpos > lo) & (key.qpos < hi)), "home pose outside a joint range"
    mujoco.mj_resetDataKeyframe(model, data, key.id)
    mujoco.mj_forward(model, data)
    assert data.ncon == 0, f"{data.ncon} contacts in the home pose"
    for s in sizes:
        x0 = s.length_span[0] - s.length_zero + s.position_at_zero
        x1 = s.length_span[1] - s.length_zero + s.position_at_zero
        assert 0 < x0 < x1 < s.stroke, (s.link.joint, x0, x1, s.stroke)
        assert 0 <= s.position_at_zero <= s.stroke


def lowest_point(model: mujoco.MjModel) -> float:
    """Lowest collision-geom point [m] in the home pose (the floor is at z = 0)."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    low = np.inf
    for g in range(model.ngeom):
        if model.geom_group[g] != 3:
            continue
        # sample the geom's surface by its AABB corners in its own frame
        half = model.geom_aabb[g, 3:]
        centre = model.geom_aabb[g, :3]
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half + centre
        world = corners @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
        low = min(low, world[:, 2].min())
    return float(low)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quiet", action="store_true", help="print nothing")
    args = parser.parse_args(argv)

    provisional = {l.joint: JointDyn() for l in LINKS}
    loads = sample_loads(mujoco.MjModel.from_xml_string(build_mjcf(provisional)))
    phases = {l.joint: best_phase(l, loads[l.joint]) for l in LINKS if isinstance(l.drive, Tendon)}
    sizes = size_actuators(mujoco.MjModel.from_xml_string(build_mjcf(provisional, phases)), loads)
    dyn = joint_dynamics(sizes)
    valves = valve_tables(sizes)
    notes = {}
    for s in sizes:
        if s.kind == "rotary":
            notes[s.link.joint] = f"vane {s.displacement * 1e6:.3g} cm3/rad"
        else:
            notes[s.link.joint] = f"cylinder {s.bore_mm}/{s.rod_mm} mm x {1e3 * s.stroke:.0f} mm"
    xml = build_mjcf(dyn, phases, notes)
    final = mujoco.MjModel.from_xml_string(xml)
    check(final, sizes)
    (HERE / f"{MODEL}.xml").write_text(xml)
    (HERE / "fluid.toml").write_text(build_toml(sizes, valves))
    update_readme(readme_table(sizes, dyn))

    if not args.quiet:
        mass = final.body_subtreemass[final.body("pelvis").id]
        d = mujoco.MjData(final)
        mujoco.mj_resetDataKeyframe(final, d, final.key("home").id)
        mujoco.mj_forward(final, d)
        top = max(d.geom_xpos[g, 2] + final.geom_rbound[g] for g in range(final.ngeom))
        print(f"{MODEL}: {final.njnt} joints, {final.nu} actuators, {final.ntendon} tendons, "
              f"mass {mass:.2f} kg, height {top:.3f} m, lowest collision point {lowest_point(final):.3f} m")
        for s in sizes:
            size = (f"D {s.displacement * 1e6:7.3g} cm3/rad" if s.kind == "rotary"
                    else f"bore {s.bore_mm:2d}/{s.rod_mm:2d} mm")
            print(f"  {s.link.joint:26s} {s.transmission:6s} {size:20s} stroke {s.stroke:.3f} "
                  f"x0 {s.position_at_zero:.4f}  gravity {s.tau_gravity:6.2f} N m  "
                  f"capacity {s.capacity:6.2f} N m  dead {s.dead_volume * 1e6:.2f} cm3  "
                  f"valve {s.extras['valve_base_m2']:.2e} m2")


if __name__ == "__main__":
    main()
