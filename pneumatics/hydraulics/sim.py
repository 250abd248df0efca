"""A hydraulic joint stepped together with MuJoCo (paper 001's SARCOS elbow).

One physics step of length dt, state (q, qd, hydraulics, valve) at t::

    valve tip        x_v(t + dt) from i_hys held over the step (exact ZOH, eq. 4)
    hydraulics       pressures and line flows to t + dt with the vane angle and velocity of t
                     (linearly-implicit Euler, L-stable: see circuit.py)
    torque           D_v (P_a - P_b)(t + dt) -> data.ctrl of the vane's motor
    mj_step          MuJoCo's implicitfast step: qd(t + dt) from that torque, then q(t + dt)

Pressure is updated from the old velocity and the velocity from the new pressure: for the oil
spring (P ~ -beta D_v theta / V) and the vane inertia this is the symplectic Euler scheme,
stable for omega dt < 2 with no numerical damping; the shaft spring and MuJoCo's friction and
brace constraints are MuJoCo's own.  At the model's 0.2 ms the fastest mode (vane between oil
and shaft springs, ~640 Hz) has omega dt ~ 0.8; tests/test_sarcos.py checks that halving dt
changes the pressures by less than a percent and that the error falls with dt.

The input current is clipped at the hysteresis saturation current (the amplifier's limit).
"""
from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

import models

from .. import arguments
from ..errors import ConfigError
from .circuit import BLOCKED, VALVE, HydraulicCircuit, Port
from .config import HydraulicCfg, load_hydraulic_cfg
from .hysteresis import Hysteresis
from .servovalve import ValveTip

VANE_JOINT, SHAFT_JOINT, LOAD_TENDON, BRACE, ACTUATOR = "elbow", "shaft", "load_angle", "brace", "elbow"
#: a current beyond this many times the saturation current is a unit slip (mA given as A)
CURRENT_SLIP_FACTOR = 10.0


