"""An independent arm2 simulator written from the arm2 reference numbers
(``reference/arm2.md`` beside DESIGN.md) and paper 002 only: its own MJCF (two hinges), its own chamber ODEs (:mod:`.kernel`), its own PIDF
controller at 100 Hz with zero-order hold, DAQ averaging and sensor noise.

Nothing here imports pneumasim (``pneumatics``, ``identification``, ``controllers``,
``models``): the point is to judge the doctor on physics it was not written against.
"""
from __future__ import annotations

import copy
import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from . import hysteresis as H
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
    outside the kernel (valve hysteresis operators and dead times on the command, sensor
    models, the supply step's time as a fraction of the recording)."""

    P_rows: dict = field(default_factory=dict)      #: (row, col) -> value
    hysteresis: dict = field(default_factory=dict)  #: chamber column -> (form name, parameters)
    dead_time_s: np.ndarray = field(default_factory=lambda: np.zeros(4))
    pressure_offset_pa: np.ndarray = field(default_factory=lambda: np.zeros(4))
    pressure_gain_error: np.ndarray = field(default_factory=lambda: np.zeros(4))
    pressure_drift_pa: np.ndarray = field(default_factory=lambda: np.zeros(4))
    pressure_drift_tau_s: np.ndarray = field(default_factory=lambda: np.ones(4))
    angle_offset_rad: np.ndarray = field(default_factory=lambda: np.zeros(2))
    angle_gain_error: np.ndarray = field(default_factory=lambda: np.zeros(2))
    angle_wobble_rad: np.ndarray = field(default_factory=lambda: np.zeros(2))
    angle_wobble_phase: np.ndarray = field(default_factory=lambda: np.zeros(2))
    supply_step_fraction: float | None = None       #: the supply step's time / recording length


#: rows of command history kept for the valve dead time (dead times up to 50 ms)
HISTORY_ROWS = 7


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
        self.hyst = {c: H.make(form, params) for c, (form, params) in self.hidden.hysteresis.items()}
        self.dead_ms = np.round(np.asarray(self.hidden.dead_time_s) * 1000).astype(int)
        if self.dead_ms.max() > 10 * (HISTORY_ROWS - 2):
            raise ValueError(f"variant simulator: valve dead time {self.dead_ms.max()} ms above the "
                             f"{10 * (HISTORY_ROWS - 2)} ms the command history holds")
        self.u_hist = [np.full(4, 5.0)] * HISTORY_ROWS
        self._tau = np.zeros(2)

    def reset(self, q, pressure_pa=4.5e5):
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = q
        mujoco.mj_forward(self.model, self.data)
        self.S[:] = 0.0
        self.S[K.SP] = self.S[K.SPT] = pressure_pa
        self.S[K.SN0:K.SN0 + 3] = pressure_pa
        self.S[K.ST] = self.S[K.STW] = K.T0
        self.S[K.SY] = 5.0
        self.S[K.STH, :2] = q
        self.S[K.SPS, 0] = K.P_SUPPLY
        for op in self.hyst.values():
            op.reset(5.0)
        self.u_hist = [np.full(4, 5.0)] * HISTORY_ROWS

    def start_clock(self, seconds: float, preroll_s: float):
        """Set the clock to -preroll_s (t = 0 at the recording's first row) and place the
        supply step (if any) at its fraction of the recording's ``seconds``."""
        self.S[K.SCLK, 0] = -preroll_s
        if self.hidden.supply_step_fraction is not None:
            self.P[K.OS_T, 0] = self.hidden.supply_step_fraction * seconds

    def snapshot(self) -> dict:
        return {"qpos": self.data.qpos.copy(), "qvel": self.data.qvel.copy(), "S": self.S.copy(),
                "hyst": copy.deepcopy(self.hyst), "u_hist": list(self.u_hist)}

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
            p = snap["S"][K.SP]
            self.S[K.SP] = self.S[K.SPT] = p
            self.S[K.SN0:K.SN0 + 3] = p
            self.S[K.SCLK, 0] = snap["S"][K.SCLK, 0]
            self.S[K.SY] = snap["u_hist"][-1]
            self.u_hist = [snap["u_hist"][-1]] * HISTORY_ROWS
        else:
            self.S[:] = snap["S"]
            self.hyst, self.u_hist = copy.deepcopy(snap["hyst"]), list(snap["u_hist"])

    def _command_ms(self, i: int) -> np.ndarray:
        """The spool command at millisecond i of the row: each chamber's command from its dead
        time ago (commands held per 10 ms row)."""
        if not self.dead_ms.any():
            return self.u_hist[-1]
        u = np.empty(4)
        for c in range(4):
            back = (i - self.dead_ms[c]) // 10            # 0 = this row, -1 = the row before, ...
            u[c] = self.u_hist[-1 + back][c]
        return u

    def advance_row(self, u) -> tuple[np.ndarray, np.ndarray]:
        """Hold command u (4,) [V] for 10 ms; return the true link angles (2,) and chamber
        pressures (4,) averaged over the 10 ms (DAQ averaging)."""
        u_eff = np.asarray(u, float).copy()
        for c, op in self.hyst.items():
            u_eff[c] = op(u_eff[c])
        self.u_hist = self.u_hist[1:] + [u_eff]
        qsum, psum = np.zeros(2), np.zeros(4)
        d, m = self.data, self.model
        n = round(ROW_S / DT_S)
        for i in range(n):
            K.step_ms(self._command_ms(i), d.qpos, d.qvel, d.qfrc_bias, self.P, self.S, DT_S, NSUB, self._tau)
            d.qfrc_applied[:] = self._tau
            mujoco.mj_step(m, d)
            qsum += d.qpos
            psum += self.S[K.SP]
        return qsum / n, psum / n

    def measure(self, q, p):
        """Sensor model without noise: encoder offset, scale error and once-per-turn
        eccentricity; pressure offset, gain error and a warm-up drift
        offset + drift (1 - exp(-t / tau)) from the recording's start."""
        h = self.hidden
        t = max(float(self.S[K.SCLK, 0]), 0.0)
        qm = q + h.angle_offset_rad + h.angle_gain_error * q + h.angle_wobble_rad * np.sin(q + h.angle_wobble_phase)
        drift = h.pressure_drift_pa * (1.0 - np.exp(-t / h.pressure_drift_tau_s))
        return qm, K.P_ATM + (1 + h.pressure_gain_error) * (p - K.P_ATM) + h.pressure_offset_pa + drift


def write_csv(path: Path, table: np.ndarray):
    """CSV in DESIGN.md's recording format, written atomically."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    fmt = ["%.3f"] + ["%.7f"] * 2 + ["%.1f"] * 4 + ["%.5f"] * 4 + ["%.7f"] * 2
    np.savetxt(tmp, table, delimiter=",", header=",".join(COLUMNS), comments="", fmt=fmt)
    os.replace(tmp, path)
