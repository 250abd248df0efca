"""An independent arm2 simulator written from the arm2 reference numbers
(``reference/arm2.md`` beside DESIGN.md) and paper 002 only: its own MJCF (two hinges), its own chamber ODEs (:mod:`.kernel`), its own PIDF
controller at 100 Hz with zero-order hold, DAQ averaging and sensor noise.

Nothing here imports pneumasim (``pneumatics``, ``identification``, ``controllers``,
``models``): the point is to judge the doctor on physics it was not written against.
"""
from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from . import kernel as K

JOINTS = ("shoulder", "elbow")
CHAMBERS = ("shoulder.a", "shoulder.b", "elbow.a", "elbow.b")
ROW_S = 0.01          #: recording and control period [s] (100 Hz)
DT_S = 0.001          #: physics step [s]
NSUB = 4              #: fluid sub-steps per physics step (0.25 ms: the valve's laminar
#                        region relaxes a 3 cm^3 chamber at ~1600 1/s)
ANGLE_NOISE_RAD = math.radians(0.05)
PRESSURE_NOISE_PA = 300.0
COLUMNS = ("time", "q.shoulder", "q.elbow", "p_a.shoulder", "p_b.shoulder", "p_a.elbow", "p_b.elbow",
           "u_a.shoulder", "u_b.shoulder", "u_a.elbow", "u_b.elbow", "ref.shoulder", "ref.elbow")


