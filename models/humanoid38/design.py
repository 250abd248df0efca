"""humanoid38's design tables: the sizing rules, the mass split and the link table (each
link's parent, joint, range, drive, geoms), mirrored left to right, and the geometry derived
from them (rotations, link inertias, tendon lever sites and lengths).  The generator
(:mod:`.generate`) derives the model files from these; its docstring says how."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

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