class HydraulicJointSim:
    """MuJoCo bodies (vane, compliant shaft, load) and the hydraulic circuit, stepped together.

    Args:
      cfg: the fluid-power parameters (``fluid.toml``).
      mjcf: path of the MJCF (``sarcos_elbow.xml`` or ``scene.xml``).
      timestep: overrides the MJCF's ``option/timestep`` [s] (convergence studies).
    """

    def __init__(self, cfg: HydraulicCfg, mjcf: str | Path, timestep: float | None = None):
        self.cfg = cfg
        self.model = mujoco.MjModel.from_xml_path(str(mjcf))
        if timestep is not None:
            if not 1e-6 <= timestep <= 2e-3:
                raise ConfigError(f"timestep {timestep:g} s: expected 1e-6 .. 2e-3 s")
            self.model.opt.timestep = timestep
        self.data = mujoco.MjData(self.model)
        self.dt = float(self.model.opt.timestep)
        m = self.model
        try:
            self._vane = m.jnt_dofadr[m.joint(VANE_JOINT).id]
            self._shaft = m.jnt_dofadr[m.joint(SHAFT_JOINT).id]
            self._vane_q = m.jnt_qposadr[m.joint(VANE_JOINT).id]
            self._shaft_q = m.jnt_qposadr[m.joint(SHAFT_JOINT).id]
            self._brace = m.equality(BRACE).id
            self._act = m.actuator(ACTUATOR).id
        except KeyError as e:
            raise ConfigError(f"{mjcf}: a hydraulic joint model needs joints {VANE_JOINT!r} and "
                              f"{SHAFT_JOINT!r}, equality {BRACE!r} and actuator {ACTUATOR!r} ({e})") from None
        self.shaft_stiffness_nm_per_rad = float(m.jnt_stiffness[m.joint(SHAFT_JOINT).id])
        self.coulomb_friction_nm = float(m.dof_frictionloss[self._vane])
        self.hysteresis = Hysteresis(cfg.hysteresis)
        self.tip = ValveTip(cfg.servovalve, cfg.hysteresis.saturation_current_a, self.dt)
        self.circuit = HydraulicCircuit(cfg.oil, cfg.power, cfg.supply_line, cfg.return_line,
                                        cfg.servovalve, cfg.vane)
        self.d_v = cfg.vane.displacement_m3_per_rad
        self.null_shift_a = 0.0
        """valve null shift [A]: a bias added to i_hys at the tip (0 = a centred valve;
        pneumatics.hydraulics.effects sets it)"""
        self.reset()

    # ----------------------------------------------------------------- state
    def reset(self, keyframe: str = "home", demagnetize: bool = True, braced: bool = False):
        """Keyframe pose at rest, hydraulics at the null steady state, valve demagnetised
        (paper 001 §4: "a decaying sinusoidal current ... valve tip practically at the null")."""
        key = arguments.keyframe_id(self.model, keyframe)  # an unknown name raises, listing the valid
        if key is None:  # the bare MJCF has no keyframes (they are in scene.xml): qpos0
            mujoco.mj_resetData(self.model, self.data)
        else:
            mujoco.mj_resetDataKeyframe(self.model, self.data, key)
        self.brace(braced)
        self.circuit.ports = [VALVE, VALVE]
        self.circuit.y = self.circuit.null_state()
        self.circuit.tap_volume_m3[:] = 0.0
        self.hysteresis.reset()
        if demagnetize:
            self.hysteresis.demagnetize()
        self.current_a = 0.0
        self.i_hys_a = self.hysteresis(0.0)
        self.tip.reset((self.i_hys_a + self.null_shift_a) * self.cfg.servovalve.tip_travel_m
                       / self.cfg.hysteresis.saturation_current_a)
        self.data.ctrl[self._act] = self.torque_hydraulic_nm
        mujoco.mj_forward(self.model, self.data)

    def brace(self, on: bool):
        """Lock (True) or free (False) the load with the steel brace (paper 001 Fig. 2a)."""
        self.data.eq_active[self._brace] = bool(on)

    @property
    def braced(self) -> bool:
        """Whether the brace locks the load."""
        return bool(self.data.eq_active[self._brace])

    def set_ports(self, a: Port | str = VALVE, b: Port | str = VALVE):
        """Connect the chamber ports: ``"valve"``, ``"blocked"`` or a tap :class:`Port`."""
        named = {"valve": VALVE, "blocked": BLOCKED}
        ports = [named.get(p, p) if isinstance(p, str) else p for p in (a, b)]
        for p in ports:
            if not isinstance(p, Port):
                raise ConfigError(f"port {p!r}: expected 'valve', 'blocked' or a Port")
        self.circuit.ports = ports

    def set_current(self, current_a: float):
        """Valve current command [A], held until the next call; passes through the hysteresis.

        Finite; saturated at +-saturation_current_a, refused beyond CURRENT_SLIP_FACTOR times it
        (a unit slip, mA given as A: :class:`~pneumatics.errors.ArgumentError`)."""
        i_sat = self.cfg.hysteresis.saturation_current_a
        current_a = arguments.command_in_range(current_a, -CURRENT_SLIP_FACTOR * i_sat, CURRENT_SLIP_FACTOR * i_sat,
                                               "HydraulicJointSim.set_current(current_a)", "A",
                                               f"the valve saturates at ±{i_sat:g} A; beyond {CURRENT_SLIP_FACTOR:g} x "
                                               "that is a unit slip, mA given as A?")
        self.current_a = min(max(current_a, -i_sat), i_sat)
        self.i_hys_a = self.hysteresis(self.current_a)

    # ----------------------------------------------------------------- stepping
    def step(self, n: int = 1):
        """Advance ``n`` physics steps (a whole number >= 1)."""
        n = arguments.step_count(n, "HydraulicJointSim.step")
        m, d, c, tip = self.model, self.data, self.circuit, self.tip
        dt, d_v, vq, vd, act = self.dt, self.d_v, self._vane_q, self._vane, self._act
        i_tip = self.i_hys_a + self.null_shift_a
        for _ in range(n):
            x_v = tip.step(i_tip)
            y = c.step(dt, x_v, float(d.qpos[vq]), float(d.qvel[vd]))
            d.ctrl[act] = d_v * (y[4] - y[5])
            mujoco.mj_step(m, d)

    # ----------------------------------------------------------------- observations
    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def pressures(self) -> dict[str, float]:
        """Pressures [Pa abs]: supply and return at the valve, chambers a and b."""
        y = self.circuit.y
        return {"supply": float(y[0]), "return": float(y[2]), "a": float(y[4]), "b": float(y[5])}

    @property
    def load_pressure_pa(self) -> float:
        """P_L = P_a - P_b [Pa]."""
        return float(self.circuit.y[4] - self.circuit.y[5])

    @property
    def torque_hydraulic_nm(self) -> float:
        """D_v P_L [N m]: the torque the oil puts on the vane."""
        return self.d_v * self.load_pressure_pa

    @property
    def vane_angle(self) -> float:
        return float(self.data.qpos[self._vane_q])

    @property
    def load_angle(self) -> float:
        """theta_l = vane angle + shaft twist [rad]; 0 = hanging down."""
        return float(self.data.qpos[self._vane_q] + self.data.qpos[self._shaft_q])

    @property
    def load_velocity(self) -> float:
        return float(self.data.qvel[self._vane] + self.data.qvel[self._shaft])

    @property
    def joint_torque_nm(self) -> float:
        """What the strain-gauge joint torque sensor reads: k_s (theta_v - theta_l) [N m]."""
        return -self.shaft_stiffness_nm_per_rad * float(self.data.qpos[self._shaft_q])

    @property
    def warnings(self) -> list[int]:
        return [int(w.number) for w in self.data.warning]

    def rerun_robot(self):
        """What :class:`workflow.rerun_log.RerunLogger` reads of a robot, for this joint
        (log recordings with ``logger.log_recording(rec, prefix="", bodies=True)``)."""
        from ..robot_view import RobotView

        names = [VANE_JOINT, SHAFT_JOINT]
        return RobotView("sarcos_elbow", self.model, names,
                          np.array([self.model.jnt_qposadr[self.model.joint(j).id] for j in names]),
                          [ACTUATOR], [(ACTUATOR, "a"), (ACTUATOR, "b")])


def load_hydraulic(name: str = "sarcos_elbow", timestep: float | None = None,
                   scene: bool = True) -> HydraulicJointSim:
    """Build the simulation of shipped hydraulic model ``name`` from its folder."""
    kind = models.model_kind(name)
    if kind != "hydraulic":
        raise ConfigError(f"model {name!r} is of kind {kind!r}, not 'hydraulic'")
    cfg = load_hydraulic_cfg(models.fluid_path(name))
    return HydraulicJointSim(cfg, models.mjcf_path(name, scene=scene), timestep=timestep)