@dataclass
class Arm2Config:
    """arm2.md's numbers (SI); per-chamber lists in CHAMBERS order, per-joint in JOINTS order."""

    link_mass_kg: list = field(default_factory=lambda: [0.60, 0.45])
    link_inertia_kgm2: list = field(default_factory=lambda: [[0.004, 0.004, 0.002], [0.0035, 0.0035, 0.0003]])
    forearm_com_m: float = 0.16
    damping_nms: list = field(default_factory=lambda: [0.03, 0.02])
    armature_kgm2: list = field(default_factory=lambda: [5.4e-5, 3.8e-5])
    range_deg: list = field(default_factory=lambda: [60.0, 70.0])
    bore_m: list = field(default_factory=lambda: [0.020, 0.016])
    rod_m: list = field(default_factory=lambda: [0.008, 0.006])
    stroke_m: list = field(default_factory=lambda: [0.070, 0.070])
    moment_arm_m: list = field(default_factory=lambda: [0.030, 0.025])
    dead_volume_m3: list = field(default_factory=lambda: [4.0e-6, 4.0e-6, 3.0e-6, 3.0e-6])
    supply_area_m2: list = field(default_factory=lambda: [8.0e-7, 8.0e-7, 6.0e-7, 6.0e-7])
    exhaust_area_m2: list = field(default_factory=lambda: [9.0e-7, 9.0e-7, 7.0e-7, 7.0e-7])

    def perturbed(self, rng: np.random.Generator, fraction: float) -> tuple[Arm2Config, dict]:
        """Valve areas, dead volumes and link mass+inertia each off by U(-fraction, fraction)."""
        f = lambda: float(1 + rng.uniform(-fraction, fraction))
        c = dataclasses.replace(self)
        factors = {}
        sa, ea, dv = list(self.supply_area_m2), list(self.exhaust_area_m2), list(self.dead_volume_m3)
        for i, ch in enumerate(CHAMBERS):
            for lst, key in ((sa, "supply_area"), (ea, "exhaust_area"), (dv, "dead_volume")):
                factors[f"{ch}.{key}"] = k = f()
                lst[i] *= k
        mass, inertia = list(self.link_mass_kg), [list(x) for x in self.link_inertia_kgm2]
        for j, name in enumerate(JOINTS):
            factors[f"link.{name}.mass_and_inertia"] = k = f()
            mass[j] *= k
            inertia[j] = [x * k for x in inertia[j]]
        c.supply_area_m2, c.exhaust_area_m2, c.dead_volume_m3 = sa, ea, dv
        c.link_mass_kg, c.link_inertia_kgm2 = mass, inertia
        return c, factors

    def piston_areas(self) -> np.ndarray:
        """(4,) piston areas [m^2]: A_a = pi bore^2/4 and A_b = pi (bore^2 - rod^2)/4."""
        out = []
        for b, r in zip(self.bore_m, self.rod_m):
            out += [math.pi * b * b / 4, math.pi * (b * b - r * r) / 4]
        return np.array(out)

    def mjcf(self, no_armature=(False, False)) -> str:
        """Two hinges at the origin: shoulder about world y, elbow about the shoulder link's x;
        q = 0 points the arm up (arm2.md "Rigid body").  A joint with a compliant transmission
        (backlash) carries its piston inertia outside MuJoCo, hence ``no_armature``."""
        arm = [0.0 if n else a for a, n in zip(self.armature_kgm2, no_armature)]
        i1, i2 = self.link_inertia_kgm2
        return f"""<mujoco model="variant_arm2">
  <compiler angle="degree"/>
  <option timestep="{DT_S}" gravity="0 0 -9.81" integrator="Euler"/>
  <worldbody>
    <body name="upper_link">
      <joint name="shoulder" type="hinge" axis="0 1 0" limited="true" range="{-self.range_deg[0]} {self.range_deg[0]}"
             damping="{self.damping_nms[0]}" armature="{arm[0]}"/>
      <inertial pos="0 0 0" mass="{self.link_mass_kg[0]}" diaginertia="{i1[0]} {i1[1]} {i1[2]}"/>
      <body name="forearm">
        <joint name="elbow" type="hinge" axis="1 0 0" limited="true" range="{-self.range_deg[1]} {self.range_deg[1]}"
               damping="{self.damping_nms[1]}" armature="{arm[1]}"/>
        <inertial pos="0 0 {self.forearm_com_m}" mass="{self.link_mass_kg[1]}" diaginertia="{i2[0]} {i2[1]} {i2[2]}"/>
      </body>
    </body>
  </worldbody>
</mujoco>"""

    def param_matrix(self) -> np.ndarray:
        """The kernel's (NP, 4) parameter matrix with every effect off."""
        P = np.zeros((K.NP, 4))
        P[K.AS], P[K.AE], P[K.VD] = self.supply_area_m2, self.exhaust_area_m2, self.dead_volume_m3
        P[K.ACYL], P[K.SIGN] = self.piston_areas(), [1, -1, 1, -1]
        P[K.R_ARM, :2], P[K.STROKE, :2] = self.moment_arm_m, self.stroke_m
        P[K.DAMP, :2], P[K.BL_J, :2] = self.damping_nms, self.armature_kgm2
        m2, c2 = self.link_mass_kg[1], self.forearm_com_m
        P[K.INERTIA, :2] = [self.link_inertia_kgm2[0][1] + self.link_inertia_kgm2[1][1] + m2 * c2 * c2 + self.armature_kgm2[0],
                            self.link_inertia_kgm2[1][0] + m2 * c2 * c2 + self.armature_kgm2[1]]
        return P


@dataclass
class Hidden:
    """The variant effects switched on in one simulator: kernel parameter rows plus what acts
    outside the kernel (Bouc-Wen valve hysteresis, sensor offsets and gain errors)."""

    P_rows: dict = field(default_factory=dict)      #: (row, col) -> value
    bw_half_width_v: np.ndarray = field(default_factory=lambda: np.zeros(4))
    pressure_offset_pa: np.ndarray = field(default_factory=lambda: np.zeros(4))
    pressure_gain_error: np.ndarray = field(default_factory=lambda: np.zeros(4))
    angle_offset_rad: np.ndarray = field(default_factory=lambda: np.zeros(2))


