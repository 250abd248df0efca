"""Loads and actuator sizes of humanoid38: MuJoCo's gravity torques and inertias over random
poses in the joint ranges, the tendon levers' phases, ISO bores and strokes, the air spring
that holds the home pose, and each joint's damping and armature (steps 3-6 of :mod:`.generate`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from .design import (
    ACCEL_REF,
    ALUMINIUM,
    ARMATURE_RANGE,
    DAMPING_PER_TORQUE,
    DAMPING_RANGE,
    DEAD_FRACTION,
    DEAD_MAX_M3,
    DEAD_MIN_M3,
    DEAD_TUBE_M3,
    DP_PA,
    GRAVITY_MARGIN,
    HOLD_PA,
    HOLD_SAG_RAD,
    ISO_BORES,
    LINKS,
    Link,
    MIN_CYLINDER_BODY_M,
    N_POSES,
    PHI_CLEAR,
    PISTON_THICKNESS_M,
    POLYTROPIC,
    ROD_EXTRA_M,
    Rotary,
    SEED,
    STEEL,
    STROKE_MARGIN_M,
    STROKE_ROUND_M,
    TORQUE_FLOOR,
    TRAVEL_MARGIN_RAD,
    TRAVEL_ROUND_RAD,
    Tendon,
    VANE_ARMATURE,
    tendon_length,
)
from .mjcf import JointDyn


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


def lengths_over_range(model, data, act_id, qadr, lo, hi, n=201):
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
        qs, L = lengths_over_range(model, data, model.actuator(link.joint).id, qadr, qlo, qhi)
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