class VariantArm:
    """One arm2 with its hidden effects; steps 10 ms at a time with a held command."""

    def __init__(self, cfg: Arm2Config, hidden: Hidden | None = None):
        self.cfg, self.hidden = cfg, hidden or Hidden()
        self.P = cfg.param_matrix()
        for (row, col), v in self.hidden.P_rows.items():
            self.P[row, col] = v
        self.model = mujoco.MjModel.from_xml_string(cfg.mjcf(tuple(self.P[K.BL_GAP, :2] > 0)))
        self.data = mujoco.MjData(self.model)
        self.S = np.zeros((K.NS, 4))
        self.bw_z = np.zeros(4)
        self.u_prev = np.full(4, 5.0)
        self._tau = np.zeros(2)

    def reset(self, q, pressure_pa=4.5e5):
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = q
        mujoco.mj_forward(self.model, self.data)
        self.S[:] = 0.0
        self.S[K.SP] = self.S[K.SPT] = pressure_pa
        self.S[K.ST] = K.T0
        self.S[K.SY] = 5.0
        self.S[K.STH, :2] = q
        self.S[K.SPS, 0] = K.P_SUPPLY
        self.bw_z[:] = 0.0
        self.u_prev[:] = 5.0

    def snapshot(self) -> dict:
        return {"qpos": self.data.qpos.copy(), "qvel": self.data.qvel.copy(), "S": self.S.copy(),
                "bw_z": self.bw_z.copy(), "u_prev": self.u_prev.copy()}

    def restore(self, snap: dict, physics_only: bool = False):
        """Set the state from a snapshot; ``physics_only`` keeps only what a simulator without
        the effects has (link state, chamber pressures, spool at the command)."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:], self.data.qvel[:] = snap["qpos"], snap["qvel"]
        mujoco.mj_forward(self.model, self.data)
        if physics_only:
            self.reset(snap["qpos"])
            self.data.qvel[:] = snap["qvel"]
            mujoco.mj_forward(self.model, self.data)
            self.S[K.SP] = snap["S"][K.SP]
            self.S[K.SY] = self.u_prev[:] = snap["u_prev"]
        else:
            self.S[:], self.bw_z[:], self.u_prev[:] = snap["S"], snap["bw_z"], snap["u_prev"]

    def _bouc_wen(self, u):
        """Bouc-Wen hysteresis between command and spool (Wen 1976), n = 1, beta = gamma =
        1/(2H): dz = du (1 - |z|/H) while |z| grows, dz = du while it shrinks; spool = u - z."""
        du = u - self.u_prev
        self.u_prev = u.copy()
        H = self.hidden.bw_half_width_v
        for c in np.nonzero(H > 0)[0]:
            d, z = du[c], self.bw_z[c]
            if d == 0.0:
                continue
            sg = 1.0 if d > 0 else -1.0
            rem = abs(d)
            if z * sg < 0:               # reversal: z follows the command back to 0
                step = min(rem, abs(z))
                z += sg * step
                rem -= step
            z = sg * H[c] - (sg * H[c] - z) * math.exp(-rem / H[c])
            self.bw_z[c] = z
        return u - self.bw_z

    def advance_row(self, u) -> tuple[np.ndarray, np.ndarray]:
        """Hold command u (4,) [V] for 10 ms; return the true link angles (2,) and chamber
        pressures (4,) averaged over the 10 ms (DAQ averaging)."""
        u_eff = self._bouc_wen(np.asarray(u, float))
        qsum, psum = np.zeros(2), np.zeros(4)
        d, m = self.data, self.model
        n = round(ROW_S / DT_S)
        for _ in range(n):
            K.step_ms(u_eff, d.qpos, d.qvel, d.qfrc_bias, self.P, self.S, DT_S, NSUB, self._tau)
            d.qfrc_applied[:] = self._tau
            mujoco.mj_step(m, d)
            qsum += d.qpos
            psum += self.S[K.SP]
        return qsum / n, psum / n

    def measure(self, q, p):
        """Sensor model without noise: encoder offset, pressure offset and gain error."""
        h = self.hidden
        return q + h.angle_offset_rad, K.P_ATM + (1 + h.pressure_gain_error) * (p - K.P_ATM) + h.pressure_offset_pa


def write_csv(path: Path, table: np.ndarray):
    """CSV in DESIGN.md's recording format, written atomically."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    fmt = ["%.3f"] + ["%.7f"] * 2 + ["%.1f"] * 4 + ["%.5f"] * 4 + ["%.7f"] * 2
    np.savetxt(tmp, table, delimiter=",", header=",".join(COLUMNS), comments="", fmt=fmt)
    os.replace(tmp, path)
